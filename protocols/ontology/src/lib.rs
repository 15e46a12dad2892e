//! Ontologies as FIPA-SL content: FIPA-Agent-Management and the wheelchair ontology.
//!
//! Agents never build SL by hand: they fill typed values (a DF search, a `goto-xy` request, a
//! pose with its covariance) and this crate turns them into [`iw_sl::Content`] and back.
//!
//! # Organization
//! - [`Concept`]: the term form of a value; implemented by every concept below and by
//!   [`iw_acl::AgentId`] (`agent-identifier`).
//! - [`fipa`]: FIPA-Agent-Management (SC00023): descriptions, `register`/`deregister`/`modify`/
//!   `search`/`get-description`, `done`, `result`, subscriptions and the FIPA exceptions, in
//!   [`fipa::ManagementContent`].
//! - [`wheelchair`]: poses, sensor readings, driving actions, goals and doors, in
//!   [`wheelchair::WheelchairContent`].
//! - [`world`]: a chair's body and the shared world of a deployment (attach, wheel speeds, poses,
//!   sensor frames, doors), in [`world::WorldContent`].
//! - [`OntologyContent`]: puts a value into an [`iw_acl::AclMessage`] (content, language,
//!   ontology) and reads it back at the SL level the message's `:language` names.
//! - [`OntologyError`]: what in the content did not fit, and where.
//!
//! # Guarantees
//! - Re-encoding what JADE's AMS and DF answer gives JADE's text (checked on the wire captures in
//!   `shared/fipa/wire/`); what we send decodes in JADE's codec (its content is fipa-sl0).
//! - `from_content(&to_content(v)) == v` for every value (property-tested), also through SL text.
//! - Symbols and slot names are matched without regard to ASCII case, as JADE does.
#![warn(missing_docs)]

mod concept;
mod error;
pub mod fipa;
mod message;
pub mod wheelchair;
pub mod world;

pub use concept::Concept;
pub use error::OntologyError;
pub use message::OntologyContent;
