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
    /// A receiver could not be reached, for a reason of this platform's (a limit, no
    /// transport address, a name taken by a local agent).
    #[error("{agent}: {reason}")]
    Unreachable {
        /// The agent's name.
        agent: String,
        /// Why.
        reason: String,
    },
    /// An agent, or the platform itself, could not be put on the bus: registering a foreign
    /// agent's proxy, starting the platform's bus, hosting a local agent. The bus's (or the
    /// host's) error is kept whole; its type is not always this crate's to name.
    #[error("{agent}: {what}: {source}")]
    Attach {
        /// The agent's name (the platform's, for the bus itself).
        agent: String,
        /// What was being done, e.g. `registering on the bus`.
        what: &'static str,
        /// What the bus or the host said.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// A TLS configuration was refused.
    #[error("TLS: {what}: {source}")]
    Tls {
        /// What was being set up, e.g. `trusted root`.
        what: &'static str,
        /// What rustls said.
        #[source]
        source: tokio_rustls::rustls::Error,
    },
    /// A TLS handshake failed.
    #[error("TLS: handshake with {peer}: {source}")]
    Handshake {
        /// Address of the peer.
        peer: String,
        /// What the TLS stream said.
        #[source]
        source: std::io::Error,
    },
    /// A host name that cannot be a TLS server name.
    #[error("address {address:?}: not a TLS server name: {source}")]
    ServerName {
        /// The address.
        address: String,
        /// Why not.
        #[source]
        source: tokio_rustls::rustls::pki_types::InvalidDnsNameError,
    },
    /// Text that must be UTF-8 is not (a request head, an envelope, an ACL payload).
    #[error("{what} is not UTF-8: {source}")]
    Utf8 {
        /// Which text.
        what: &'static str,
        /// Where the decoding stopped.
        #[source]
        source: std::str::Utf8Error,
    },
    /// An envelope date in neither the FIPA nor the JADE form.
    #[error("envelope: date {raw:?} is neither FIPA nor JADE form: {source}")]
    Date {
        /// The date as received.
        raw: String,
        /// What the FIPA date parser said.
        #[source]
        source: iw_acl::Error,
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
