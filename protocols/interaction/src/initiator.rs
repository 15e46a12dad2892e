//! The initiator engine: one for every protocol, with one session per participant (as JADE's
//! `AchieveREInitiator`, generalised to contract net, subscribe and propose).

use std::collections::HashMap;

use iw_acl::{AclMessage, AgentId, Performative};

use crate::protocol::{Actor, check_conversation, check_deadline, check_sender};
use crate::{Error, Protocol, SessionState};

/// One initiator-participant exchange.
#[derive(Clone, Debug)]
pub struct Session {
    participant: AgentId,
    state: SessionState,
    last_received: Option<AclMessage>,
}

impl Session {
    /// The other agent.
    pub fn participant(&self) -> &AgentId {
        &self.participant
    }

    /// Where the exchange stands.
    pub fn state(&self) -> SessionState {
        self.state
    }

    /// The participant's latest message (its proposal, its result, ...).
    pub fn last_received(&self) -> Option<&AclMessage> {
        self.last_received.as_ref()
    }
}

/// What a handled message or a deadline did to one session.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Event {
    /// The participant concerned.
    pub participant: AgentId,
    /// What happened.
    pub kind: EventKind,
    /// The session's state afterwards.
    pub state: SessionState,
}

/// What happened in a session.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum EventKind {
    /// AGREE: the result will follow.
    Agreed,
    /// REFUSE.
    Refused,
    /// NOT-UNDERSTOOD.
    NotUnderstood,
    /// INFORM carrying the result.
    Informed,
    /// INFORM carrying a subscription notification.
    Notified,
    /// FAILURE.
    Failed,
    /// PROPOSE (contract net bid).
    Proposed,
    /// ACCEPT-PROPOSAL (fipa-propose).
    Accepted,
    /// REJECT-PROPOSAL (fipa-propose).
    Rejected,
    /// INFORM confirming a CANCEL.
    Cancelled,
    /// No answer by the `reply-by` deadline.
    TimedOut,
}

/// Typed callbacks for an initiator; every method defaults to doing nothing. `()` is the no-op
/// handler.
pub trait Handler {
    /// AGREE received.
    fn on_agree(&mut self, _message: &AclMessage) {}
    /// REFUSE received.
    fn on_refuse(&mut self, _message: &AclMessage) {}
    /// NOT-UNDERSTOOD received.
    fn on_not_understood(&mut self, _message: &AclMessage) {}
    /// INFORM received: a result, a notification or a cancel confirmation.
    fn on_inform(&mut self, _message: &AclMessage) {}
    /// FAILURE received.
    fn on_failure(&mut self, _message: &AclMessage) {}
    /// PROPOSE received.
    fn on_propose(&mut self, _message: &AclMessage) {}
    /// ACCEPT-PROPOSAL received (fipa-propose).
    fn on_accept_proposal(&mut self, _message: &AclMessage) {}
    /// REJECT-PROPOSAL received (fipa-propose).
    fn on_reject_proposal(&mut self, _message: &AclMessage) {}
    /// The participant did not answer by the deadline.
    fn on_timeout(&mut self, _participant: &AgentId) {}
}

impl Handler for () {}

/// The initiating side of one conversation with one or more participants.
///
/// Start it with [`Initiator::start`], send the messages it returns, feed every reply to
/// [`Initiator::handle`] and call [`Initiator::tick`] by [`Initiator::next_deadline`]. Time is
/// always an argument (`now_unix_ms`), never read from a clock.
#[derive(Clone, Debug)]
pub struct Initiator {
    protocol: Protocol,
    conversation_id: String,
    me: Option<AgentId>,
    /// The opening message (content and parameters reused by follow-ups).
    opening: AclMessage,
    sessions: Vec<Session>,
    /// Every `reply-with` we sent, mapped to its session: replies quote it in `in-reply-to`.
    by_tag: HashMap<String, usize>,
    tag_base: String,
    tags_issued: u64,
    deadline_unix_ms: Option<i64>,
    round: u32,
}

