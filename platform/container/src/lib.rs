//! Agent containers (thesis 3.3.3): one process hosts many agents; each container keeps a Local
//! Agent List (LAL) and a copy of the Global Agent List (GAL) that an elected container
//! distributes, carrying each agent's public key and address.
//!
//! Organization:
//! - [`LocalAgentList`], [`GlobalAgentList`], [`AgentEntry`], [`Part`]: the lists; the GAL
//!   merges per container by generation (a version vector), so merges commute and repeat safely.
//! - [`Container`]: the pure state machine (heartbeats, leases, lowest-id election, list sync),
//!   driven with explicit [`iw_bus::Time`]; [`ContainerMsg`] is what containers say.
//! - [`ContainerNode`]: a container run over a real [`iw_bus::transport::FrameTransport`].
//! - [`ContainerError`]: this crate's errors.
//!
//! Guarantees:
//! - Losing the leader or the network never stops a container: its LAL and its agents' lookups
//!   keep working; with no peers it leads itself.
//! - With a connected set of containers whose heartbeats arrive within the lease, all elect the
//!   lowest id within one lease plus one heartbeat, and their GALs become equal within a few
//!   heartbeats after the last change; after a partition heals they converge the same way.
//! - A malformed control frame is refused with its length and reason, never a panic.
//! - A live container is bound to the address its heartbeats come from: agent lists are taken
//!   only from the elected leader's address, a container's part only from that container, and
//!   a follower mirrors its leader, so no generation (even `u64::MAX`) pins a route. A second
//!   container claiming a live id is told so ([`ContainerMsg::Duplicate`]) and refuses to run
//!   ([`Container::refusal`]); the running one is not disturbed. These rules hold beneath the
//!   control channel's group key, which keeps out whoever lacks it.
//!
//! Known limits: a dead container's agents stay in the GAL (marked by their container id; check
//! [`Container::live_peers`]) until that container comes back with a higher incarnation.
#![warn(missing_docs)]

mod lists;
mod machine;
mod node;

pub use lists::{AgentEntry, GlobalAgentList, LocalAgentList, Part, VersionVector};
pub use machine::{Container, ContainerConfig, ContainerMsg, Outgoing};
pub use node::ContainerNode;

/// A container's identity; lower ids win elections.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct ContainerId(pub u64);

impl std::fmt::Display for ContainerId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "container-{}", self.0)
    }
}

/// Errors of the container crate, with the offending input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ContainerError {
    /// A control frame that is not a container message.
    #[error("control frame of {len} bytes is not a container message: {reason}")]
    BadMessage {
        /// Frame length, bytes.
        len: usize,
        /// Decoder's complaint.
        reason: String,
    },
    /// A message that does not encode.
    #[error("container message does not encode: {reason}")]
    Encode {
        /// Encoder's complaint.
        reason: String,
    },
    /// The container thread could not start.
    #[error("cannot spawn the container thread: {source}")]
    Spawn {
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
}
