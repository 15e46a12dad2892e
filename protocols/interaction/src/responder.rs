//! The responder engine: the participant's side of one conversation, on the same state table
//! as the initiator, so it can only send what the initiator will accept.

use iw_acl::{AclMessage, AgentId, Performative};

use crate::initiator::opening_protocol;
use crate::protocol::{Actor, check_conversation, check_deadline, check_sender};
use crate::{Error, Protocol, SessionState};

/// The participant's side of one conversation.
///
/// Create it from the opening message with [`Responder::accept`], answer with
/// [`Responder::reply`] and feed the initiator's follow-ups (ACCEPT/REJECT-PROPOSAL, a new CFP,
/// CANCEL) to [`Responder::handle`].
#[derive(Clone, Debug)]
pub struct Responder {
    protocol: Protocol,
    state: SessionState,
    me: AgentId,
    initiator: Option<AgentId>,
    conversation_id: String,
    /// The initiator's latest message; replies answer it.
    latest: AclMessage,
    deadline_unix_ms: Option<i64>,
}

impl Responder {
    /// Takes up a conversation opened by `opening` (which must name its protocol, open it
    /// properly and carry a conversation id), answering as `me`.
    pub fn accept(opening: &AclMessage, me: AgentId, now_unix_ms: i64) -> Result<Self, Error> {
        let protocol = opening_protocol(opening)?;
        let conversation_id =
            opening
                .conversation_id
                .clone()
                .ok_or(Error::MissingConversationId {
                    performative: opening.performative,
                })?;
        Ok(Self {
            protocol,
            state: SessionState::AwaitingResponse,
            me,
            initiator: opening.sender.clone(),
            conversation_id,
            latest: opening.clone(),
            deadline_unix_ms: opening.reply_by.map(|t| t.to_unix_ms(now_unix_ms)),
        })
    }

    /// The protocol run.
    pub fn protocol(&self) -> Protocol {
        self.protocol
    }

    /// Where the exchange stands.
    pub fn state(&self) -> SessionState {
        self.state
    }

    /// The conversation answered.
    pub fn conversation_id(&self) -> &str {
        &self.conversation_id
    }

    /// The agent that opened the conversation, when the opening named it.
    pub fn initiator(&self) -> Option<&AgentId> {
        self.initiator.as_ref()
    }

    /// The initiator's latest message (the request, the CFP, the accepted proposal, ...).
    pub fn latest(&self) -> &AclMessage {
        &self.latest
    }

    /// Answers the initiator's latest message with `act` if the protocol allows it now and,
    /// for a first answer, the `reply-by` deadline has not passed. The caller adds content.
    pub fn reply(&mut self, act: Performative, now_unix_ms: i64) -> Result<AclMessage, Error> {
        let initiator = self.initiator_name();
        let state = self
            .protocol
            .step(Actor::Participant, self.state, act, &initiator)?;
        check_deadline(
            self.state,
            self.deadline_unix_ms,
            act,
            &initiator,
            now_unix_ms,
        )?;
        self.state = state;
        let mut reply = self.latest.create_reply();
        reply.performative = act;
        reply.sender = Some(self.me.clone());
        reply.protocol = Some(self.protocol.fipa_name().to_owned());
        reply.conversation_id = Some(self.conversation_id.clone());
        Ok(reply)
    }

    /// Applies an initiator follow-up; returns the new state. A further REQUEST of a request
    /// stream ([`crate::Initiator::stream`]) is checked like any follow-up (same conversation,
    /// same initiator, the stream not ended), but the replies still answer the opening.
    pub fn handle(
        &mut self,
        message: &AclMessage,
        now_unix_ms: i64,
    ) -> Result<SessionState, Error> {
        check_conversation(message, &self.conversation_id)?;
        let initiator = self.initiator_name();
        if self.initiator.is_some() {
            check_sender(message, &initiator)?;
        }
        let act = message.performative;
        let state = self
            .protocol
            .step(Actor::Initiator, self.state, act, &initiator)?;
        if act == Performative::Cfp {
            self.deadline_unix_ms = message.reply_by.map(|t| t.to_unix_ms(now_unix_ms));
        }
        self.state = state;
        if act != Performative::Request {
            self.latest = message.clone();
        }
        Ok(state)
    }

    fn initiator_name(&self) -> String {
        self.initiator
            .as_ref()
            .map_or_else(String::new, |a| a.name.clone())
    }
}
