//! In process: the scenario over an [`iw_fleet::Fleet`] in simulated time (mock clock, fixed
//! step, faster than real time), deterministic.

use iw_fleet::{ChairConfig, Fleet, FleetError, FleetOptions};

use crate::ScenarioError;
use crate::assertions::check;
use crate::observe::{Observation, Totals};
use crate::report::{ChairSummary, Mode, Report};
use crate::schedule::{Cue, add_goal_places, schedule};
use crate::schema::{Fault, Scenario};

/// Rounds of message delivery without time passing at the end of a run.
const MAX_QUIESCE_ROUNDS: usize = 16;

/// Runs `scenario` to its end in process and checks its assertions.
pub fn run(scenario: &Scenario) -> Result<Report, ScenarioError> {
    run_with_progress(scenario, |_, _| {})
}

/// [`run`], calling `progress(step, steps)` after each step.
pub fn run_with_progress(
    scenario: &Scenario,
    mut progress: impl FnMut(u64, u64),
) -> Result<Report, ScenarioError> {
    let mut map = scenario.load_map()?;
    scenario.validate_for(&map, Mode::InProcess)?;
    add_goal_places(scenario, &mut map);
    let path = scenario.source.display().to_string();
    let fleet_err = |time_s: f64| {
        let path = path.clone();
        move |source: FleetError| ScenarioError::Fleet {
            path,
            time_s,
            source,
        }
    };
    let configs = scenario
        .chairs
        .iter()
        .map(|c| {
            let t_world_body = scenario
                .start_of(c, &map)
                .map_err(|reason| scenario.invalid(c.name.clone(), reason))?;
            Ok(ChairConfig {
                name: c.name.clone(),
                t_world_body,
            })
        })
        .collect::<Result<Vec<_>, ScenarioError>>()?;
    let schedule = schedule(scenario, &map)?;
    let options = FleetOptions {
        bodies: scenario
            .chairs
            .iter()
            .map(|c| (c.name.clone(), c.body))
            .collect(),
        restricted: scenario
            .restricted
            .iter()
            .map(|r| (r.door.clone(), r.authorised.iter().cloned().collect()))
            .collect(),
        log_path: None,
        visual_odometry: scenario.visual_odometry,
        ..FleetOptions::default()
    };
    let mut fleet =
        Fleet::with_options(map, scenario.seed, &configs, options).map_err(fleet_err(0.0))?;
    let dt = scenario.step;
    let steps = (scenario.duration_s * 1000.0 / dt.as_millis() as f64).ceil() as u64;
    let mut timeline = Vec::new();
    let mut seen = Vec::new();
    let mut next = 0;
    let mut conversations: Vec<(String, String)> = Vec::new(); // conversation -> chair
    let mut events_seen = 0;
    for step in 0..steps {
        let now_s = fleet.time_s();
        while let Some((at_s, action)) = schedule.get(next) {
            if *at_s > now_s + 1e-9 {
                break;
            }
            next += 1;
            let line = match action {
                Cue::Goal(g, point) => {
                    seen.push(Observation::GoalGiven {
                        time_s: now_s,
                        chair: g.chair.clone(),
                        target: [point.x, point.y],
                    });
                    match fleet.goal(&g.chair, *point) {
                        Ok(conversation) => {
                            conversations.push((conversation.clone(), g.chair.clone()));
                            format!(
                                "goal {} -> ({:.2}, {:.2}) [{conversation}]",
                                g.chair, point.x, point.y
                            )
                        }
                        // no path (e.g. behind a jammed door): the goal fails before any request
                        Err(FleetError::Plan { reason }) => {
                            seen.push(Observation::NoPath {
                                time_s: now_s,
                                chair: g.chair.clone(),
                            });
                            format!(
                                "goal {} -> ({:.2}, {:.2}) failed: no path: {reason}",
                                g.chair, point.x, point.y
                            )
                        }
                        Err(e) => return Err(fleet_err(now_s)(e)),
                    }
                }
                Cue::Door(d) => {
                    fleet.set_door(&d.door, d.open).map_err(fleet_err(now_s))?;
                    format!(
                        "door {} {}",
                        d.door,
                        if d.open { "opened" } else { "closed" }
                    )
                }
                Cue::Fault(f) => {
                    match f {
                        Fault::LinkLoss { container, .. } => fleet.set_link(container, false),
                        Fault::KillAgent {
                            container, agent, ..
                        } => fleet.kill_agent(container, agent),
                        Fault::SensorFailure { chair, sensor, .. } => {
                            fleet.set_sensor_failure(chair, *sensor, true)
                        }
                        Fault::LaserBlind { chair, .. } => fleet.set_laser_blind(chair, true),
                        Fault::JammedDoor { door, .. } => fleet.jam_door(door),
                        Fault::KillContainer { .. } => {
                            return Err(scenario.invalid(
                                "fault",
                                "a killed container cannot be played in one process",
                            ));
                        }
                    }
                    .map_err(fleet_err(now_s))?;
                    format!("fault {}", serde_json::to_string(f).unwrap_or_default())
                }
                Cue::LinkUp(container) => {
                    fleet.set_link(container, true).map_err(fleet_err(now_s))?;
                    format!("link {container} restored")
                }
                Cue::LaserBack(chair) => {
                    fleet
                        .set_laser_blind(chair, false)
                        .map_err(fleet_err(now_s))?;
                    format!("laser of {chair} restored")
                }
                Cue::SensorsBack(chair, sensor) => {
                    fleet
                        .set_sensor_failure(chair, *sensor, false)
                        .map_err(fleet_err(now_s))?;
                    format!("sensor {sensor} of {chair} restored")
                }
            };
            timeline.push(format!("{now_s:7.2} s: {line}"));
        }
        fleet.step(dt);
        let snapshot = fleet.snapshot();
        let events = fleet.goal_events();
        for event in events.iter().skip(events_seen) {
            timeline.push(format!(
                "{:7.2} s: {} from {} [{}]",
                event.time_s, event.performative, event.from, event.conversation
            ));
            let chair = conversations
                .iter()
                .find(|(conversation, _)| conversation == &event.conversation);
            if let (Some((_, chair)), Ok(performative)) = (chair, event.performative.parse()) {
                seen.push(Observation::Answer {
                    time_s: event.time_s,
                    chair: chair.clone(),
                    performative,
                });
            }
        }
        events_seen = events.len();
        seen.extend(snapshot.chairs.iter().map(|c| Observation::Body {
            time_s: snapshot.time_s,
            chair: c.name.clone(),
            pose: c.pose,
            speed_mps: c.twist[0].abs(),
            distance_m: c.distance_m,
            collisions: c.collisions,
        }));
        progress(step + 1, steps);
    }

    // what is in flight reaches its receivers (and the log) without time passing
    fleet.quiesce(MAX_QUIESCE_ROUNDS);
    let sent = fleet.messages_sent();
    let logged = fleet.messages_logged().map_err(fleet_err(fleet.time_s()))?;
    let snapshot = fleet.snapshot();
    let exchanges = fleet.exchanges();
    let totals = Totals {
        messages: exchanges.len() as u64,
        dropped: exchanges.iter().filter(|e| e.dropped).count() as u64,
        sent,
        logged,
    };
    // the frames delivered, typed (a frame that does not parse is not a message anyone got)
    seen.extend(
        exchanges
            .iter()
            .filter(|e| !e.dropped)
            .filter_map(|e| iw_acl::codec::parse(&e.acl).ok())
            .map(|m| Observation::Message(Box::new(m))),
    );
    let chairs: Vec<ChairSummary> = snapshot
        .chairs
        .iter()
        .map(|c| ChairSummary {
            name: c.name.clone(),
            pose: c.pose,
            distance_m: c.distance_m,
            collisions: c.collisions,
            agents: c.agents.clone(),
        })
        .collect();
    let outcomes = check(scenario, &seen, &totals, &chairs);
    let trace = exchanges
        .iter()
        .map(|e| {
            format!(
                "{} -> {}{}: {}",
                e.sender,
                e.receiver,
                if e.dropped { " [dropped]" } else { "" },
                e.acl
            )
        })
        .collect();
    Ok(Report {
        name: scenario.name.clone(),
        mode: Mode::InProcess,
        seed: scenario.seed,
        simulated_s: snapshot.time_s,
        passed: outcomes.iter().all(|o| o.passed),
        outcomes,
        chairs,
        timeline,
        messages: totals.messages,
        dropped: totals.dropped,
        sent,
        logged,
        trace,
    })
}
