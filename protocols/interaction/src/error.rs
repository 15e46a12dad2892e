//! The crate's one error type.

use iw_acl::Performative;
use thiserror::Error;

use crate::{Protocol, SessionState};

/// A message or action the protocol does not allow, or a conversation that cannot start.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum Error {
    /// `:protocol` names no protocol this crate runs.
    #[error(
        "unknown interaction protocol `{name}` (expected fipa-request, fipa-query, fipa-request-when, fipa-contract-net, fipa-iterated-contract-net, fipa-subscribe or fipa-propose)"
    )]
    UnknownProtocol {
        /// The name given.
        name: String,
    },
    /// An opening message without `:protocol`.
    #[error("{performative} message has no `:protocol`; set the interaction protocol it opens")]
    MissingProtocol {
        /// Its performative.
        performative: Performative,
    },
    /// The performative cannot open this protocol.
    #[error("{performative} cannot open a {protocol} conversation")]
    NotInitiating {
        /// The protocol.
        protocol: Protocol,
        /// The offending performative.
        performative: Performative,
    },
    /// Replies are matched by conversation id, so the opening message needs one.
    #[error("{performative} message has no `:conversation-id`; protocols match replies by it")]
    MissingConversationId {
        /// Its performative.
        performative: Performative,
    },
    /// An opening message addressed to nobody.
    #[error("{performative} message has no `:receiver`")]
    NoReceivers {
        /// Its performative.
        performative: Performative,
    },
    /// A message from another conversation.
    #[error("message for conversation {found:?}, this is conversation `{expected}`")]
    WrongConversation {
        /// This conversation's id.
        expected: String,
        /// The message's id.
        found: Option<String>,
    },
    /// No session matches the message's `in-reply-to` (nor, lacking it, its sender).
    #[error("no exchange in this conversation matches in-reply-to {in_reply_to:?} from {sender:?}")]
    UnknownReply {
        /// The message's `in-reply-to`.
        in_reply_to: Option<String>,
        /// The message's sender name.
        sender: Option<String>,
    },
    /// The reply comes from another agent than the one the exchange is with.
    #[error("reply from `{found}` in the exchange with `{expected}`")]
    WrongSender {
        /// The exchange's participant.
        expected: String,
        /// The message's sender.
        found: String,
    },
    /// The act is not allowed in this state of the protocol.
    #[error("{act} is not allowed in {protocol} state {state:?} (exchange with `{participant}`)")]
    OutOfProtocol {
        /// The protocol.
        protocol: Protocol,
        /// The exchange's state.
        state: SessionState,
        /// The offending act.
        act: Performative,
        /// The other agent of the exchange.
        participant: String,
    },
    /// An answer after the `reply-by` deadline.
    #[error(
        "{act} from/to `{participant}` at {now_unix_ms} ms is after the reply-by deadline {deadline_unix_ms} ms"
    )]
    Late {
        /// The late act.
        act: Performative,
        /// The other agent of the exchange.
        participant: String,
        /// The deadline, Unix ms.
        deadline_unix_ms: i64,
        /// The time the act was handled, Unix ms.
        now_unix_ms: i64,
    },
    /// A contract-net decision while some bidders may still answer.
    #[error(
        "still awaiting responses from {waiting:?}; decide after they answer or after tick() passes the deadline"
    )]
    RoundOpen {
        /// Participants not yet answered.
        waiting: Vec<String>,
    },
    /// An action names an agent that is not a participant of this conversation.
    #[error("`{name}` is not a participant of this conversation")]
    UnknownParticipant {
        /// The name given.
        name: String,
    },
}
