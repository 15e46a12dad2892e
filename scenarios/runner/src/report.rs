//! What a run gives back: per-assertion outcomes, the chairs at the end, the timeline and the
//! traffic, as text ([`Report::render`]) or JSON (serde). Both modes give the same shape.

use serde::{Deserialize, Serialize};

/// How a scenario is played.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// Every container in this process, on a lockstep network, in simulated time (mock clock,
    /// fixed step): deterministic and faster than real time.
    #[default]
    InProcess,
    /// One `intellwheels spawn` process per container (world, services, each chair) over
    /// loopback UDP, in real time: the deployment.
    Processes,
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
    /// How it was played.
    pub mode: Mode,
    /// Its seed.
    pub seed: u64,
    /// Time run, s: simulated in process, wall-clock time since every container joined across
    /// processes.
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
            "scenario {} (seed {}), {:.1} s {}\n",
            self.name,
            self.seed,
            self.simulated_s,
            match self.mode {
                Mode::InProcess => "simulated",
                Mode::Processes => "in real time across processes",
            }
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
