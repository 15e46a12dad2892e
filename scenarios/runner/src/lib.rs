//! Scripted scenarios (thesis 3.3, issue "scenarios"): a TOML file names the map, the chairs,
//! their goals over time, injected faults and assertions; [`run`] plays it over an
//! [`iw_fleet::Fleet`] in simulated time (mock clock, fixed step, faster than real time),
//! [`run_processes`] plays the same file as the deployment (one `intellwheels spawn` process
//! per container over loopback UDP, in real time); both return the same pass/fail [`Report`].
//!
//! # Organization
//! - [`schema`]: the file, [`Scenario::load`] / [`Scenario::parse`] (format in
//!   `docs/scenario-format.md`); [`Fault`], [`Assertion`]: what can be injected and checked.
//! - `validation`: [`Scenario::validate`] against its map, [`Scenario::validate_for`] against
//!   what a [`Mode`] can play.
//! - [`schedule`]: goals, doors and faults as one time-ordered list.
//! - [`observe`]: [`Observation`], the typed events both modes produce.
//! - [`assertions`]: each assertion checked over observations.
//! - [`run()`](run()) (in process) and [`process`] ([`run_processes`]).
//! - [`report`]: [`Report`] (text with [`Report::render`], JSON via serde).
//!
//! # Guarantees
//! - Every input error names the file and the offending entry; no file content panics.
//! - In process, deterministic: the same file (seed included) gives the same report and the
//!   same message trace, bit for bit. Across processes the run is real time; the outcomes, not
//!   the trace, are what compare.
//! - Across processes every child process is killed and reaped on every exit path (an error,
//!   a panic) when the run is dropped.
#![warn(missing_docs)]

pub mod assertions;
pub mod observe;
pub mod process;
pub mod report;
mod run;
pub mod schedule;
pub mod schema;
mod validation;

use iw_fleet::FleetError;

pub use observe::{Observation, Totals};
pub use process::{ProcessOptions, run_processes};
pub use report::{ChairSummary, Mode, Outcome, Report};
pub use run::{run, run_with_progress};
pub use schema::{
    Assertion, ChairEntry, DoorEntry, Fault, GoalEntry, MAX_SCENARIO_BYTES, RestrictedEntry,
    Scenario,
};

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
    #[error("{path}: {source}")]
    Parse {
        /// The file.
        path: String,
        /// What the TOML reader said (with line and column).
        source: toml::de::Error,
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
    /// The simulator refused an entry (e.g. a chair it cannot place).
    #[error("{path}: {entry}: {source}")]
    World {
        /// The file.
        path: String,
        /// The entry, e.g. `chair[1]`.
        entry: String,
        /// What the simulator said.
        #[source]
        source: iw_sim::SimError,
    },
    /// The map could not be loaded.
    #[error("{path}: map: {source}")]
    Map {
        /// The scenario file.
        path: String,
        /// The simulator's error.
        source: iw_sim::SimError,
    },
    /// The map loads but does not make a building plan (its places, doors and landmarks).
    #[error("{path}: map: {source}")]
    Plan {
        /// The scenario file.
        path: String,
        /// What the building plan said.
        #[source]
        source: iw_fleet::compose::WiringError,
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
    /// A container process could not be started, written to or stopped (across processes).
    #[error("{path}: container `{container}`: {what}: {source}")]
    Spawn {
        /// The scenario file.
        path: String,
        /// The container.
        container: String,
        /// What was being done.
        what: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A container process misbehaved: it exited, or did not get ready or join in time
    /// (across processes). No error value is underneath: what the process said is its stderr.
    #[error("{path}: container `{container}`: {reason}{}", last_words_text(.last_words))]
    Container {
        /// The scenario file.
        path: String,
        /// The container.
        container: String,
        /// What happened.
        reason: String,
        /// The last lines the container wrote to stderr (empty: none).
        last_words: String,
    },
    /// The board emulator of a real or mixed chair could not be started (across processes).
    #[error("{path}: container `{container}`: emulating its board: {source}")]
    Board {
        /// The scenario file.
        path: String,
        /// The chair's container.
        container: String,
        /// What the emulator said.
        #[source]
        source: iw_body::BodyError,
    },
    /// The logger agent's log could not be read after a run across processes.
    #[error("{path}: the logger agent's log: {source}")]
    Log {
        /// The scenario file.
        path: String,
        /// What the log reader said.
        source: iw_logger::LogError,
    },
}

/// `; its last words:` and the lines, when the container wrote any.
fn last_words_text(lines: &str) -> String {
    if lines.is_empty() {
        String::new()
    } else {
        format!("; its last words:\n{lines}")
    }
}
