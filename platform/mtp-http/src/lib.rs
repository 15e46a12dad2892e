//! FIPA HTTP message transport (SC00084) with the XML envelope (SC00085), so foreign FIPA
//! platforms such as JADE can reach our agents and ours can reach theirs.
//!
//! A message travels as one HTTP/1.1 POST whose `multipart/mixed` body holds the XML envelope
//! first and the ACL string payload last; the receiving platform answers `200 OK` with an empty
//! body as soon as it has the message, and replies later with its own POST to the sender's
//! `:addresses`.
//!
//! # Organization
//! - [`envelope`]: [`Envelope`] and its XML codec (JADE's and FIPA's date forms).
//! - [`wire`]: HTTP framing and multipart parsing/encoding as pure byte functions.
//! - [`client`]: [`MtpClient`], posts one message in the form JADE accepts, keeping
//!   connections alive when the peer allows it.
//! - [`server`]: [`MtpServer`], a tokio HTTP/1.1 server handing each message to a channel.
//! - [`tls`]: rustls configurations for `https://` servers and clients.
//! - [`gateway`]: [`Gateway`], [`GatewayConfig`]: the platform side on an `iw_bus::Bus`:
//!   delivery to local agents by name, proxies posting to foreign agents' addresses, FAILURE
//!   with an MTS error from the AMS for unknown receivers, like JADE's.
//!
//! This crate moves messages and hosts no agents: a whole platform behind a gateway (AMS, DF and
//! agents) is assembled above it, in `iw-node` (`http_platform`).
//! - [`delivery_failure`]: the AMS's FAILURE with an `MTS-error` for a message the gateway could
//!   not deliver, in JADE's form.
//! - [`Error`]: every failure with the offending input.
//!
//! # Guarantees
//! - No input from a socket makes the server panic; heads above [`wire::MAX_HEAD_LEN`], bodies
//!   above [`wire::MAX_BODY_LEN`] and envelopes above [`envelope::MAX_ENVELOPE_LEN`] are refused.
//! - Replays of JADE's captured posts are accepted and answered `HTTP/1.1 200 OK` with
//!   `Content-Length: 0`; an unquoted boundary or LF-only line endings (which JADE drops or never
//!   answers) get `400 Bad Request` and a logged reason.
//! - The client writes an absolute-form request line, a quoted boundary after ` ;`, CRLF line
//!   endings, an exact `payload-length` and no `payload-encoding`.
//! - Servers bind where told; [`GatewayConfig::new`] binds [`server::LOOPBACK`]. The server
//!   holds at most [`server::ServerLimits`]' connections (in total and per source address) and
//!   closes one whose handshake or next request is not whole within its timeout (a slow trickle
//!   included); the client gives up after [`client::ANSWER_TIMEOUT`].
//! - A foreign agent cannot take a local agent's name: its messages are refused.
#![warn(missing_docs)]

pub mod client;
pub mod envelope;
mod error;
pub mod gateway;
mod mts;
pub mod server;
pub mod tls;
pub mod wire;

pub use client::MtpClient;
pub use envelope::Envelope;
pub use error::Error;
pub use gateway::{Gateway, GatewayConfig};
pub use mts::delivery_failure;
pub use server::{Delivery, MtpServer, ServerLimits};
