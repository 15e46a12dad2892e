//! The FIPA platform services of thesis 3.3.3: the Agent Management System (white pages) and the
//! Directory Facilitator (yellow pages), as agents that speak FIPA-ACL with FIPA-SL content in
//! the FIPA-Agent-Management ontology (SC00023), answering the way JADE's `ams` and `df` do in
//! the wire captures (`shared/fipa/wire/`).
//!
//! # Organization
//! - [`Ams`], [`WhitePages`]: the AMS agent and the agent list it serves (register, deregister,
//!   modify, search of ams-agent-descriptions with their life-cycle state); the container lists
//!   the agents it hosts through [`WhitePages::host`].
//! - [`Df`], [`matches()`]: the DF agent (register, deregister, modify, search with
//!   `:max-results`, fipa-subscribe with notifications, cancel) and its template matching.
//! - [`MAX_RESULTS`]: the most descriptions one search returns.
//!
//! # Guarantees
//! - Answers as JADE's: no AGREE; INFORM `((done (action ...)))` or `((result (action ...)
//!   (sequence ...)))` in fipa-sl0; FAILURE `already-registered` / `not-registered`; REFUSE
//!   `unauthorised` when an agent acts on another's entry, `(missing-parameter ...)` for a
//!   description without a name, `(unsupported-function ...)`; NOT-UNDERSTOOD with
//!   `(unsupported-act ...)` or `(unrecognised-value ...)` for other performatives, ontologies,
//!   languages or content. Answers (INFORM, FAILURE, ...) are never answered, so services cannot
//!   loop with each other.
//! - No input makes a service panic; a search returns at most [`MAX_RESULTS`] descriptions and
//!   the DF holds at most [`df::MAX_SUBSCRIPTIONS`] subscriptions.
#![warn(missing_docs)]

mod ams;
pub mod df;
mod service;

pub use ams::{Ams, WhitePages};
pub use df::{Df, matches};
pub use service::MAX_RESULTS;
