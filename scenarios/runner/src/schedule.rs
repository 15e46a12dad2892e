//! The scenario's goals, door commands and faults as one time-ordered list of cues, the same
//! for both modes.

use iw_fleet::compose::world_link::FailedSensor;
use iw_sim::Map;
use nalgebra::Point2;

use crate::ScenarioError;
use crate::schema::{DoorEntry, Fault, GoalEntry, Scenario};

/// A cue: something the scenario makes happen at its time in the run.
#[derive(Debug, Clone, Copy)]
pub enum Cue<'a> {
    /// Give a goal (the point it resolves to).
    Goal(&'a GoalEntry, Point2<f64>),
    /// Open or close a door.
    Door(&'a DoorEntry),
    /// Inject a fault.
    Fault(&'a Fault),
    /// A link fault ends.
    LinkUp(&'a str),
    /// A sensor fault ends.
    SensorsBack(&'a str, FailedSensor),
    /// A blinded laser sees again.
    LaserBack(&'a str),
}

/// Adds a place for every goal given as a point that is not already (within 0.5 m) a place of
/// `map`, named `goal-INDEX`, so the cognitive agents can plan to it.
pub fn add_goal_places(scenario: &Scenario, map: &mut Map) {
    for (i, g) in scenario.goals.iter().enumerate() {
        if let Some([x, y]) = g.xy {
            let position = Point2::new(x, y);
            if !map
                .places
                .iter()
                .any(|p| (p.position - position).norm() <= 0.5)
            {
                map.places.push(iw_sim::Place {
                    name: format!("goal-{i}"),
                    position,
                });
            }
        }
    }
}

/// Every cue of `scenario`, ordered by time; entries at one time keep file order (goals,
/// doors, faults).
pub fn schedule<'a>(
    scenario: &'a Scenario,
    map: &Map,
) -> Result<Vec<(f64, Cue<'a>)>, ScenarioError> {
    let mut schedule: Vec<(f64, Cue)> = Vec::new();
    for g in &scenario.goals {
        let point = scenario
            .goal_point(g, map)
            .map_err(|reason| scenario.invalid(g.chair.clone(), reason))?;
        schedule.push((g.at_s, Cue::Goal(g, point)));
    }
    schedule.extend(scenario.doors.iter().map(|d| (d.at_s, Cue::Door(d))));
    for f in &scenario.faults {
        schedule.push((f.at_s(), Cue::Fault(f)));
        match f {
            Fault::LinkLoss {
                at_s,
                container,
                for_s: Some(d),
            } => schedule.push((at_s + d, Cue::LinkUp(container))),
            Fault::SensorFailure {
                at_s,
                chair,
                sensor,
                for_s: Some(d),
            } => schedule.push((at_s + d, Cue::SensorsBack(chair, *sensor))),
            Fault::LaserBlind {
                at_s,
                chair,
                for_s: Some(d),
            } => schedule.push((at_s + d, Cue::LaserBack(chair))),
            _ => {}
        }
    }
    // stable sort
    schedule.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(schedule)
}
