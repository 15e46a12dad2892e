//! Checks a scenario against its map, and against what the mode it runs in can do.

use std::time::Duration;

use iw_fleet::compose::world_link::FailedSensor;
use iw_sim::Map;
use nalgebra::{Isometry2, Point2, Vector2};

use crate::ScenarioError;
use crate::report::Mode;
use crate::schema::{Assertion, ChairEntry, Fault, GoalEntry, Scenario};

impl Scenario {
    /// [`Scenario::validate`], and refuses what `mode` cannot play: a killed container in one
    /// process; a failure of every body read, jammed doors and door commands across processes
    /// (their world container takes no such commands: a world that sends a chair nothing is an
    /// outage the chair waits out, not a failed sensor).
    pub fn validate_for(&self, map: &Map, mode: Mode) -> Result<(), ScenarioError> {
        self.validate(map)?;
        let unsupported = |entry: String, what: &str| {
            Err(self.invalid(
                entry,
                format!(
                    "{what} cannot be played {}",
                    match mode {
                        Mode::InProcess => "in one process (run it with --processes)",
                        Mode::Processes => "across processes (run it without --processes)",
                    }
                ),
            ))
        };
        for (i, f) in self.faults.iter().enumerate() {
            let entry = format!("fault[{i}]");
            match (mode, f) {
                (Mode::InProcess, Fault::KillContainer { .. }) => {
                    return unsupported(entry, "a killed container (kill-container)");
                }
                (
                    Mode::Processes,
                    Fault::SensorFailure {
                        sensor: FailedSensor::All,
                        ..
                    },
                ) => {
                    return unsupported(
                        entry,
                        "a failure of every body read (sensor-failure with sensor `all`, the \
                         default; `laser` and `sonars` can be played there)",
                    );
                }
                (Mode::Processes, Fault::JammedDoor { .. }) => {
                    return unsupported(entry, "a jammed door (jammed-door)");
                }
                _ => {}
            }
        }
        if mode == Mode::Processes && !self.doors.is_empty() {
            return unsupported("door[0]".into(), "a door command ([[door]])");
        }
        Ok(())
    }

