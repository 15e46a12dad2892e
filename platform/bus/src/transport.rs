//! Frame transports: move opaque byte frames between endpoints. They know nothing of ACL, layers
//! or agents; reliability, security and ordering are the layers' job, above.
//!
//! Implementations: in-process (this crate), UDP and TCP (`iw-transport-net`), iceoryx2 shared
//! memory (`iw-transport-shm`). The same agent code runs on all of them.

use std::time::Duration;

/// The address of an endpoint in a transport's own syntax (`127.0.0.1:7000`, an iceoryx2 service
/// name, an in-process node name).
#[derive(
    Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct PeerAddr(pub String);

impl std::fmt::Display for PeerAddr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Why a transport could not send or receive.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TransportError {
    /// The frame is longer than the transport carries.
    #[error("frame of {len} bytes exceeds the transport limit of {max} bytes")]
    FrameTooLarge {
        /// Offered length.
        len: usize,
        /// Limit.
        max: usize,
    },
    /// The peer address does not parse or is not known to this transport.
    #[error("unknown or malformed peer address `{addr}`: {reason}")]
    BadAddress {
        /// The address as given.
        addr: String,
        /// Why.
        reason: String,
    },
    /// A peer address that does not resolve: not `host:port`, or a host name the resolver
    /// does not know.
    #[error("unknown or malformed peer address `{addr}`: expected `host:port`: {source}")]
    Unresolved {
        /// The address as given.
        addr: String,
        /// What the resolver said.
        #[source]
        source: std::io::Error,
    },
    /// The endpoint was closed.
    #[error("transport closed")]
    Closed,
    /// An operating-system I/O error, with what was being done.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// An error of the underlying middleware (iceoryx2) or of a wrapping layer's codec, kept
    /// whole (its type is the middleware's, which this crate does not name).
    #[error("{context}: {source}")]
    Middleware {
        /// What was being done.
        context: String,
        /// What the middleware said.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// The bus's layers would not let a frame out (a verdict, not an error underneath).
    #[error("{context}: refused by the layers")]
    Refused {
        /// What was being done.
        context: String,
    },
}

/// A datagram-like endpoint: `send` one frame to a peer, `recv_timeout` the next frame from any.
///
/// Frames arrive whole or not at all; a transport may lose, duplicate or reorder them (UDP), which
/// the communication layer repairs. Implementations are thread-safe so one thread can receive
/// while others send.
pub trait FrameTransport: Send + Sync {
    /// This endpoint's own address, as peers name it.
    fn local_addr(&self) -> &PeerAddr;
    /// Largest frame this transport carries, bytes.
    fn max_frame_len(&self) -> usize;
    /// Sends one frame. Returns once the transport has taken it (not when the peer has it).
    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError>;
    /// Waits up to `timeout` for the next frame: `Ok(Some((from, frame)))`, `Ok(None)` on timeout.
    fn recv_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError>;
}
