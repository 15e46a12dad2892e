//! The protocols and their state machine: which act may follow which, from either side.

use std::fmt;
use std::str::FromStr;

use iw_acl::{AclMessage, Performative};

use crate::Error;

/// A FIPA interaction protocol, named on the wire by `:protocol`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Protocol {
    /// `fipa-request` (SC00026): REQUEST, then AGREE/REFUSE, then INFORM/FAILURE.
    Request,
    /// `fipa-query` (SC00027): QUERY-IF or QUERY-REF, answered as a request.
    Query,
    /// `fipa-request-when` (SC00028): REQUEST-WHEN; the result comes when the condition holds.
    RequestWhen,
    /// `fipa-contract-net` (SC00029): CFP, PROPOSE/REFUSE, ACCEPT/REJECT-PROPOSAL, result.
    ContractNet,
    /// `fipa-iterated-contract-net` (SC00030): contract net with further CFP rounds.
    IteratedContractNet,
    /// `fipa-subscribe` (SC00035): SUBSCRIBE, AGREE, INFORM notifications until CANCEL.
    Subscribe,
    /// `fipa-propose` (SC00036): PROPOSE, then ACCEPT-PROPOSAL or REJECT-PROPOSAL.
    Propose,
}

impl Protocol {
    /// Every protocol.
    pub const ALL: [Protocol; 7] = [
        Self::Request,
        Self::Query,
        Self::RequestWhen,
        Self::ContractNet,
        Self::IteratedContractNet,
        Self::Subscribe,
        Self::Propose,
    ];

    /// The `:protocol` value.
    pub const fn fipa_name(self) -> &'static str {
        match self {
            Self::Request => "fipa-request",
            Self::Query => "fipa-query",
            Self::RequestWhen => "fipa-request-when",
            Self::ContractNet => "fipa-contract-net",
            Self::IteratedContractNet => "fipa-iterated-contract-net",
            Self::Subscribe => "fipa-subscribe",
            Self::Propose => "fipa-propose",
        }
    }

    /// Whether `performative` may open a conversation of this protocol.
    pub fn is_initiating(self, performative: Performative) -> bool {
        use Performative as P;
        match self {
            Self::Request => performative == P::Request,
            Self::Query => matches!(performative, P::QueryIf | P::QueryRef),
            Self::RequestWhen => performative == P::RequestWhen,
            Self::ContractNet | Self::IteratedContractNet => performative == P::Cfp,
            Self::Subscribe => performative == P::Subscribe,
            Self::Propose => performative == P::Propose,
        }
    }

    fn is_request_like(self) -> bool {
        matches!(self, Self::Request | Self::Query | Self::RequestWhen)
    }

    fn is_contract_net(self) -> bool {
        matches!(self, Self::ContractNet | Self::IteratedContractNet)
    }

    /// The state after the participant (responder) sends `act` in `state`; `None` when the
    /// protocol does not allow it. Both sides run this same table.
    pub fn after_participant_act(
        self,
        state: SessionState,
        act: Performative,
    ) -> Option<SessionState> {
        use Performative as P;
        use SessionState as S;
        let done = |outcome| Some(S::Done(outcome));
        match (state, act) {
            (S::AwaitingResponse, P::NotUnderstood) => done(Outcome::NotUnderstood),
            (S::AwaitingResponse, P::Refuse) if self != Self::Propose => done(Outcome::Refused),
            (S::AwaitingResponse, P::Agree) if self.is_request_like() => Some(S::AwaitingResult),
            (S::AwaitingResponse, P::Agree) if self == Self::Subscribe => Some(S::Subscribed),
            // An INFORM or FAILURE without a prior AGREE is allowed (the agreement is implied).
            (S::AwaitingResponse | S::AwaitingResult, P::Inform) if self.is_request_like() => {
                done(Outcome::Informed)
            }
            (S::AwaitingResponse | S::AwaitingResult, P::Failure) if self.is_request_like() => {
                done(Outcome::Failed)
            }
            (S::AwaitingResponse | S::Subscribed, P::Inform) if self == Self::Subscribe => {
                Some(S::Subscribed)
            }
            (S::AwaitingResponse | S::Subscribed | S::Cancelling, P::Failure)
                if self == Self::Subscribe =>
            {
                done(Outcome::Failed)
            }
            (S::Cancelling, P::Inform) => done(Outcome::Cancelled),
            (S::AwaitingResponse, P::Propose) if self.is_contract_net() => Some(S::Proposed),
            (S::AwaitingResponse, P::AcceptProposal) if self == Self::Propose => {
                done(Outcome::Accepted)
            }
            (S::AwaitingResponse, P::RejectProposal) if self == Self::Propose => {
                done(Outcome::Rejected)
            }
            (S::AwaitingResult, P::Inform) if self.is_contract_net() => done(Outcome::Informed),
            (S::AwaitingResult, P::Failure) if self.is_contract_net() => done(Outcome::Failed),
            _ => None,
        }
    }

    /// The state after the initiator sends a follow-up `act` (not the opening one) in `state`.
    pub fn after_initiator_act(
        self,
        state: SessionState,
        act: Performative,
    ) -> Option<SessionState> {
        use Performative as P;
        use SessionState as S;
        match (state, act) {
            (S::Proposed, P::AcceptProposal) if self.is_contract_net() => Some(S::AwaitingResult),
            (S::Proposed, P::RejectProposal) if self.is_contract_net() => {
                Some(S::Done(Outcome::Rejected))
            }
            (S::Proposed, P::Cfp) if self == Self::IteratedContractNet => Some(S::AwaitingResponse),
            (S::AwaitingResponse | S::Subscribed, P::Cancel) if self == Self::Subscribe => {
                Some(S::Cancelling)
            }
            // A request stream (a held input's drive commands): until the participant ends it,
            // the initiator refines its request with further REQUESTs; the state is unchanged.
            (S::AwaitingResponse | S::AwaitingResult, P::Request) if self == Self::Request => {
                Some(state)
            }
            _ => None,
        }
    }
}

