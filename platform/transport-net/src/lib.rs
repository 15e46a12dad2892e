//! UDP and TCP frame transports, and a seeded UDP impairment proxy (thesis 3.3.3: transports
//! between hosts; EN 50159 faults injected on real sockets).
//!
//! Organization:
//! - [`UdpTransport`]: one frame per datagram, std blocking sockets with a read timeout.
//! - [`TcpTransport`]: length-prefixed frames ([`frame`] draws the header) over a cache of
//!   outbound connections with reconnect; inbound connections each get a reader thread, under
//!   [`TcpLimits`] (a hello and an idle timeout, a total and a per-source cap).
//! - [`ImpairProxy`] / [`Impairer`]: a UDP relay between two loopback endpoints that drops,
//!   duplicates, reorders, corrupts, delays and injects datagrams by seeded probabilities
//!   (`intellwheels impair` runs it as a process of its own).
//! - [`NetError`]: this crate's own errors (codec, proxy configuration, I/O).
//!
//! Guarantees: no input from a socket can panic these types; a frame longer than the configured
//! limit is never delivered; every blocking call is bounded by a timeout or ended on drop.
#![warn(missing_docs)]

pub mod frame;
mod impair;
mod tcp;
mod udp;

pub use impair::{Direction, Emit, ImpairConfig, ImpairProxy, ImpairStats, Impairer};
pub use tcp::{TCP_DEFAULT_MAX_FRAME, TcpLimits, TcpTransport};
pub use udp::{UDP_MAX_PAYLOAD, UdpTransport};

/// Errors of the codec and the impairment proxy, with the offending input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NetError {
    /// A frame did not start with the magic bytes `IW`: not our protocol, or a desynchronised stream.
    #[error(
        "frame starts with {found:02x?}, expected the magic \"IW\": wrong protocol or corrupt stream"
    )]
    BadMagic {
        /// The two bytes found.
        found: [u8; 2],
    },
    /// A frame of a wire version this build does not speak.
    #[error("frame wire version {found} is not supported (this build speaks version 1)")]
    UnsupportedVersion {
        /// The version byte found.
        found: u8,
    },
    /// A frame kind byte that is neither hello (1) nor data (2).
    #[error("unknown frame kind {found} (expected 1 = hello or 2 = data)")]
    UnknownKind {
        /// The kind byte found.
        found: u8,
    },
    /// A frame longer than the configured limit.
    #[error("frame of {len} bytes exceeds the limit of {max} bytes")]
    FrameTooLong {
        /// Declared or offered length.
        len: usize,
        /// The limit.
        max: usize,
    },
    /// A connection's hello frame was missing, repeated or not an address.
    #[error("bad hello on a TCP connection: {reason}")]
    BadHello {
        /// What was wrong.
        reason: String,
    },
    /// A connection's hello frame whose address is not UTF-8.
    #[error("bad hello on a TCP connection: the address is not UTF-8: {source}")]
    HelloNotUtf8 {
        /// Where the decoding stopped.
        #[source]
        source: std::string::FromUtf8Error,
    },
    /// An impairment probability outside `0..=1`.
    #[error("impairment probability `{name}` = {value} is outside 0..=1")]
    BadProbability {
        /// Which setting.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// An impairment delay range with min above max.
    #[error(
        "delay range {}..={} ms is empty: min must not exceed max",
        min.as_millis(),
        max.as_millis()
    )]
    BadDelayRange {
        /// Shortest delay.
        min: std::time::Duration,
        /// Longest delay.
        max: std::time::Duration,
    },
    /// The proxy only relays on loopback.
    #[error("address {addr} is not loopback: the impairment proxy relays on loopback only")]
    NotLoopback {
        /// The refused address.
        addr: std::net::SocketAddr,
    },
    /// An operating-system I/O error, with what was being done.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
}
