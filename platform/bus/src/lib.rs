//! The message bus of the IntellWheels platform (thesis 3.3.3): envelopes, the binary frame
//! codec, the layer trait and stack, routing between agent mailboxes and frame transports, and
//! the in-process transport.
//!
//! # Organization
//! - [`Envelope`], [`Header`], [`MsgId`], [`IdGen`], [`Flags`]: one message and its header.
//! - [`FrameCodec`]: the versioned binary frame (byte diagram in [`codec`]), size-limited.
//! - [`Layer`], [`Verdict`], [`Reason`], [`Counters`], [`Stack`], [`PassThrough`],
//!   [`LayerKind`], [`LayerSet`]: the layer contract; the four layers live in their own crates
//!   (`iw-layer-comm`, `iw-layer-security`, `iw-layer-temporal`, `iw-layer-parser`) and
//!   `iw-stack` assembles them from a [`LayerSet`].
//! - [`Bus`], [`BusConfig`], [`Mailbox`]: routing by agent name to local mailboxes (tokio
//!   channels) or to remote endpoints over any [`transport::FrameTransport`]; an agent thread
//!   blocked on its mailbox receives from the transport itself (see [`Mailbox`]).
//! - [`InProcNetwork`], [`InProcTransport`]: the in-process transport.
//! - [`FaultyTransport`], [`Impairments`]: a seeded fault injector for tests.
//! - [`ConnectionSlots`]: total and per-source connection caps for listeners facing outside.
//! - [`Time`], [`Clock`], [`MockController`]: nanosecond time and the clock handle;
//!   [`millis`]: serde for a `Duration` kept as whole milliseconds in files.
//!
//! # Guarantees
//! - Decoding never panics on any input: a frame is `Ok(Some)`, `Ok(None)` (need more bytes) or
//!   `Err` naming what is wrong; frames over the codec limit (64 KiB by default) are rejected
//!   before allocation.
//! - Every rejection, in any layer or in the bus, is counted under its [`Reason`].
//! - What each layer guarantees, and which EN 50159 threats it covers, is stated in its crate:
//!   communication (repetition, deletion, resequencing by retransmission), security (corruption,
//!   masquerade, insertion), temporal (delay, repetition, resequencing), parser (insertion,
//!   masquerade).
#![warn(missing_docs)]

pub mod codec;
mod envelope;
mod fault;
mod inproc;
mod layer;
pub mod millis;
mod router;
mod slots;
mod time;
pub mod transport;
mod warn;

pub use codec::{FrameCodec, write_aad};
pub use envelope::{Envelope, Flags, Header, IdGen, MsgId, SIGNATURE_LEN};
pub use fault::{FaultStats, FaultyTransport, Impairments};
pub use inproc::{InProcNetwork, InProcTransport};
pub use layer::{
    Counters, Layer, LayerKind, LayerSet, PassThrough, Reason, Stack, Verdict, WARN_PERIOD,
};
pub use router::{Bus, BusConfig, Mailbox};
pub use slots::{ConnectionSlot, ConnectionSlots};
pub use time::{Clock, MockController, Time, duration_ns};
pub use warn::WarnEvery;

/// Errors of the bus: frames that do not decode or encode, routing and transport failures.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BusError {
    /// The first two bytes are not `IW`.
    #[error("not a bus frame: magic bytes {found:02x?}, expected `IW`")]
    BadMagic {
        /// The bytes found.
        found: [u8; 2],
    },
    /// A wire version this build does not read.
    #[error("frame wire version {found} is not supported (this build reads version 1)")]
    UnsupportedVersion {
        /// The version byte.
        found: u8,
    },
    /// Flag bits this build does not define.
    #[error("frame flags {bits:#04x} contain undefined bits")]
    UnknownFlags {
        /// The flags byte.
        bits: u8,
    },
    /// The frame exceeds the codec limit.
    #[error("frame of {len} bytes exceeds the limit of {max} bytes")]
    FrameTooLarge {
        /// Frame length.
        len: usize,
        /// Limit.
        max: usize,
    },
    /// An agent name longer than 255 bytes.
    #[error("{field} name of {len} bytes is longer than 255 bytes")]
    NameTooLong {
        /// `sender` or `receiver`.
        field: &'static str,
        /// Its length.
        len: usize,
    },
    /// An agent name that is not UTF-8.
    #[error("{field} name is not UTF-8")]
    BadName {
        /// `sender` or `receiver`.
        field: &'static str,
    },
    /// A datagram holds bytes after its frame.
    #[error("{extra} bytes after the end of the frame")]
    TrailingBytes {
        /// How many.
        extra: usize,
    },
    /// A datagram ends before its frame does.
    #[error("datagram of {have} bytes ends inside the frame")]
    Truncated {
        /// Datagram length.
        have: usize,
    },
    /// A frame flagged signed (and not sealed) carries no signature.
    #[error("message {id} is flagged SIGNED but has no signature")]
    MissingSignature {
        /// The message.
        id: MsgId,
    },
    /// A layer name in a layer list is unknown.
    #[error(
        "unknown layer `{name}`: expected all, none, or a comma list of parser, temporal, security, comm"
    )]
    UnknownLayer {
        /// The name given.
        name: String,
    },
    /// No local agent and no route for the receiver.
    #[error("no local agent and no route for receiver `{receiver}`: register it or add a route")]
    NoRoute {
        /// The receiver's name.
        receiver: String,
    },
    /// The local receiver's mailbox is full (it fell [`BusConfig::mailbox_capacity`] envelopes
    /// behind) or closed (it left): the message was not delivered (counted
    /// [`Reason::MailboxFull`]).
    #[error(
        "the mailbox of `{receiver}` is full (the agent is behind) or closed (it left): the message was not delivered"
    )]
    MailboxFull {
        /// The receiver's name.
        receiver: String,
    },
    /// A local agent of that name is already registered.
    #[error("agent `{name}` is already registered on this bus")]
    AgentExists {
        /// The name.
        name: String,
    },
    /// The transport failed.
    #[error("{context}: {source}")]
    Transport {
        /// What was being done.
        context: String,
        /// The transport's error.
        #[source]
        source: transport::TransportError,
    },
    /// The pump thread could not be started.
    #[error("cannot start the bus pump thread: {source}")]
    Spawn {
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
}