    /// Checks names and numbers against `map`.
    pub fn validate(&self, map: &Map) -> Result<(), ScenarioError> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.duration_s) || self.duration_s > 3600.0 {
            return Err(self.invalid(
                "duration_s",
                format!("{} is not in (0, 3600] s", self.duration_s),
            ));
        }
        if self.step.is_zero() || self.step > Duration::from_secs(1) {
            return Err(self.invalid(
                "step_ms",
                format!("{} is not in [1, 1000] ms", self.step.as_millis()),
            ));
        }
        if self.chairs.is_empty() {
            return Err(self.invalid("chair", "a scenario needs at least one chair"));
        }
        let chair = |entry: String, name: &str| {
            if self.chairs.iter().any(|c| c.name == name) {
                Ok(())
            } else {
                Err(self.invalid(entry, format!("no chair `{name}`")))
            }
        };
        // An instant of the run: an event or check after its end would silently never happen.
        let time = |entry: String, t: f64| {
            if t.is_finite() && (0.0..=self.duration_s).contains(&t) {
                Ok(())
            } else {
                Err(self.invalid(
                    entry,
                    format!(
                        "time {t} s is not within the run, [0, {}] s (duration_s)",
                        self.duration_s
                    ),
                ))
            }
        };
        let span = |entry: String, t: f64| {
            if t.is_finite() && t >= 0.0 {
                Ok(())
            } else {
                Err(self.invalid(
                    entry,
                    format!("duration {t} s is not a non-negative number"),
                ))
            }
        };
        let door = |entry: String, id: &str| {
            if map.doors.iter().any(|d| d.id == id) {
                Ok(())
            } else {
                Err(self.invalid(entry, format!("no door `{id}` in the map")))
            }
        };
        let container = |entry: String, name: &str| {
            if name == iw_fleet::SERVICES {
                Ok(())
            } else {
                chair(entry, name)
            }
        };
        for (i, c) in self.chairs.iter().enumerate() {
            self.start_of(c, map)
                .map_err(|reason| self.invalid(format!("chair[{i}]"), reason))?;
            if c.name.is_empty()
                || c.name == iw_fleet::SERVICES
                || c.name.contains('@')
                || self.chairs[..i].iter().any(|o| o.name == c.name)
            {
                return Err(self.invalid(
                    format!("chair[{i}]"),
                    format!(
                        "name `{}` is empty, reserved, has `@` or is used twice",
                        c.name
                    ),
                ));
            }
        }
        self.check_start_poses(map)?;
        for (i, r) in self.restricted.iter().enumerate() {
            door(format!("restricted[{i}]"), &r.door)?;
            for c in &r.authorised {
                chair(format!("restricted[{i}]"), c)?;
            }
        }
        for (i, g) in self.goals.iter().enumerate() {
            chair(format!("goal[{i}]"), &g.chair)?;
            time(format!("goal[{i}]"), g.at_s)?;
            self.goal_point(g, map)
                .map_err(|reason| self.invalid(format!("goal[{i}]"), reason))?;
        }
        for (i, d) in self.doors.iter().enumerate() {
            door(format!("door[{i}]"), &d.door)?;
            time(format!("door[{i}]"), d.at_s)?;
        }
        for (i, f) in self.faults.iter().enumerate() {
            let entry = format!("fault[{i}]");
            time(entry.clone(), f.at_s())?;
            match f {
                Fault::LinkLoss {
                    container: c,
                    for_s,
                    ..
                } => {
                    container(entry.clone(), c)?;
                    if let Some(d) = for_s {
                        span(entry, *d)?;
                    }
                }
                Fault::KillAgent { container: c, .. } => container(entry, c)?,
                Fault::SensorFailure {
                    chair: c, for_s, ..
                }
                | Fault::LaserBlind {
                    chair: c, for_s, ..
                } => {
                    chair(entry.clone(), c)?;
                    if let Some(d) = for_s {
                        span(entry, *d)?;
                    }
                }
                Fault::JammedDoor { door: d, .. } => door(entry, d)?,
                Fault::KillContainer { container: c, .. } => {
                    if c != iw_fleet::compose::world_link::WORLD {
                        container(entry, c)?;
                    }
                }
            }
        }
        for (i, a) in self.assertions.iter().enumerate() {
            let entry = format!("assert[{i}]");
            match a {
                Assertion::NoCollision { chair: Some(c) } => chair(entry, c)?,
                Assertion::GoalReached {
                    chair: c,
                    by_s,
                    within_m,
                } => {
                    chair(entry.clone(), c)?;
                    time(entry.clone(), *by_s)?;
                    if !positive(*within_m) {
                        return Err(
                            self.invalid(entry, format!("within_m {within_m} must be positive"))
                        );
                    }
                    if !self.goals.iter().any(|g| &g.chair == c) {
                        return Err(self.invalid(entry, format!("chair `{c}` is given no goal")));
                    }
                }
                Assertion::LandmarkVisited {
                    chair: c,
                    from_s,
                    by_s,
                    within_m,
                } => {
                    chair(entry.clone(), c)?;
                    time(entry.clone(), *from_s)?;
                    time(entry.clone(), *by_s)?;
                    if from_s > by_s {
                        return Err(self
                            .invalid(entry, format!("from_s {from_s} s is after by_s {by_s} s")));
                    }
                    if !positive(*within_m) {
                        return Err(
                            self.invalid(entry, format!("within_m {within_m} must be positive"))
                        );
                    }
                    if map.landmarks.is_empty() {
                        return Err(self.invalid(
                            entry,
                            "the map has no landmark (a `landmark` statement) to visit",
                        ));
                    }
                }
                Assertion::GoalFailed { chair: c, by_s } => {
                    chair(entry.clone(), c)?;
                    time(entry, *by_s)?;
                }
                Assertion::Stopped { chair: c, from_s } => {
                    chair(entry.clone(), c)?;
                    time(entry, *from_s)?;
                }
                Assertion::DoorRefused { chair: c, door: d } => {
                    chair(entry.clone(), c)?;
                    door(entry, d)?;
                }
                Assertion::DoorFailed { door: d } => door(entry, d)?,
                Assertion::NoCollision { chair: None }
                | Assertion::MessagesDropped { .. }
                | Assertion::AllMessagesLogged => {}
            }
        }
        Ok(())
    }

    /// Refuses a chair whose footprint at its start overlaps a wall, furniture, a door closed at
    /// the start, or a chair listed before it: the run would begin in a collision.
    fn check_start_poses(&self, map: &Map) -> Result<(), ScenarioError> {
        let mut world = iw_sim::World::new(map.clone(), 0);
        for (i, c) in self.chairs.iter().enumerate() {
            let start = self
                .start_of(c, map)
                .map_err(|reason| self.invalid(format!("chair[{i}]"), reason))?;
            let id = world.add_chair(
                iw_sim::ChairSpec::default(),
                start,
                iw_sim::ChairKind::Simulated,
            );
            let obstruction = world
                .obstruction(id)
                .map_err(|source| ScenarioError::World {
                    path: self.source.display().to_string(),
                    entry: format!("chair[{i}]"),
                    source,
                })?;
            if let Some(what) = obstruction {
                let what = match what {
                    iw_sim::Owner::Chair(j) => {
                        format!("chair[{j}] `{}`", self.chairs[j].name)
                    }
                    other => world.describe(other),
                };
                return Err(self.invalid(
                    format!("chair[{i}]"),
                    format!(
                        "`{}` starts at ({:.2}, {:.2}) overlapping {what}",
                        c.name, start.translation.x, start.translation.y
                    ),
                ));
            }
        }
        Ok(())
    }

    pub(crate) fn start_of(&self, chair: &ChairEntry, map: &Map) -> Result<Isometry2<f64>, String> {
        match (&chair.start, chair.pose) {
            (Some(name), None) => map
                .start(name)
                .or_else(|| map.place(name).map(|p| Isometry2::new(p.coords, 0.0)))
                .ok_or_else(|| format!("no start or place `{name}` in the map")),
            (None, Some([x, y, deg])) if x.is_finite() && y.is_finite() && deg.is_finite() => {
                Ok(Isometry2::new(Vector2::new(x, y), deg.to_radians()))
            }
            _ => Err(
                "give exactly one of `start` (a name) or `pose` ([x, y, heading_deg], finite)"
                    .into(),
            ),
        }
    }

    pub(crate) fn goal_point(&self, goal: &GoalEntry, map: &Map) -> Result<Point2<f64>, String> {
        match (&goal.place, goal.xy) {
            (Some(name), None) => map
                .place(name)
                .ok_or_else(|| format!("no place `{name}` in the map")),
            (None, Some([x, y])) if x.is_finite() && y.is_finite() => Ok(Point2::new(x, y)),
            _ => Err("give exactly one of `place` (a name) or `xy` ([x, y], finite)".into()),
        }
    }
}
