//! Scripted scenarios (thesis 3.3, issue "scenarios"): a TOML file names the map, the chairs,
//! their goals over time, injected faults and assertions; [`run`] plays it over an
//! [`iw_fleet::Fleet`] in simulated time (mock clock, fixed step, faster than real time) and
//! returns a pass/fail [`Report`].
//!
//! # Organization
//! - [`Scenario`]: the file, [`Scenario::load`] / [`Scenario::parse`] (format in
//!   `docs/scenario-format.md`), checked by [`Scenario::validate`] against its map.
//! - [`Fault`], [`Assertion`]: what can be injected and what can be checked.
//! - [`run`] → [`Report`] (text with [`Report::render`], JSON via serde).
//!
//! # Guarantees
//! - Every input error names the file and the offending entry; no file content panics.
//! - Deterministic: the same file (seed included) gives the same report and the same message
//!   trace, bit for bit.
#![warn(missing_docs)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use iw_fleet::{BodyKind, ChairConfig, Fleet, FleetError, FleetOptions};
use iw_sim::Map;
use nalgebra::{Isometry2, Point2, Vector2};
use serde::{Deserialize, Serialize};

/// What went wrong loading or running a scenario (not an assertion failing: that is a report).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario `{path}`: {source}")]
    Io {
        /// The path.
        path: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// Not valid TOML or not the scenario schema.
    #[error("{path}: {reason}")]
    Parse {
        /// The file.
        path: String,
        /// What the TOML reader said (with line and column).
        reason: String,
    },
    /// Well-formed but inconsistent (unknown chair, place, door, bad number).
    #[error("{path}: {entry}: {reason}")]
    Invalid {
        /// The file.
        path: String,
        /// The entry, e.g. `goal[2]`.
        entry: String,
        /// Why.
        reason: String,
    },
    /// The map could not be loaded.
    #[error("{path}: map: {source}")]
    Map {
        /// The scenario file.
        path: String,
        /// The simulator's error.
        source: iw_sim::SimError,
    },
    /// The fleet refused during the run.
    #[error("{path}: at {time_s:.2} s: {source}")]
    Fleet {
        /// The scenario file.
        path: String,
        /// When.
        time_s: f64,
        /// What the fleet said.
        source: FleetError,
    },
}

/// A chair of the scenario.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ChairEntry {
    /// Its name (its container's name).
    pub name: String,
    /// A `start` or `place` of the map to start at.
    #[serde(default)]
    pub start: Option<String>,
    /// Or an explicit pose: x m, y m, heading degrees.
    #[serde(default)]
    pub pose: Option<[f64; 3]>,
    /// `virtual` (default), `real` (the serial driver against the interface board emulated on a
    /// pty, its pose fed into the world) or `mixed` (real, plus the virtual sonars).
    #[serde(default)]
    pub body: BodyKind,
}

/// A restricted door: only the listed chairs get it opened; the door agent refuses the others.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RestrictedEntry {
    /// The door id.
    pub door: String,
    /// The chairs allowed through.
    #[serde(default)]
    pub authorised: Vec<String>,
}

/// A goal given to a chair at a time.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GoalEntry {
    /// When, s.
    pub at_s: f64,
    /// Which chair.
    pub chair: String,
    /// A place of the map...
    #[serde(default)]
    pub place: Option<String>,
    /// ...or a point, m.
    #[serde(default)]
    pub xy: Option<[f64; 2]>,
}

/// A door opened or closed at a time.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DoorEntry {
    /// When, s.
    pub at_s: f64,
    /// The door id.
    pub door: String,
    /// Open (true) or closed.
    pub open: bool,
}