impl Initiator {
    /// Opens a conversation: `opening` must carry `:protocol`, a performative that opens it,
    /// a `:conversation-id` and receivers; its `reply-by` (relative ones resolved at
    /// `now_unix_ms`) bounds the first answers. Returns one message per receiver, each with its
    /// own `reply-with` so replies find their session.
    pub fn start(opening: AclMessage, now_unix_ms: i64) -> Result<(Self, Vec<AclMessage>), Error> {
        let protocol = opening_protocol(&opening)?;
        if opening.receivers.is_empty() {
            return Err(Error::NoReceivers {
                performative: opening.performative,
            });
        }
        let conversation_id =
            opening
                .conversation_id
                .clone()
                .ok_or(Error::MissingConversationId {
                    performative: opening.performative,
                })?;
        let tag_base = opening
            .reply_with
            .clone()
            .unwrap_or_else(|| conversation_id.clone());
        let mut initiator = Self {
            protocol,
            conversation_id,
            me: opening.sender.clone(),
            sessions: Vec::with_capacity(opening.receivers.len()),
            by_tag: HashMap::new(),
            tag_base,
            tags_issued: 0,
            deadline_unix_ms: opening.reply_by.map(|t| t.to_unix_ms(now_unix_ms)),
            round: 1,
            opening,
        };
        let mut out = Vec::with_capacity(initiator.opening.receivers.len());
        for (index, participant) in initiator.opening.receivers.clone().into_iter().enumerate() {
            let mut message = initiator.opening.clone();
            message.receivers = vec![participant.clone()];
            message.reply_with = Some(initiator.new_tag(index));
            initiator.sessions.push(Session {
                participant,
                state: SessionState::AwaitingResponse,
                last_received: None,
            });
            out.push(message);
        }
        Ok((initiator, out))
    }

    /// The protocol run.
    pub fn protocol(&self) -> Protocol {
        self.protocol
    }

    /// The conversation id every message carries.
    pub fn conversation_id(&self) -> &str {
        &self.conversation_id
    }

    /// One session per receiver, in the opening message's order.
    pub fn sessions(&self) -> &[Session] {
        &self.sessions
    }

    /// The session with this participant (by name).
    pub fn session(&self, participant: &str) -> Option<&Session> {
        self.sessions
            .iter()
            .find(|s| s.participant.name == participant)
    }

    /// Contract-net round, from 1.
    pub fn round(&self) -> u32 {
        self.round
    }

    /// Whether every session has ended.
    pub fn is_done(&self) -> bool {
        self.sessions.iter().all(|s| s.state.is_done())
    }

    /// When [`Initiator::tick`] next has something to time out, Unix ms.
    pub fn next_deadline(&self) -> Option<i64> {
        self.deadline_unix_ms
            .filter(|_| self.waiting().next().is_some())
    }

    fn waiting(&self) -> impl Iterator<Item = &Session> {
        self.sessions
            .iter()
            .filter(|s| s.state == SessionState::AwaitingResponse)
    }

    fn new_tag(&mut self, index: usize) -> String {
        self.tags_issued += 1;
        let tag = format!("{}#{}", self.tag_base, self.tags_issued);
        self.by_tag.insert(tag.clone(), index);
        tag
    }

    /// Applies a participant's message: the protocol must allow it in the session's current
    /// state, and a first answer must arrive by the deadline. On error nothing changes.
    pub fn handle(&mut self, message: &AclMessage, now_unix_ms: i64) -> Result<Event, Error> {
        check_conversation(message, &self.conversation_id)?;
        let index = self.session_index(message)?;
        let session = &self.sessions[index];
        let participant = session.participant.name.as_str();
        check_sender(message, participant)?;
        let act = message.performative;
        let state = self
            .protocol
            .step(Actor::Participant, session.state, act, participant)?;
        check_deadline(
            session.state,
            self.deadline_unix_ms,
            act,
            participant,
            now_unix_ms,
        )?;
        let session = &mut self.sessions[index];
        session.state = state;
        session.last_received = Some(message.clone());
        Ok(Event {
            participant: session.participant.clone(),
            kind: event_kind(act, state),
            state,
        })
    }

    /// [`Initiator::handle`], then the matching [`Handler`] method.
    pub fn dispatch(
        &mut self,
        message: &AclMessage,
        now_unix_ms: i64,
        handler: &mut impl Handler,
    ) -> Result<Event, Error> {
        let event = self.handle(message, now_unix_ms)?;
        match message.performative {
            Performative::Agree => handler.on_agree(message),
            Performative::Refuse => handler.on_refuse(message),
            Performative::NotUnderstood => handler.on_not_understood(message),
            Performative::Inform => handler.on_inform(message),
            Performative::Failure => handler.on_failure(message),
            Performative::Propose => handler.on_propose(message),
            Performative::AcceptProposal => handler.on_accept_proposal(message),
            Performative::RejectProposal => handler.on_reject_proposal(message),
            // `handle` admits no other act.
            _ => {}
        }
        Ok(event)
    }

