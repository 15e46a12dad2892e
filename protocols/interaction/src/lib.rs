//! FIPA interaction protocols as typed state machines, independent of any transport.
//!
//! An agent opens a conversation with an [`Initiator`] (fipa-request, fipa-query,
//! fipa-request-when, fipa-contract-net and its iterated form, fipa-subscribe, fipa-propose) and
//! answers one with a [`Responder`]. Both run the same transition table
//! ([`Protocol::after_participant_act`], [`Protocol::after_initiator_act`]) over typed
//! [`SessionState`]s, so a responder cannot send what the initiator would reject.
//!
//! # Organization
//! - [`Protocol`], [`SessionState`], [`Outcome`]: the protocols and their state machine.
//! - [`Initiator`]: one engine for all protocols (modelled on JADE's `AchieveREInitiator`):
//!   a [`Session`] per participant keyed by `reply-with`, [`Event`]s or a typed [`Handler`],
//!   contract-net decisions ([`Initiator::decide`], [`Initiator::iterate`]),
//!   [`Initiator::cancel`] for subscriptions and [`Initiator::stream`] for a request refined
//!   while it runs (a held input's drive commands).
//! - [`Responder`]: the participant's side.
//! - [`Error`]: out-of-protocol acts, late answers, foreign conversations.
//!
//! # Guarantees
//! - A message the protocol does not allow in the session's state is refused with
//!   [`Error::OutOfProtocol`] and changes nothing.
//! - Replies are matched by conversation id and `in-reply-to`; a reply from another agent than
//!   the session's participant is refused.
//! - `reply-by` bounds the first answer of each round: later ones are refused
//!   ([`Error::Late`]) and [`Initiator::tick`] turns silence into [`Outcome::TimedOut`]. Time is
//!   always an explicit `now_unix_ms` argument: the logic never reads a clock.
//!
//! # Known limits
//! - Only the first answer of a round has a deadline; a result after AGREE may come any time.
//! - In a subscription being cancelled, any INFORM counts as the cancel confirmation: the
//!   machine does not read content. A notification that crossed the CANCEL is told from the
//!   confirmation by its content (the wheelchair ontology's `Cancelled`, `((done (action W
//!   (cancel (action W act)))))`), which the agent checks.
//! - A request stream is our extension of fipa-request (SC00026 has one REQUEST): further
//!   REQUESTs in the conversation until the participant ends it. A FIPA participant that does
//!   not know it answers each as a new request.
#![warn(missing_docs)]

mod error;
mod initiator;
mod protocol;
mod responder;

pub use error::Error;
pub use initiator::{Event, EventKind, Handler, Initiator, Session};
pub use protocol::{Outcome, Protocol, SessionState};
pub use responder::Responder;
