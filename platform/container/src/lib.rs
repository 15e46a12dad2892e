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
//! - [`ControlChannel`]: a container's end of the control channel, per-peer Noise sessions
//!   bound to each container's Ed25519 identity; [`Authenticated`]: a control message as it
//!   comes out of one.
//! - [`Roster`], [`Pin`]: a deployment's container identities pinned in advance (id, name,
//!   Ed25519 key), read from a file ([`ContainerConfig::roster`]).
//! - [`ContainerError`]: this crate's errors.
//!
//! Guarantees:
//! - Losing the leader or the network never stops a container: its LAL and its agents' lookups
//!   keep working; with no peers it leads itself.
//! - With a connected set of containers whose heartbeats arrive within the lease, all elect the
//!   lowest id within one lease plus one heartbeat, and their GALs become equal within a few
//!   heartbeats after the last change; after a partition heals they converge the same way.
//! - Cost grows with the containers one hears, not with their square: a container heartbeats to
//!   its seeds and to whoever heartbeats to it (chairs greet the services, so the leader hears
//!   N and a chair one), every `heartbeat` while the lists differ and every fifth of the
//!   lease once they agree. A list travels as the parts the follower lacks, at most 32 KiB a
//!   frame, so no GAL is too big for a datagram.
//! - A malformed control frame is refused with its length and reason, never a panic.
//! - Every control frame travels in a Noise session between the two containers
//!   ([`ControlChannel`]), agreed once per peer with the data plane's handshake, each static key
//!   bound to the container's Ed25519 identity; a frame outside a session, altered, or
//!   replayed within it is refused and counted. A live container is bound to the identity its
//!   heartbeats' session was agreed with and the address they come from: agent lists are taken only under the elected
//!   leader's key and address, a container's part only under that container's, each with a
//!   sequence number above the last (no replay), and a follower mirrors its leader: it keeps a
//!   part only at the generation the leader's last list names, sent by that leader or held from
//!   an earlier list of the same leader, so no generation (even `u64::MAX`) pins a route. A
//!   holder of the group key therefore cannot speak for another live container, even from its
//!   address. A second container claiming a live id is told so ([`ContainerMsg::Duplicate`])
//!   and refuses to run ([`Container::refusal`]); the running one (the one that has run longer)
//!   is not disturbed. These rules hold beneath the control channel's group key, which decides
//!   who may join at all.
//! - A list entry carries its container's identity key (an agent's messages are verified with
//!   it): a container's part whose entries carry another key is refused, at the leader (a LAL)
//!   and at a follower (a part of the leader's GAL, against the key that container's live id is
//!   bound to here, or one key for the whole part when it is not known).
//! - With a [`Roster`] ([`ContainerConfig::roster`]), no id is bound to whoever claims it first:
//!   a frame speaks for id X only under X's pinned key, so an id the roster does not list is
//!   nobody's (a group-key holder cannot claim a free id, nor a low one to lead) and a listed id
//!   cannot be claimed under another key, even while its container is down; a container's part
//!   carries only agents named `ROLE@NAME` for its pinned name, under its pinned key; a
//!   `Duplicate` is believed only under the receiver's own pinned key (a third party's report
//!   makes it greet the named holder, which answers itself if it holds that identity); and a
//!   container whose own key is not the one pinned for its id does not start
//!   ([`ContainerNode::start`]). Refusals are counted per reason ([`Container::counters`]:
//!   `unknown_peer`, `mismatch`) and warned at most once per 10 s per kind.
//!
//! Known limits: without a roster (the weaker mode) an id is bound to a key first come, first
//! served while its lease holds, so a group-key holder can claim an id nobody holds, including a
//! low one that leads, list agent names of her choosing under her own key, and make a
//! container refuse to run with a forged [`ContainerMsg::Duplicate`]. With a roster, a holder
//! of a container's own identity key is that container: she can do all it may (list its own
//! agents, stop a second holder of its key), nothing more. A dead container's agents stay in the GAL (marked
//! by their container id; check [`Container::live_peers`]) until that container comes back with
//! a higher incarnation.
#![warn(missing_docs)]

mod lists;
mod machine;
mod node;
mod roster;
mod vetting;
mod wire;

pub use lists::{AgentEntry, GlobalAgentList, LocalAgentList, Part, VersionVector};
pub use machine::{Container, ContainerConfig, ContainerMsg, Outgoing};
pub use node::ContainerNode;
pub use roster::{MAX_ROSTER_BYTES, Pin, Roster};
pub use wire::{Authenticated, ControlChannel};

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
    /// A control frame whose body is not a container message.
    #[error("control frame of {len} bytes is not a container message: {source}")]
    BadMessage {
        /// Frame length, bytes.
        len: usize,
        /// The JSON decoder's error (with line and column).
        #[source]
        source: serde_json::Error,
    },
    /// A control frame too short to hold its sequence number.
    #[error(
        "control frame of {len} bytes is shorter than its {}-byte sequence number",
        wire::SEQ_LEN
    )]
    ShortFrame {
        /// Frame length, bytes.
        len: usize,
    },
    /// A control datagram refused by the sessions (not a session's, altered, replayed, a
    /// handshake that does not verify).
    #[error("control datagram of {len} bytes refused: {reason}")]
    Refused {
        /// Datagram length, bytes.
        len: usize,
        /// Why.
        reason: iw_bus::Reason,
    },
    /// The control sessions failed (the system random generator, a key setup).
    #[error("control sessions: {source}")]
    Sessions {
        /// The security layer's error.
        #[source]
        source: iw_layer_security::SecurityError,
    },
    /// A message that does not encode.
    #[error("container message does not encode: {source}")]
    Encode {
        /// The JSON encoder's error.
        #[source]
        source: serde_json::Error,
    },
    /// A roster file that cannot be read or is wrong, or that pins another identity for this
    /// container.
    #[error("roster {file}{}: {reason}", line.map(|n| format!(" line {n}")).unwrap_or_default())]
    Roster {
        /// The file (or what the roster was built from).
        file: String,
        /// The line at fault (1-based), when one is.
        line: Option<usize>,
        /// Why.
        reason: String,
    },
    /// A roster line with a value that does not parse (a container id, a key).
    #[error("roster {file} line {line}: {what}: {source}")]
    RosterValue {
        /// The file (or what the roster was built from).
        file: String,
        /// The line at fault (1-based).
        line: usize,
        /// Which value.
        what: String,
        /// The value parser's error (`ParseIntError`, `hex::FromHexError`).
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A roster file that cannot be opened or read.
    #[error("roster {file}: {source}")]
    RosterRead {
        /// The file.
        file: String,
        /// Why it could not be read.
        #[source]
        source: std::io::Error,
    },
    /// The container thread could not start.
    #[error("cannot spawn the container thread: {source}")]
    Spawn {
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
}