/// Which side performs an act.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Actor {
    Initiator,
    Participant,
}

impl Protocol {
    /// The next state, or why `act` is not allowed; `participant` names the other agent.
    pub(crate) fn step(
        self,
        actor: Actor,
        state: SessionState,
        act: Performative,
        participant: &str,
    ) -> Result<SessionState, Error> {
        let next = match actor {
            Actor::Initiator => self.after_initiator_act(state, act),
            Actor::Participant => self.after_participant_act(state, act),
        };
        next.ok_or_else(|| Error::OutOfProtocol {
            protocol: self,
            state,
            act,
            participant: participant.to_owned(),
        })
    }
}

/// A first answer (state [`SessionState::AwaitingResponse`]) must come by the deadline.
pub(crate) fn check_deadline(
    state: SessionState,
    deadline_unix_ms: Option<i64>,
    act: Performative,
    participant: &str,
    now_unix_ms: i64,
) -> Result<(), Error> {
    match deadline_unix_ms {
        Some(deadline_unix_ms)
            if state == SessionState::AwaitingResponse && now_unix_ms > deadline_unix_ms =>
        {
            Err(Error::Late {
                act,
                participant: participant.to_owned(),
                deadline_unix_ms,
                now_unix_ms,
            })
        }
        _ => Ok(()),
    }
}

/// The message belongs to conversation `expected`.
pub(crate) fn check_conversation(message: &AclMessage, expected: &str) -> Result<(), Error> {
    if message.conversation_id.as_deref() == Some(expected) {
        Ok(())
    } else {
        Err(Error::WrongConversation {
            expected: expected.to_owned(),
            found: message.conversation_id.clone(),
        })
    }
}

/// The message, if it names a sender, comes from `expected`.
pub(crate) fn check_sender(message: &AclMessage, expected: &str) -> Result<(), Error> {
    match &message.sender {
        Some(sender) if sender.name != expected => Err(Error::WrongSender {
            expected: expected.to_owned(),
            found: sender.name.clone(),
        }),
        _ => Ok(()),
    }
}

impl fmt::Display for Protocol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.fipa_name())
    }
}

