//! FIPA-ACL messages (SC00061) and their string representation (SC00070).
//!
//! Agents talk by exchanging [`AclMessage`]s: a [`Performative`] (the speech act) plus optional
//! parameters (sender, receivers, content, conversation id, ...). This crate is the model and
//! its wire text; it knows nothing of transports or content languages (see `iw-sl`).
//!
//! # Organization
//! - [`Performative`]: the 22 FIPA communicative acts.
//! - [`AgentId`]: agent identifiers with addresses, resolvers and user slots.
//! - [`AclMessage`], [`Content`]: the message; [`AclMessage::create_reply`] answers one.
//! - [`FipaDateTime`]: `reply-by` and other FIPA date-times.
//! - [`codec`]: [`codec::parse`] and [`codec::print`], with a JADE-compatible [`codec::Escaping`];
//!   [`codec::check_with`] gives `parse`'s verdict and errors with only an [`codec::AclSummary`]
//!   of the names, without building (or allocating for) the message.
//! - [`Error`]: every failure, with line, column and the offending input where there is one.
//!
//! # Guarantees
//! - No input makes the parser panic; input above [`codec::DEFAULT_MAX_LEN`] bytes (unless
//!   configured) and identifiers nested deeper than [`codec::DEFAULT_MAX_DEPTH`] are refused.
//! - `parse(&print(&m)) == m` for every message `m` (standard escaping); with JADE escaping the
//!   printer refuses, rather than corrupts, the strings JADE cannot carry (those ending in a backslash).
//! - [`codec::check_with`] is `Ok` exactly when [`codec::parse_with`] is, with the same [`Error`]
//!   otherwise (one parser builds both; property-tested and fuzzed against each other).
//! - Agrees with JADE 4.6.5 on the FIPA test vectors kept beside the project (`shared/fipa`).
//! - serde: [`AclMessage`] serializes to the JSON shape of those vectors.
#![warn(missing_docs)]

mod agent_id;
pub mod codec;
mod datetime;
mod error;
mod message;
mod performative;

pub use agent_id::AgentId;
pub use datetime::FipaDateTime;
pub use error::{Error, ValueError};
pub use message::{AclMessage, Content};
pub use performative::Performative;