    /// Times out every session still awaiting its first answer past the deadline.
    pub fn tick(&mut self, now_unix_ms: i64) -> Vec<Event> {
        let Some(deadline) = self.deadline_unix_ms else {
            return Vec::new();
        };
        if now_unix_ms <= deadline {
            return Vec::new();
        }
        let timed_out = SessionState::Done(crate::Outcome::TimedOut);
        self.sessions
            .iter_mut()
            .filter(|s| s.state == SessionState::AwaitingResponse)
            .map(|s| {
                s.state = timed_out;
                Event {
                    participant: s.participant.clone(),
                    kind: EventKind::TimedOut,
                    state: timed_out,
                }
            })
            .collect()
    }

    /// [`Initiator::tick`], calling [`Handler::on_timeout`] for each timed-out participant.
    pub fn tick_with(&mut self, now_unix_ms: i64, handler: &mut impl Handler) -> Vec<Event> {
        let events = self.tick(now_unix_ms);
        events
            .iter()
            .for_each(|e| handler.on_timeout(&e.participant));
        events
    }

    /// Contract net: accepts the bids of `accepted` and rejects every other standing bid.
    /// Every bidder must have answered (or timed out) first.
    pub fn decide(&mut self, accepted: &[&str]) -> Result<Vec<AclMessage>, Error> {
        self.close_round(accepted, Performative::AcceptProposal, None)
    }

    /// Iterated contract net: sends `next_cfp` (its content, `reply-by` and parameters) to the
    /// bidders in `keep` for a new round and rejects every other standing bid.
    pub fn iterate(
        &mut self,
        keep: &[&str],
        next_cfp: &AclMessage,
        now_unix_ms: i64,
    ) -> Result<Vec<AclMessage>, Error> {
        let out = self.close_round(keep, Performative::Cfp, Some(next_cfp))?;
        self.round += 1;
        self.deadline_unix_ms = next_cfp.reply_by.map(|t| t.to_unix_ms(now_unix_ms));
        Ok(out)
    }

    /// Sends `chosen_act` to the chosen bidders and REJECT-PROPOSAL to the other proposers.
    fn close_round(
        &mut self,
        chosen: &[&str],
        chosen_act: Performative,
        template: Option<&AclMessage>,
    ) -> Result<Vec<AclMessage>, Error> {
        let waiting: Vec<String> = self.waiting().map(|s| s.participant.name.clone()).collect();
        if !waiting.is_empty() {
            return Err(Error::RoundOpen { waiting });
        }
        if let Some(name) = chosen.iter().find(|name| self.session(name).is_none()) {
            return Err(Error::UnknownParticipant {
                name: (*name).to_owned(),
            });
        }
        let mut plan = Vec::new();
        for (index, session) in self.sessions.iter().enumerate() {
            let act = if chosen.contains(&session.participant.name.as_str()) {
                chosen_act
            } else if session.state == SessionState::Proposed {
                Performative::RejectProposal
            } else {
                continue;
            };
            let state = self.protocol.step(
                Actor::Initiator,
                session.state,
                act,
                &session.participant.name,
            )?;
            plan.push((index, act, state));
        }
        Ok(plan
            .into_iter()
            .map(|(index, act, state)| self.follow_up(index, act, state, template))
            .collect())
    }

    /// Subscribe: ends the subscription with this participant (CANCEL carrying the
    /// subscription's content); its INFORM then confirms.
    pub fn cancel(&mut self, participant: &str) -> Result<AclMessage, Error> {
        let index = self
            .sessions
            .iter()
            .position(|s| s.participant.name == participant)
            .ok_or_else(|| Error::UnknownParticipant {
                name: participant.to_owned(),
            })?;
        let session = &self.sessions[index];
        let act = Performative::Cancel;
        let state = self
            .protocol
            .step(Actor::Initiator, session.state, act, participant)?;
        Ok(self.follow_up(index, act, state, None))
    }

