//! Errors of the HTTP MTP.

/// What went wrong, with the offending input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Malformed HTTP request or response.
    #[error("HTTP: {reason}")]
    Http {
        /// What was wrong.
        reason: String,
    },
    /// Malformed multipart body.
    #[error("multipart body: {reason}")]
    Multipart {
        /// What was wrong.
        reason: String,
    },
    /// Malformed XML envelope.
    #[error("envelope: {reason}")]
    Envelope {
        /// What was wrong.
        reason: String,
    },
    /// Input above a size limit.
    #[error("{what} is {len} bytes, more than the {max} accepted")]
    TooLarge {
        /// Which input.
        what: &'static str,
        /// Its size.
        len: usize,
        /// The limit.
        max: usize,
    },
    /// The ACL payload did not parse or print.
    #[error("ACL payload: {source}")]
    Acl {
        /// The codec's error.
        #[from]
        source: iw_acl::Error,
    },
    /// An address this transport cannot use.
    #[error("address {address:?}: {reason}")]
    Address {
        /// The address.
        address: String,
        /// Why.
        reason: String,
    },
    /// The remote platform answered with a status other than 200.
    #[error("{url} answered HTTP {status}")]
    Rejected {
        /// Where we posted.
        url: String,
        /// Its status code.
        status: u16,
    },
    /// A receiver could not be reached.
    #[error("{agent}: {reason}")]
    Unreachable {
        /// The agent's name.
        agent: String,
        /// Why.
        reason: String,
    },
    /// TLS setup or handshake failure.
    #[error("TLS: {reason}")]
    Tls {
        /// What failed.
        reason: String,
    },
    /// A peer took longer than allowed.
    #[error("{peer} sent nothing for {seconds} s")]
    Timeout {
        /// Address of the peer.
        peer: String,
        /// The limit, in seconds.
        seconds: u64,
    },
    /// Socket failure.
    #[error("I/O with {peer}: {source}")]
    Io {
        /// Address or peer involved.
        peer: String,
        /// The I/O error.
        source: std::io::Error,
    },
}