/// An injected fault.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Fault {
    /// A container's link to the others is down from `at_s` for `for_s` (forever if absent).
    LinkLoss {
        /// When, s.
        at_s: f64,
        /// A chair name or `services`.
        container: String,
        /// Duration, s.
        #[serde(default)]
        for_s: Option<f64>,
    },
    /// An agent is removed from its container.
    KillAgent {
        /// When, s.
        at_s: f64,
        /// A chair name or `services`.
        container: String,
        /// The agent's role: `perception`, `control`, `cognitive`, `interface` in a chair;
        /// `door`, `logger`, `watcher`, `assistant`, `staff` in `services`.
        agent: String,
    },
    /// Every sensor read of a chair fails from `at_s` for `for_s` (forever if absent).
    SensorFailure {
        /// When, s.
        at_s: f64,
        /// The chair.
        chair: String,
        /// Duration, s.
        #[serde(default)]
        for_s: Option<f64>,
    },
    /// A door closes and stays closed.
    JammedDoor {
        /// When, s.
        at_s: f64,
        /// The door id.
        door: String,
    },
}

impl Fault {
    fn at_s(&self) -> f64 {
        match self {
            Fault::LinkLoss { at_s, .. }
            | Fault::KillAgent { at_s, .. }
            | Fault::SensorFailure { at_s, .. }
            | Fault::JammedDoor { at_s, .. } => *at_s,
        }
    }
}

/// What must hold.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Assertion {
    /// The chair (every chair if absent) never touches anything.
    NoCollision {
        /// The chair.
        #[serde(default)]
        chair: Option<String>,
    },
    /// The chair's last goal is within `within_m` (default 0.5 m) by `by_s`, and its cognitive
    /// agent reported it done (relayed by the assistant).
    GoalReached {
        /// The chair.
        chair: String,
        /// Deadline, s.
        by_s: f64,
        /// Tolerance, m.
        #[serde(default = "half_metre")]
        within_m: f64,
    },
    /// The chair's cognitive agent reported a goal failed (FAILURE, relayed by the assistant) by
    /// `by_s`.
    GoalFailed {
        /// The chair.
        chair: String,
        /// Deadline, s.
        by_s: f64,
    },
    /// From `from_s` to the end the chair's speed stays below 2 cm/s.
    Stopped {
        /// The chair.
        chair: String,
        /// From when, s.
        from_s: f64,
    },
    /// At least `at_least` frames between containers were lost to link faults.
    MessagesDropped {
        /// The minimum.
        at_least: u64,
    },
    /// The door agent refused to open `door` for `chair` (restricted) and logged the refusal.
    DoorRefused {
        /// The chair.
        chair: String,
        /// The door id.
        door: String,
    },
    /// The door agent answered FAILURE for `door` (it could not move it: jammed).
    DoorFailed {
        /// The door id.
        door: String,
    },
    /// Every message the agents sent is in the logger agent's log (counted against the traffic
    /// at the end, once in-flight messages are delivered).
    AllMessagesLogged,
}

fn half_metre() -> f64 {
    0.5
}

/// A scenario file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Its name.
    pub name: String,
    /// What it shows.
    #[serde(default)]
    pub description: String,
    /// The map file, relative to the scenario file.
    pub map: PathBuf,
    /// The simulator's seed.
    #[serde(default)]
    pub seed: u64,
    /// Simulated length, s.
    pub duration_s: f64,
    /// Fixed step, ms.
    #[serde(default = "default_step_ms")]
    pub step_ms: u64,
    /// Virtual chairs' perception agents run RGB-D visual odometry on the rendered camera.
    #[serde(default)]
    pub visual_odometry: bool,
    /// The chairs.
    #[serde(rename = "chair")]
    pub chairs: Vec<ChairEntry>,
    /// Goals over time.
    #[serde(default, rename = "goal")]
    pub goals: Vec<GoalEntry>,
    /// Door commands over time.
    #[serde(default, rename = "door")]
    pub doors: Vec<DoorEntry>,
    /// Injected faults.
    #[serde(default, rename = "fault")]
    pub faults: Vec<Fault>,
    /// Restricted doors.
    #[serde(default, rename = "restricted")]
    pub restricted: Vec<RestrictedEntry>,
    /// What must hold.
    #[serde(default, rename = "assert")]
    pub assertions: Vec<Assertion>,
    /// Where it was read from (for relative paths and messages).
    #[serde(skip)]
    pub source: PathBuf,
}