    /// fipa-request as a stream (a held input's drive commands): `next`'s content and
    /// parameters as a further REQUEST to every participant that has not ended the
    /// conversation, which goes on as before. The participant answers the opening (AGREE, then
    /// INFORM or FAILURE when the stream ends), so an item asks for no reply of its own.
    pub fn stream(&self, next: &AclMessage) -> Result<Vec<AclMessage>, Error> {
        let mut out = Vec::new();
        for session in self.sessions.iter().filter(|s| !s.state.is_done()) {
            let name = &session.participant.name;
            self.protocol
                .step(Actor::Initiator, session.state, Performative::Request, name)?;
            let mut message = next.clone();
            message.performative = Performative::Request;
            message.sender = self.me.clone();
            message.receivers = vec![session.participant.clone()];
            message.protocol = Some(self.protocol.fipa_name().to_owned());
            message.conversation_id = Some(self.conversation_id.clone());
            message.reply_with = None;
            message.in_reply_to = None;
            out.push(message);
        }
        Ok(out)
    }

    /// Builds an initiator follow-up (answering the participant's last message when there is
    /// one), registers its `reply-with`, and moves the session to `state`.
    fn follow_up(
        &mut self,
        index: usize,
        act: Performative,
        state: SessionState,
        template: Option<&AclMessage>,
    ) -> AclMessage {
        let session = &self.sessions[index];
        let mut message = template
            .cloned()
            .unwrap_or_else(|| match &session.last_received {
                Some(last) => last.create_reply(),
                None => {
                    let mut fresh = self.opening.clone();
                    fresh.reply_by = None;
                    fresh
                }
            });
        message.performative = act;
        message.sender = self.me.clone();
        message.receivers = vec![session.participant.clone()];
        message.protocol = Some(self.protocol.fipa_name().to_owned());
        message.conversation_id = Some(self.conversation_id.clone());
        if act == Performative::Cancel {
            message.content = self.opening.content.clone();
        }
        if let Some(last) = &session.last_received {
            message.in_reply_to = last.reply_with.clone();
        }
        if act == Performative::Cfp {
            // A new round: answers to the previous round's messages no longer route.
            self.by_tag.retain(|_, session| *session != index);
        }
        message.reply_with = Some(self.new_tag(index));
        self.sessions[index].state = state;
        message
    }

    /// The session a reply belongs to: by `in-reply-to`, else by sender when unambiguous.
    fn session_index(&self, message: &AclMessage) -> Result<usize, Error> {
        let unknown = || Error::UnknownReply {
            in_reply_to: message.in_reply_to.clone(),
            sender: message.sender.as_ref().map(|s| s.name.clone()),
        };
        if let Some(tag) = &message.in_reply_to {
            return self.by_tag.get(tag).copied().ok_or_else(unknown);
        }
        let sender = message.sender.as_ref().ok_or_else(unknown)?;
        let mut matching = self
            .sessions
            .iter()
            .enumerate()
            .filter(|(_, s)| s.participant.name == sender.name);
        match (matching.next(), matching.next()) {
            (Some((index, _)), None) => Ok(index),
            _ => Err(unknown()),
        }
    }
}

/// The protocol named by `opening`, checked against its performative.
pub(crate) fn opening_protocol(opening: &AclMessage) -> Result<Protocol, Error> {
    let name = opening.protocol.as_deref().ok_or(Error::MissingProtocol {
        performative: opening.performative,
    })?;
    let protocol: Protocol = name.parse()?;
    if !protocol.is_initiating(opening.performative) {
        return Err(Error::NotInitiating {
            protocol,
            performative: opening.performative,
        });
    }
    Ok(protocol)
}

fn event_kind(act: Performative, state: SessionState) -> EventKind {
    use crate::Outcome;
    match (act, state) {
        (Performative::Agree, _) => EventKind::Agreed,
        (Performative::Refuse, _) => EventKind::Refused,
        (Performative::NotUnderstood, _) => EventKind::NotUnderstood,
        (Performative::Failure, _) => EventKind::Failed,
        (Performative::Propose, _) => EventKind::Proposed,
        (Performative::AcceptProposal, _) => EventKind::Accepted,
        (Performative::RejectProposal, _) => EventKind::Rejected,
        (_, SessionState::Subscribed) => EventKind::Notified,
        (_, SessionState::Done(Outcome::Cancelled)) => EventKind::Cancelled,
        _ => EventKind::Informed,
    }
}