impl FromStr for Protocol {
    type Err = Error;

    /// Case-insensitive, as agents spell these freely (`FIPA-Request`).
    fn from_str(name: &str) -> Result<Self, Error> {
        Self::ALL
            .into_iter()
            .find(|p| p.fipa_name().eq_ignore_ascii_case(name))
            .ok_or_else(|| Error::UnknownProtocol {
                name: name.to_owned(),
            })
    }
}

/// Where one initiator-participant exchange stands. Both sides hold the same state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SessionState {
    /// The opening act (or a new CFP round) was sent; the first answer is due by the deadline.
    AwaitingResponse,
    /// The participant agreed (or its proposal was accepted); the result is due.
    AwaitingResult,
    /// A subscription is active: INFORM notifications flow until CANCEL.
    Subscribed,
    /// The participant proposed; the initiator has to accept, reject or call a new round.
    Proposed,
    /// The initiator sent CANCEL; the participant confirms with INFORM or answers FAILURE.
    Cancelling,
    /// Finished.
    Done(Outcome),
}

impl SessionState {
    /// Whether the exchange has ended.
    pub fn is_done(self) -> bool {
        matches!(self, Self::Done(_))
    }
}

/// How an exchange ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Outcome {
    /// The result came as INFORM.
    Informed,
    /// The participant refused.
    Refused,
    /// The participant did not understand the opening act.
    NotUnderstood,
    /// The participant agreed but failed, or the subscription failed.
    Failed,
    /// No answer by the `reply-by` deadline.
    TimedOut,
    /// A subscription cancelled and confirmed.
    Cancelled,
    /// fipa-propose: the proposal was accepted.
    Accepted,
    /// fipa-propose: the proposal was rejected; contract net: the initiator rejected the bid.
    Rejected,
}

#[cfg(test)]
mod tests {
    use super::*;
    use Performative as P;

    #[test]
    fn names_round_trip() {
        for p in Protocol::ALL {
            assert_eq!(p.fipa_name().to_uppercase().parse::<Protocol>().unwrap(), p);
        }
        assert!("fipa-dance".parse::<Protocol>().is_err());
    }

    #[test]
    fn request_table() {
        let r = Protocol::Request;
        assert_eq!(
            r.after_participant_act(SessionState::AwaitingResponse, P::Agree),
            Some(SessionState::AwaitingResult)
        );
        assert_eq!(
            r.after_participant_act(SessionState::AwaitingResult, P::Agree),
            None
        );
        assert_eq!(
            r.after_participant_act(SessionState::AwaitingResult, P::Refuse),
            None
        );
        assert_eq!(
            r.after_participant_act(SessionState::AwaitingResponse, P::Propose),
            None
        );
        assert_eq!(
            r.after_initiator_act(SessionState::AwaitingResult, P::Cancel),
            None
        );
        for state in [
            SessionState::Done(Outcome::Informed),
            SessionState::Done(Outcome::TimedOut),
        ] {
            assert!(
                Performative::ALL
                    .iter()
                    .all(|&p| r.after_participant_act(state, p).is_none())
            );
        }
    }

    #[test]
    fn a_request_is_streamed_only_until_the_participant_ends_it() {
        let r = Protocol::Request;
        for state in [SessionState::AwaitingResponse, SessionState::AwaitingResult] {
            assert_eq!(r.after_initiator_act(state, P::Request), Some(state));
        }
        assert_eq!(
            r.after_initiator_act(SessionState::Done(Outcome::Refused), P::Request),
            None
        );
        assert_eq!(
            Protocol::Query.after_initiator_act(SessionState::AwaitingResult, P::Request),
            None
        );
    }

    #[test]
    fn only_iterated_contract_net_calls_new_rounds() {
        assert_eq!(
            Protocol::ContractNet.after_initiator_act(SessionState::Proposed, P::Cfp),
            None
        );
        assert_eq!(
            Protocol::IteratedContractNet.after_initiator_act(SessionState::Proposed, P::Cfp),
            Some(SessionState::AwaitingResponse)
        );
    }
}