fn default_step_ms() -> u64 {
    50
}

impl Scenario {
    /// Reads and parses `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ScenarioError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses `text` as if read from `path`.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let mut scenario: Scenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        scenario.source = path.to_path_buf();
        Ok(scenario)
    }

    fn invalid(&self, entry: impl Into<String>, reason: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid {
            path: self.source.display().to_string(),
            entry: entry.into(),
            reason: reason.into(),
        }
    }

    /// The map, resolved beside the scenario file.
    pub fn load_map(&self) -> Result<Map, ScenarioError> {
        let base = self.source.parent().unwrap_or(Path::new("."));
        Map::load(base.join(&self.map)).map_err(|source| ScenarioError::Map {
            path: self.source.display().to_string(),
            source,
        })
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
        if self.step_ms == 0 || self.step_ms > 1000 {
            return Err(self.invalid(
                "step_ms",
                format!("{} is not in [1, 1000] ms", self.step_ms),
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
                } => {
                    chair(entry.clone(), c)?;
                    if let Some(d) = for_s {
                        span(entry, *d)?;
                    }
                }
                Fault::JammedDoor { door: d, .. } => door(entry, d)?,
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
                .map_err(|e| self.invalid(format!("chair[{i}]"), e.to_string()))?;
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

    fn start_of(&self, chair: &ChairEntry, map: &Map) -> Result<Isometry2<f64>, String> {
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

    fn goal_point(&self, goal: &GoalEntry, map: &Map) -> Result<Point2<f64>, String> {
        match (&goal.place, goal.xy) {
            (Some(name), None) => map
                .place(name)
                .ok_or_else(|| format!("no place `{name}` in the map")),
            (None, Some([x, y])) if x.is_finite() && y.is_finite() => Ok(Point2::new(x, y)),
            _ => Err("give exactly one of `place` (a name) or `xy` ([x, y], finite)".into()),
        }
    }
}

/// One assertion's outcome.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outcome {
    /// The assertion, as written.
    pub assertion: String,
    /// Whether it held.
    pub passed: bool,
    /// What was observed.
    pub detail: String,
}

/// One chair at the end of the run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChairSummary {
    /// Its name.
    pub name: String,
    /// Final pose: x m, y m, heading rad.
    pub pose: [f64; 3],
    /// Distance driven, m.
    pub distance_m: f64,
    /// Contacts.
    pub collisions: u64,
    /// Its agents at the end.
    pub agents: Vec<String>,
}

/// The result of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// Scenario name.
    pub name: String,
    /// Its seed.
    pub seed: u64,
    /// Simulated time run, s.
    pub simulated_s: f64,
    /// Every assertion held.
    pub passed: bool,
    /// Per assertion.
    pub outcomes: Vec<Outcome>,
    /// The chairs at the end.
    pub chairs: Vec<ChairSummary>,
    /// What happened, in order (`time_s: text`): goals, faults, answers.
    pub timeline: Vec<String>,
    /// Frames between containers, delivered and dropped.
    pub messages: u64,
    /// Frames lost to link faults.
    pub dropped: u64,
    /// Messages the agents sent (each once).
    pub sent: u64,
    /// Records in the logger agent's log.
    pub logged: u64,
    /// Every frame between containers: `sender -> receiver [dropped]: ACL`.
    pub trace: Vec<String>,
}

