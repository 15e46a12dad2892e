//! The scenario file: its entries as typed values, read from TOML (format in
//! `docs/scenario-format.md`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use iw_fleet::BodyKind;
use iw_fleet::compose::world_link::FailedSensor;
use iw_sim::Map;
use serde::{Deserialize, Serialize};

use crate::ScenarioError;

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
    /// A chair's sensor fails from `at_s` for `for_s` (forever if absent): every body read
    /// (`sensor = "all"`, the default; in process only), or the laser's or the sonars'
    /// readings, which come as garbage while the rest reads on.
    SensorFailure {
        /// When, s.
        at_s: f64,
        /// The chair.
        chair: String,
        /// Which sensor.
        #[serde(default)]
        sensor: FailedSensor,
        /// Duration, s.
        #[serde(default)]
        for_s: Option<f64>,
    },
    /// A chair's laser returns nothing from `at_s` for `for_s` (forever if absent), as if
    /// covered, while its wheels, sonars and camera read on: its localizer drops the laser and
    /// dead-reckons.
    LaserBlind {
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
    /// A container process is killed outright (SIGKILL): no take-down runs, its agents leave
    /// when their lease expires, a real chair's board watchdog stops it. Process mode only
    /// (`--processes`): in one process there is no container to kill.
    KillContainer {
        /// When, s.
        at_s: f64,
        /// A chair name, `services` or `world`.
        container: String,
    },
}

impl Fault {
    /// When it strikes, s.
    pub fn at_s(&self) -> f64 {
        match self {
            Fault::LinkLoss { at_s, .. }
            | Fault::KillAgent { at_s, .. }
            | Fault::SensorFailure { at_s, .. }
            | Fault::LaserBlind { at_s, .. }
            | Fault::JammedDoor { at_s, .. }
            | Fault::KillContainer { at_s, .. } => *at_s,
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
    /// The chair came within `within_m` (default 0.5 m) of one of the points where a chair
    /// stops to read a landmark's marker (the cognitive agent's landmark stops) between `from_s`
    /// (default 0) and `by_s`: it detoured past a landmark.
    LandmarkVisited {
        /// The chair.
        chair: String,
        /// Not before, s.
        #[serde(default)]
        from_s: f64,
        /// Deadline, s.
        by_s: f64,
        /// Tolerance, m.
        #[serde(default = "half_metre")]
        within_m: f64,
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
    /// Fixed step (key `step_ms`, whole milliseconds).
    #[serde(rename = "step_ms", default = "default_step", with = "iw_bus::millis")]
    pub step: Duration,
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

fn default_step() -> Duration {
    Duration::from_millis(50)
}

/// Largest scenario file [`Scenario::load`] reads, bytes (a scenario is a page of TOML; a 2 GB
/// file made the TOML parser ask for 14 GB).
pub const MAX_SCENARIO_BYTES: u64 = 4 << 20;

impl Scenario {
    /// Reads (a regular file of at most [`MAX_SCENARIO_BYTES`]) and parses `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ScenarioError> {
        let path = path.as_ref();
        let text = iw_sim::file::read_text(path, MAX_SCENARIO_BYTES).map_err(|source| {
            ScenarioError::Io {
                path: path.display().to_string(),
                source,
            }
        })?;
        Self::parse(&text, path)
    }

    /// Parses `text` as if read from `path`.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let mut scenario: Scenario =
            toml::from_str(text).map_err(|source| ScenarioError::Parse {
                path: path.display().to_string(),
                source,
            })?;
        scenario.source = path.to_path_buf();
        Ok(scenario)
    }

    pub(crate) fn invalid(
        &self,
        entry: impl Into<String>,
        reason: impl Into<String>,
    ) -> ScenarioError {
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
}
