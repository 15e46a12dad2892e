//! What a container reports while it runs: one JSON object per line on stdout, so scripts and
//! tests follow a fleet of processes without scraping logs (and the scenario runner reads them
//! back typed).

use serde::{Deserialize, Serialize};

/// One report line. The `event` field names the variant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "kebab-case")]
pub enum Event {
    /// The container is up: its agents are registered and its addresses bound.
    Ready {
        /// The container's name.
        container: String,
        /// Its container id (lowest leads).
        id: u64,
        /// The agent bus address others reach it at.
        bus: String,
        /// Its agents.
        agents: Vec<String>,
    },
    /// A service the container serves besides the bus (services only): `dashboard`, or
    /// `mtp-http` (the FIPA HTTP MTP gateway; `url` is its transport address).
    Serving {
        /// The container's name.
        container: String,
        /// What it serves.
        service: String,
        /// Where (the dashboard's URL carries its token, as `intellwheels demo` prints it).
        url: String,
    },
    /// An agent of another container appeared in the Global Agent List (its container is live).
    Joined {
        /// The agent.
        agent: String,
        /// Its container id.
        container: u64,
    },
    /// An agent left: its container deregistered it or stopped answering heartbeats.
    Left {
        /// The agent.
        agent: String,
        /// Its container id.
        container: u64,
    },
    /// An answer about a goal (services only).
    Goal {
        /// The chair.
        chair: String,
        /// The goal's place.
        place: String,
        /// The conversation.
        conversation: String,
        /// AGREE, INFORM (done), FAILURE, REFUSE or NOT-UNDERSTOOD; FAILURE also when no path.
        performative: String,
        /// Why, for a FAILURE, REFUSE or NOT-UNDERSTOOD: the chair's `error-message` text (its
        /// content verbatim when it is not one), or what the services detected themselves.
        reason: Option<String>,
        /// Who gave the goal, for a goal the services learned of from the chair (asked when it
        /// joined) and did not follow: given by an earlier life of the services, or past them.
        /// Absent for the services' own goals.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        requester: Option<String>,
    },
    /// A chair's cognitive agent agreed to a goal the assistant forwarded (services only): the
    /// REQUEST/AGREE round trip in real time, each end's wait for its agent step included.
    Agreed {
        /// The chair.
        chair: String,
        /// From the REQUEST leaving the assistant to the AGREE reaching it, ms.
        round_trip_ms: f64,
    },
    /// A chair's pose as its perception agent published it (services only, rate-limited).
    Pose {
        /// The chair.
        chair: String,
        /// x, m (map frame).
        x_m: f64,
        /// y, m.
        y_m: f64,
        /// Heading, rad.
        theta_rad: f64,
    },
    /// Frames refused so far, per reason, when the counts changed (at most every 5 s): what an
    /// attack (or a broken peer) shows at the default level.
    Security {
        /// The container's name.
        container: String,
        /// Rejections on the agent bus (all layers), by reason (`bad_tag`, `unknown_session`,
        /// `duplicate`, `stale`, ...); reasons never seen are left out.
        bus: std::collections::BTreeMap<String, u64>,
        /// Rejections on the control channel (frames that do not decode or fail its group key).
        control: std::collections::BTreeMap<String, u64>,
    },
    /// A body in the shared world as the world sees it (world only, every
    /// `services.pose_report_ms`).
    Body {
        /// The chair.
        chair: String,
        /// True x, m (map frame).
        x_m: f64,
        /// True y, m.
        y_m: f64,
        /// True heading, rad.
        theta_rad: f64,
        /// Distance driven, m.
        distance_m: f64,
        /// Contacts with walls, furniture or other chairs so far.
        collisions: u64,
        /// The world's simulated time, s: real time since it started, except that a lockstep
        /// world's clock stands still while it waits for its bodies' wheel speeds.
        world_s: f64,
    },
    /// A chair's control agent handed its wheels the first non-zero command of a manual drive
    /// (chairs only; once per drive, not per command), read right after the agent step that did
    /// it: when, for `intellwheels bench drive`'s latency across processes.
    DriveApplied {
        /// The chair.
        chair: String,
        /// What shared control applied: linear, m/s.
        linear_mps: f64,
        /// Angular, rad/s.
        angular_radps: f64,
        /// Wall-clock time, ms since the Unix epoch.
        unix_ms: f64,
    },
    /// A chair's wheels took a command to move after a stop, or a stop after moving (chairs
    /// only; read after each agent step): when, so a test sees a chair stop on a lost world link.
    Wheels {
        /// The chair.
        chair: String,
        /// Whether the wheels now turn.
        moving: bool,
        /// Wall-clock time, ms since the Unix epoch.
        unix_ms: f64,
    },
    /// An admin command from the parent process (`--admin-stdin`) was carried out, or refused.
    Admin {
        /// The container's name.
        container: String,
        /// The command, as done (`goal CHAIR PLACE`, `kill-agent NAME`) or as read.
        done: String,
        /// Why it was refused, if it was.
        error: Option<String>,
    },
    /// The container has shut down cleanly.
    Stopped {
        /// The container's name.
        container: String,
        /// Messages its agents sent while it ran (each is copied to the logger).
        messages_sent: u64,
    },
}