impl Report {
    /// The human-readable report.
    pub fn render(&self) -> String {
        let mut out = format!(
            "scenario {} (seed {}), {:.1} s simulated\n",
            self.name, self.seed, self.simulated_s
        );
        for line in &self.timeline {
            out.push_str(&format!("  {line}\n"));
        }
        for c in &self.chairs {
            out.push_str(&format!(
                "  {}: at ({:.2}, {:.2}, {:.0} deg), {:.2} m driven, {} collisions, agents {}\n",
                c.name,
                c.pose[0],
                c.pose[1],
                c.pose[2].to_degrees(),
                c.distance_m,
                c.collisions,
                c.agents.join(" ")
            ));
        }
        out.push_str(&format!(
            "  {} messages between containers, {} dropped\n",
            self.messages, self.dropped
        ));
        out.push_str(&format!(
            "  {} messages sent by agents, {} in the log\n",
            self.sent, self.logged
        ));
        for o in &self.outcomes {
            out.push_str(&format!(
                "  [{}] {}: {}\n",
                if o.passed { "PASS" } else { "FAIL" },
                o.assertion,
                o.detail
            ));
        }
        out.push_str(if self.passed { "PASS\n" } else { "FAIL\n" });
        out
    }
}

/// Something scheduled in the run.
enum Action<'a> {
    Goal(&'a GoalEntry, Point2<f64>),
    Door(&'a DoorEntry),
    Fault(&'a Fault),
    LinkUp(&'a str),
    SensorsBack(&'a str),
}

/// Per-assertion observations gathered while running.
#[derive(Default, Clone)]
struct Watch {
    reached_at: Option<f64>,
    max_speed: f64,
}

/// Rounds of message delivery without time passing at the end of a run.
const MAX_QUIESCE_ROUNDS: usize = 16;

/// Runs `scenario` to its end and checks its assertions.
pub fn run(scenario: &Scenario) -> Result<Report, ScenarioError> {
    run_with_progress(scenario, |_, _| {})
}

/// [`run`], calling `progress(step, steps)` after each step.
pub fn run_with_progress(
    scenario: &Scenario,
    mut progress: impl FnMut(u64, u64),
) -> Result<Report, ScenarioError> {
    let mut map = scenario.load_map()?;
    scenario.validate(&map)?;
    // A goal given as a point becomes a place of the map, so the cognitive agents can plan to it.
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
    let mut schedule: Vec<(f64, Action)> = Vec::new();
    for g in &scenario.goals {
        let point = scenario
            .goal_point(g, &map)
            .map_err(|reason| scenario.invalid(g.chair.clone(), reason))?;
        schedule.push((g.at_s, Action::Goal(g, point)));
    }
    schedule.extend(scenario.doors.iter().map(|d| (d.at_s, Action::Door(d))));
    for f in &scenario.faults {
        schedule.push((f.at_s(), Action::Fault(f)));
        match f {
            Fault::LinkLoss {
                at_s,
                container,
                for_s: Some(d),
            } => schedule.push((at_s + d, Action::LinkUp(container))),
            Fault::SensorFailure {
                at_s,
                chair,
                for_s: Some(d),
            } => schedule.push((at_s + d, Action::SensorsBack(chair))),
            _ => {}
        }
    }
    // stable: entries at one time keep file order (goals, doors, faults)
    schedule.sort_by(|a, b| a.0.total_cmp(&b.0));

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
    };
    let mut fleet =
        Fleet::with_options(map, scenario.seed, &configs, options).map_err(fleet_err(0.0))?;
    let dt = Duration::from_millis(scenario.step_ms);
    let steps = (scenario.duration_s * 1000.0 / scenario.step_ms as f64).ceil() as u64;
    let mut timeline = Vec::new();
    let mut next = 0;
    let mut conversations: Vec<(String, String)> = Vec::new(); // conversation -> chair
    let mut watches = vec![Watch::default(); scenario.assertions.len()];
    let mut events_seen = 0;
    let mut unplannable: Vec<(String, f64)> = Vec::new(); // chair, time
    for step in 0..steps {
        let now_s = fleet.time_s();
        while let Some((at_s, action)) = schedule.get(next) {
            if *at_s > now_s + 1e-9 {
                break;
            }
            next += 1;
            let line = match action {
                Action::Goal(g, point) => match fleet.goal(&g.chair, *point) {
                    Ok(conversation) => {
                        conversations.push((conversation.clone(), g.chair.clone()));
                        format!(
                            "goal {} -> ({:.2}, {:.2}) [{conversation}]",
                            g.chair, point.x, point.y
                        )
                    }
                    // no path (e.g. behind a jammed door): the goal fails before any request
                    Err(FleetError::Plan { reason }) => {
                        unplannable.push((g.chair.clone(), now_s));
                        format!(
                            "goal {} -> ({:.2}, {:.2}) failed: no path: {reason}",
                            g.chair, point.x, point.y
                        )
                    }
                    Err(e) => return Err(fleet_err(now_s)(e)),
                },
                Action::Door(d) => {
                    fleet.set_door(&d.door, d.open).map_err(fleet_err(now_s))?;
                    format!(
                        "door {} {}",
                        d.door,
                        if d.open { "opened" } else { "closed" }
                    )
                }
                Action::Fault(f) => {
                    match f {
                        Fault::LinkLoss { container, .. } => fleet.set_link(container, false),
                        Fault::KillAgent {
                            container, agent, ..
                        } => fleet.kill_agent(container, agent),
                        Fault::SensorFailure { chair, .. } => fleet.set_sensor_failure(chair, true),
                        Fault::JammedDoor { door, .. } => fleet.jam_door(door),
                    }
                    .map_err(fleet_err(now_s))?;
                    format!("fault {}", serde_json::to_string(f).unwrap_or_default())
                }
                Action::LinkUp(container) => {
                    fleet.set_link(container, true).map_err(fleet_err(now_s))?;
                    format!("link {container} restored")
                }
                Action::SensorsBack(chair) => {
                    fleet
                        .set_sensor_failure(chair, false)
                        .map_err(fleet_err(now_s))?;
                    format!("sensors of {chair} restored")
                }
            };
            timeline.push(format!("{now_s:7.2} s: {line}"));
        }
        fleet.step(dt);
        let snapshot = fleet.snapshot();
        for event in fleet.goal_events().iter().skip(events_seen) {
            timeline.push(format!(
                "{:7.2} s: {} from {} [{}]",
                event.time_s, event.performative, event.from, event.conversation
            ));
        }
        events_seen = fleet.goal_events().len();
        for (assertion, watch) in scenario.assertions.iter().zip(&mut watches) {
            match assertion {
                Assertion::GoalReached {
                    chair, within_m, ..
                } => {
                    let c = snapshot.chairs.iter().find(|c| &c.name == chair);
                    let near = c.and_then(|c| {
                        c.goal
                            .map(|g| ((c.pose[0] - g[0]).hypot(c.pose[1] - g[1])) <= *within_m)
                    });
                    if near == Some(true) && watch.reached_at.is_none() {
                        watch.reached_at = Some(snapshot.time_s);
                    }
                }
                Assertion::Stopped { chair, from_s } if snapshot.time_s >= *from_s => {
                    if let Some(c) = snapshot.chairs.iter().find(|c| &c.name == chair) {
                        watch.max_speed = watch.max_speed.max(c.twist[0].abs());
                    }
                }
                _ => {}
            }
        }
        progress(step + 1, steps);
    }

    // what is in flight reaches its receivers (and the log) without time passing
    fleet.quiesce(MAX_QUIESCE_ROUNDS);
    let sent = fleet.messages_sent();
    let logged = fleet.messages_logged().map_err(fleet_err(fleet.time_s()))?;
    let refusals = fleet.door_refusals();
    let snapshot = fleet.snapshot();
    let events = fleet.goal_events();
    let exchanges = fleet.exchanges();
    let dropped = exchanges.iter().filter(|e| e.dropped).count() as u64;
    let answered = |chair: &str, performative: &str, by_s: f64| {
        events.iter().find(|e| {
            e.performative == performative
                && e.time_s <= by_s + 1e-9
                && conversations
                    .iter()
                    .any(|(conv, c)| conv == &e.conversation && c == chair)
        })
    };
    let outcomes: Vec<Outcome> = scenario
        .assertions
        .iter()
        .zip(&watches)
        .map(|(assertion, watch)| {
            let text = serde_json::to_string(assertion).unwrap_or_default();
            let (passed, detail) = match assertion {
                Assertion::NoCollision { chair } => {
                    let hits: Vec<String> = snapshot
                        .chairs
                        .iter()
                        .filter(|c| chair.as_ref().is_none_or(|n| n == &c.name) && c.collisions > 0)
                        .map(|c| format!("{} {}", c.name, c.collisions))
                        .collect();
                    (
                        hits.is_empty(),
                        if hits.is_empty() {
                            "no contact".into()
                        } else {
                            format!("contacts: {}", hits.join(", "))
                        },
                    )
                }
                Assertion::GoalReached { chair, by_s, .. } => {
                    let done = answered(chair, "INFORM", *by_s);
                    let reached = watch.reached_at.filter(|t| *t <= *by_s + 1e-9);
                    let detail = match (reached, done) {
                        (Some(t), Some(d)) => format!(
                            "within tolerance at {t:.2} s, done reported at {:.2} s",
                            d.time_s
                        ),
                        (Some(t), None) => {
                            format!("within tolerance at {t:.2} s but no done reported by {by_s} s")
                        }
                        (None, _) => format!("not within tolerance by {by_s} s"),
                    };
                    (reached.is_some() && done.is_some(), detail)
                }
                Assertion::GoalFailed { chair, by_s } => {
                    let unplanned = unplannable
                        .iter()
                        .find(|(c, t)| c == chair && *t <= *by_s + 1e-9);
                    match (answered(chair, "FAILURE", *by_s), unplanned) {
                        (Some(e), _) => (true, format!("failure reported at {:.2} s", e.time_s)),
                        (None, Some((_, t))) => (true, format!("no path at {t:.2} s")),
                        (None, None) => (false, format!("no failure reported by {by_s} s")),
                    }
                }
                Assertion::Stopped { .. } => (
                    watch.max_speed < 0.02,
                    format!("highest speed afterwards {:.3} m/s", watch.max_speed),
                ),
                Assertion::MessagesDropped { at_least } => {
                    (dropped >= *at_least, format!("{dropped} dropped"))
                }
                Assertion::DoorRefused { chair, door } => {
                    let requester = format!("cognitive@{chair}");
                    let name = iw_fleet::compose::door_name(door);
                    match refusals
                        .iter()
                        .find(|r| r.requester == requester && r.door == name)
                    {
                        Some(r) => (
                            true,
                            format!("refused at {:.2} s: {}", r.time_ns as f64 * 1e-9, r.reason),
                        ),
                        None => (
                            false,
                            format!(
                                "{} refusals, none of `{name}` for {requester}",
                                refusals.len()
                            ),
                        ),
                    }
                }
                Assertion::DoorFailed { door } => {
                    let name = iw_fleet::compose::door_name(door);
                    let failures = exchanges
                        .iter()
                        .filter(|e| {
                            e.sender == "door@services"
                                && e.acl.starts_with("(FAILURE")
                                && e.acl.contains(&name)
                        })
                        .count();
                    (
                        failures > 0,
                        format!("{failures} FAILURE answers about `{name}`"),
                    )
                }
                Assertion::AllMessagesLogged => (
                    sent > 0 && logged == sent,
                    format!("{sent} messages sent, {logged} in the log"),
                ),
            };
            Outcome {
                assertion: text,
                passed,
                detail,
            }
        })
        .collect();
    let chairs = snapshot
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
        seed: scenario.seed,
        simulated_s: snapshot.time_s,
        passed: outcomes.iter().all(|o| o.passed),
        outcomes,
        chairs,
        timeline,
        messages: exchanges.len() as u64,
        dropped,
        sent,
        logged,
        trace,
    })
}
