//! Every branch of every protocol, driven end to end: initiator and responders exchange real
//! `AclMessage`s (through the string codec, as on a wire), time is passed explicitly.

use iw_acl::codec;
use iw_acl::{AclMessage, AgentId, FipaDateTime, Performative as P};
use iw_interaction::{
    Error, EventKind, Handler, Initiator, Outcome, Protocol, Responder, SessionState,
};

const T0: i64 = 1_900_000_000_000;
const DEADLINE: i64 = T0 + 5_000;

fn aid(name: &str) -> AgentId {
    AgentId::new(format!("{name}@IntellWheels"))
}

fn name(agent: &str) -> String {
    aid(agent).name
}

/// Sends through the ACL string codec, as a transport would.
fn wire(message: &AclMessage) -> AclMessage {
    codec::parse(&codec::print(message)).expect("printed messages parse")
}

fn opening(protocol: Protocol, act: P, receivers: &[&str]) -> AclMessage {
    receivers
        .iter()
        .fold(AclMessage::new(act), |m, r| m.with_receiver(aid(r)))
        .with_sender(aid("wheelchair1"))
        .with_protocol(protocol.fipa_name())
        .with_conversation_id("conv-1")
        .with_reply_with("req")
        .with_language("fipa-sl")
        .with_content("((action (agent-identifier :name x) (goto-xy :x 1 :y 2)))")
        .with_reply_by(FipaDateTime::from_unix_ms(DEADLINE))
}

/// Starts a conversation and one responder per receiver.
fn start(protocol: Protocol, act: P, receivers: &[&str]) -> (Initiator, Vec<Responder>) {
    let (initiator, sent) = Initiator::start(opening(protocol, act, receivers), T0).unwrap();
    let responders = sent
        .iter()
        .map(|m| {
            let m = wire(m);
            Responder::accept(&m, m.receivers[0].clone(), T0).unwrap()
        })
        .collect();
    (initiator, responders)
}

/// The responder answers `act`; the initiator handles it; returns the event kind.
fn answer(
    initiator: &mut Initiator,
    responder: &mut Responder,
    act: P,
    now: i64,
) -> Result<EventKind, Error> {
    let reply = responder.reply(act, now)?;
    initiator.handle(&wire(&reply), now).map(|e| e.kind)
}

#[derive(Default)]
struct Counts {
    agree: u32,
    refuse: u32,
    not_understood: u32,
    inform: u32,
    failure: u32,
    timeout: Vec<String>,
}

impl Handler for Counts {
    fn on_agree(&mut self, _: &AclMessage) {
        self.agree += 1;
    }
    fn on_refuse(&mut self, _: &AclMessage) {
        self.refuse += 1;
    }
    fn on_not_understood(&mut self, _: &AclMessage) {
        self.not_understood += 1;
    }
    fn on_inform(&mut self, _: &AclMessage) {
        self.inform += 1;
    }
    fn on_failure(&mut self, _: &AclMessage) {
        self.failure += 1;
    }
    fn on_timeout(&mut self, participant: &AgentId) {
        self.timeout.push(participant.name.clone());
    }
}

#[test]
fn request_agree_then_inform_reaches_the_handler() {
    let (mut initiator, mut responders) = start(Protocol::Request, P::Request, &["nav"]);
    let responder = &mut responders[0];
    let mut counts = Counts::default();
    let agree = wire(&responder.reply(P::Agree, T0 + 10).unwrap());
    assert_eq!(agree.in_reply_to.as_deref(), Some("req#1"));
    let event = initiator.dispatch(&agree, T0 + 10, &mut counts).unwrap();
    assert_eq!(
        (event.kind, event.state),
        (EventKind::Agreed, SessionState::AwaitingResult)
    );
    // The result may come after the deadline: only the first answer is bounded.
    let inform = wire(
        &responder
            .reply(P::Inform, DEADLINE + 10)
            .unwrap()
            .with_content("((done x))"),
    );
    let event = initiator
        .dispatch(&inform, DEADLINE + 10, &mut counts)
        .unwrap();
    assert_eq!(event.state, SessionState::Done(Outcome::Informed));
    assert_eq!((counts.agree, counts.inform), (1, 1));
    assert!(initiator.is_done());
    assert_eq!(initiator.next_deadline(), None);
    assert_eq!(
        initiator
            .session(&name("nav"))
            .unwrap()
            .last_received()
            .unwrap()
            .content_text(),
        Some("((done x))")
    );
}

#[test]
fn request_refused_not_understood_failed_and_direct_inform() {
    let (mut initiator, mut responders) =
        start(Protocol::Request, P::Request, &["a", "b", "c", "d"]);
    let mut counts = Counts::default();
    let acts = [
        (P::Refuse, Outcome::Refused),
        (P::NotUnderstood, Outcome::NotUnderstood),
        (P::Failure, Outcome::Failed),
        (P::Inform, Outcome::Informed),
    ];
    for (responder, (act, outcome)) in responders.iter_mut().zip(acts) {
        let reply = wire(&responder.reply(act, T0 + 1).unwrap());
        assert_eq!(
            initiator
                .dispatch(&reply, T0 + 1, &mut counts)
                .unwrap()
                .state,
            SessionState::Done(outcome)
        );
        assert_eq!(responder.state(), SessionState::Done(outcome));
    }
    assert_eq!(
        (
            counts.refuse,
            counts.not_understood,
            counts.failure,
            counts.inform
        ),
        (1, 1, 1, 1)
    );
    assert!(initiator.is_done());
}

#[test]
fn request_agree_then_failure() {
    let (mut initiator, mut responders) = start(Protocol::Request, P::Request, &["nav"]);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Agree, T0),
        Ok(EventKind::Agreed)
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Failure, T0 + 1),
        Ok(EventKind::Failed)
    );
    assert_eq!(
        initiator.sessions()[0].state(),
        SessionState::Done(Outcome::Failed)
    );
}

#[test]
fn silence_times_out_at_the_deadline_and_late_answers_are_refused() {
    let (mut initiator, mut responders) = start(Protocol::Request, P::Request, &["fast", "slow"]);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Agree, T0 + 1),
        Ok(EventKind::Agreed)
    );
    assert_eq!(initiator.next_deadline(), Some(DEADLINE));
    assert!(
        initiator.tick(DEADLINE).is_empty(),
        "the deadline itself is still in time"
    );
    // A late answer is refused by both sides and changes nothing.
    let late = responders[1].clone().reply(P::Agree, DEADLINE + 1);
    assert!(matches!(late, Err(Error::Late { .. })), "{late:?}");
    let mut late_agree = responders[1]
        .latest()
        .create_reply()
        .with_performative(P::Agree);
    late_agree.sender = Some(aid("slow"));
    assert!(matches!(
        initiator.handle(&late_agree, DEADLINE + 1),
        Err(Error::Late { .. })
    ));
    let mut counts = Counts::default();
    let events = initiator.tick_with(DEADLINE + 1, &mut counts);
    assert_eq!(events.len(), 1);
    assert_eq!(
        (events[0].kind, events[0].state),
        (EventKind::TimedOut, SessionState::Done(Outcome::TimedOut))
    );
    assert_eq!(counts.timeout, [name("slow")]);
    assert_eq!(
        initiator.session(&name("fast")).unwrap().state(),
        SessionState::AwaitingResult
    );
    assert!(
        initiator.tick(DEADLINE + 100).is_empty(),
        "a timeout is reported once"
    );
    assert!(matches!(
        initiator.handle(&late_agree, DEADLINE + 2),
        Err(Error::OutOfProtocol { .. })
    ));
}

#[test]
fn out_of_protocol_messages_are_refused_with_the_reason() {
    let (mut initiator, mut responders) = start(Protocol::Request, P::Request, &["nav"]);
    let responder = &mut responders[0];
    let err = responder.reply(P::Propose, T0).unwrap_err();
    assert_eq!(
        err,
        Error::OutOfProtocol {
            protocol: Protocol::Request,
            state: SessionState::AwaitingResponse,
            act: P::Propose,
            participant: name("wheelchair1")
        }
    );
    assert!(
        err.to_string()
            .contains("PROPOSE is not allowed in fipa-request"),
        "{err}"
    );
    let mut propose = responder
        .latest()
        .create_reply()
        .with_performative(P::Propose);
    propose.sender = Some(aid("nav"));
    assert!(matches!(
        initiator.handle(&propose, T0),
        Err(Error::OutOfProtocol {
            act: P::Propose,
            ..
        })
    ));
    assert_eq!(
        initiator.sessions()[0].state(),
        SessionState::AwaitingResponse,
        "a refused message changes nothing"
    );
    answer(&mut initiator, responder, P::Agree, T0).unwrap();
    assert!(matches!(
        responder.reply(P::Refuse, T0),
        Err(Error::OutOfProtocol { .. })
    ));
    assert!(matches!(
        initiator.handle(&propose.clone().with_performative(P::Agree), T0),
        Err(Error::OutOfProtocol { .. })
    ));
    assert!(matches!(
        initiator.decide(&[&name("nav")]),
        Err(Error::OutOfProtocol {
            act: P::AcceptProposal,
            ..
        })
    ));
    assert!(matches!(
        initiator.cancel(&name("nav")),
        Err(Error::OutOfProtocol { act: P::Cancel, .. })
    ));
}

#[test]
fn foreign_replies_are_refused() {
    let (mut initiator, mut responders) = start(Protocol::Request, P::Request, &["nav"]);
    let agree = responders[0].reply(P::Agree, T0).unwrap();
    let other_conversation = agree.clone().with_conversation_id("conv-2");
    assert!(matches!(
        initiator.handle(&other_conversation, T0),
        Err(Error::WrongConversation { .. })
    ));
    let unknown_tag = agree.clone().with_in_reply_to("nope");
    assert!(matches!(
        initiator.handle(&unknown_tag, T0),
        Err(Error::UnknownReply { .. })
    ));
    let impostor = agree.clone().with_sender(aid("mallory"));
    assert!(matches!(
        initiator.handle(&impostor, T0),
        Err(Error::WrongSender { .. })
    ));
    // Without in-reply-to, the sender identifies the session.
    let mut untagged = agree.clone();
    untagged.in_reply_to = None;
    assert_eq!(
        initiator.handle(&untagged, T0).unwrap().kind,
        EventKind::Agreed
    );
}

#[test]
fn openings_are_checked() {
    let wrong_act = opening(Protocol::Query, P::Request, &["a"]);
    assert!(matches!(
        Initiator::start(wrong_act, T0),
        Err(Error::NotInitiating {
            protocol: Protocol::Query,
            performative: P::Request
        })
    ));
    let mut no_protocol = opening(Protocol::Request, P::Request, &["a"]);
    no_protocol.protocol = None;
    assert!(matches!(
        Initiator::start(no_protocol, T0),
        Err(Error::MissingProtocol { .. })
    ));
    let mut no_conversation = opening(Protocol::Request, P::Request, &["a"]);
    no_conversation.conversation_id = None;
    assert!(matches!(
        Initiator::start(no_conversation.clone(), T0),
        Err(Error::MissingConversationId { .. })
    ));
    assert!(matches!(
        Responder::accept(&no_conversation, aid("a"), T0),
        Err(Error::MissingConversationId { .. })
    ));
    assert!(matches!(
        Initiator::start(opening(Protocol::Request, P::Request, &[]), T0),
        Err(Error::NoReceivers { .. })
    ));
    let unknown = opening(Protocol::Request, P::Request, &["a"]).with_protocol("fipa-dance");
    assert!(matches!(
        Initiator::start(unknown, T0),
        Err(Error::UnknownProtocol { .. })
    ));
}

#[test]
fn query_ref_and_query_if() {
    let (mut initiator, mut responders) = start(Protocol::Query, P::QueryRef, &["loc"]);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Inform, T0 + 1),
        Ok(EventKind::Informed)
    );
    let (mut initiator, mut responders) = start(Protocol::Query, P::QueryIf, &["loc", "map"]);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Refuse, T0 + 1),
        Ok(EventKind::Refused)
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[1], P::Agree, T0 + 1),
        Ok(EventKind::Agreed)
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[1], P::Inform, T0 + 2),
        Ok(EventKind::Informed)
    );
    assert!(initiator.is_done());
}

#[test]
fn request_when_agrees_then_informs_when_the_condition_holds() {
    let (mut initiator, mut responders) = start(Protocol::RequestWhen, P::RequestWhen, &["door"]);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Agree, T0 + 1),
        Ok(EventKind::Agreed)
    );
    assert!(
        initiator.tick(DEADLINE + 60_000).is_empty(),
        "an agreed request-when waits for its condition"
    );
    assert_eq!(
        answer(
            &mut initiator,
            &mut responders[0],
            P::Inform,
            DEADLINE + 60_000
        ),
        Ok(EventKind::Informed)
    );
}

/// Bidders propose their price as content.
fn bid(initiator: &mut Initiator, responder: &mut Responder, price: u32, now: i64) -> EventKind {
    let proposal = responder
        .reply(P::Propose, now)
        .unwrap()
        .with_content(price.to_string());
    initiator.handle(&wire(&proposal), now).unwrap().kind
}

/// The cheapest standing bid.
fn best(initiator: &Initiator) -> String {
    initiator
        .sessions()
        .iter()
        .filter(|s| s.state() == SessionState::Proposed)
        .min_by_key(|s| {
            s.last_received()
                .and_then(|m| m.content_text()?.parse::<u32>().ok())
        })
        .map(|s| s.participant().name.clone())
        .unwrap()
}

/// Delivers the initiator's decisions to the matching responders.
fn deliver(decisions: &[AclMessage], responders: &mut [Responder], now: i64) {
    for message in decisions {
        let message = wire(message);
        let responder = responders
            .iter_mut()
            .find(|r| {
                r.latest()
                    .receivers
                    .iter()
                    .any(|a| a.name == message.receivers[0].name)
            })
            .unwrap();
        responder.handle(&message, now).unwrap();
    }
}

#[test]
fn contract_net_accepts_the_best_bid_and_rejects_the_others() {
    let (mut initiator, mut responders) =
        start(Protocol::ContractNet, P::Cfp, &["b1", "b2", "b3", "b4"]);
    assert_eq!(
        bid(&mut initiator, &mut responders[0], 10, T0 + 1),
        EventKind::Proposed
    );
    assert_eq!(
        bid(&mut initiator, &mut responders[1], 7, T0 + 2),
        EventKind::Proposed
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[2], P::Refuse, T0 + 3),
        Ok(EventKind::Refused)
    );
    // b4 stays silent: no decision before the deadline passes.
    assert!(
        matches!(initiator.decide(&[&name("b2")]), Err(Error::RoundOpen { waiting }) if waiting == [name("b4")])
    );
    assert_eq!(initiator.tick(DEADLINE + 1).len(), 1);
    let winner = best(&initiator);
    assert_eq!(winner, name("b2"));
    let decisions = initiator.decide(&[&winner]).unwrap();
    let acts: Vec<_> = decisions
        .iter()
        .map(|m| (m.receivers[0].name.clone(), m.performative))
        .collect();
    assert_eq!(
        acts,
        [
            (name("b1"), P::RejectProposal),
            (name("b2"), P::AcceptProposal)
        ]
    );
    assert!(
        decisions
            .iter()
            .all(|m| m.conversation_id.as_deref() == Some("conv-1")
                && m.protocol.as_deref() == Some("fipa-contract-net"))
    );
    assert_ne!(decisions[0].reply_with, decisions[1].reply_with);
    deliver(&decisions, &mut responders, DEADLINE + 2);
    assert_eq!(responders[0].state(), SessionState::Done(Outcome::Rejected));
    assert_eq!(responders[1].state(), SessionState::AwaitingResult);
    assert_eq!(
        answer(&mut initiator, &mut responders[1], P::Inform, DEADLINE + 3),
        Ok(EventKind::Informed)
    );
    assert!(initiator.is_done());
    let outcomes: Vec<_> = initiator.sessions().iter().map(|s| s.state()).collect();
    assert_eq!(
        outcomes,
        [
            Outcome::Rejected,
            Outcome::Informed,
            Outcome::Refused,
            Outcome::TimedOut
        ]
        .map(SessionState::Done)
    );
    // A rejected bidder cannot deliver a result, and the plain contract net has no second round.
    assert!(matches!(
        responders[0].reply(P::Inform, DEADLINE + 4),
        Err(Error::OutOfProtocol { .. })
    ));
    let (mut plain, mut bidders) = start(Protocol::ContractNet, P::Cfp, &["b1"]);
    bid(&mut plain, &mut bidders[0], 3, T0);
    let next = opening(Protocol::ContractNet, P::Cfp, &["b1"]);
    assert!(matches!(
        plain.iterate(&[&name("b1")], &next, T0),
        Err(Error::OutOfProtocol { act: P::Cfp, .. })
    ));
}

#[test]
fn contract_net_result_can_fail() {
    let (mut initiator, mut responders) = start(Protocol::ContractNet, P::Cfp, &["b1"]);
    bid(&mut initiator, &mut responders[0], 5, T0);
    let decisions = initiator.decide(&[&name("b1")]).unwrap();
    deliver(&decisions, &mut responders, T0 + 1);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Failure, T0 + 2),
        Ok(EventKind::Failed)
    );
    assert!(matches!(
        initiator.decide(&[&name("nobody")]),
        Err(Error::UnknownParticipant { .. })
    ));
}

#[test]
fn iterated_contract_net_runs_a_second_round() {
    let (mut initiator, mut responders) =
        start(Protocol::IteratedContractNet, P::Cfp, &["b1", "b2", "b3"]);
    for (responder, price) in responders.iter_mut().zip([12, 9, 20]) {
        bid(&mut initiator, responder, price, T0 + 1);
    }
    // Keep the two cheapest for a second round with a later deadline; reject the third.
    let second_deadline = DEADLINE + 10_000;
    let next_cfp = AclMessage::new(P::Cfp)
        .with_content("((lower-your-price))")
        .with_reply_by(FipaDateTime::from_unix_ms(second_deadline));
    let messages = initiator
        .iterate(&[&name("b1"), &name("b2")], &next_cfp, T0 + 2)
        .unwrap();
    let acts: Vec<_> = messages.iter().map(|m| m.performative).collect();
    assert_eq!(acts, [P::Cfp, P::Cfp, P::RejectProposal]);
    assert_eq!(messages[0].content_text(), Some("((lower-your-price))"));
    assert_eq!(initiator.round(), 2);
    assert_eq!(initiator.next_deadline(), Some(second_deadline));
    deliver(&messages, &mut responders, T0 + 3);
    assert_eq!(responders[2].state(), SessionState::Done(Outcome::Rejected));
    // A replayed first-round bid no longer routes.
    let stale = initiator
        .session(&name("b1"))
        .unwrap()
        .last_received()
        .unwrap()
        .clone();
    assert!(matches!(
        initiator.handle(&stale, T0 + 4),
        Err(Error::UnknownReply { .. })
    ));
    // Second round: after the first deadline, before the second.
    bid(&mut initiator, &mut responders[0], 8, DEADLINE + 1);
    bid(&mut initiator, &mut responders[1], 9, DEADLINE + 2);
    let winner = best(&initiator);
    assert_eq!(winner, name("b1"));
    let decisions = initiator.decide(&[&winner]).unwrap();
    deliver(&decisions, &mut responders, DEADLINE + 3);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Inform, DEADLINE + 4),
        Ok(EventKind::Informed)
    );
    assert!(initiator.is_done());
}

#[test]
fn subscription_notifies_until_cancelled() {
    let (mut initiator, mut responders) = start(Protocol::Subscribe, P::Subscribe, &["df"]);
    let responder = &mut responders[0];
    assert_eq!(
        answer(&mut initiator, responder, P::Agree, T0 + 1),
        Ok(EventKind::Agreed)
    );
    for now in [T0 + 2, DEADLINE + 100] {
        assert_eq!(
            answer(&mut initiator, responder, P::Inform, now),
            Ok(EventKind::Notified)
        );
    }
    assert_eq!(initiator.sessions()[0].state(), SessionState::Subscribed);
    let cancel = wire(&initiator.cancel(&name("df")).unwrap());
    assert_eq!(cancel.performative, P::Cancel);
    assert_eq!(
        cancel.content,
        opening(Protocol::Subscribe, P::Subscribe, &["df"]).content
    );
    assert_eq!(
        responder.handle(&cancel, DEADLINE + 200),
        Ok(SessionState::Cancelling)
    );
    let confirm = wire(&responder.reply(P::Inform, DEADLINE + 201).unwrap());
    assert_eq!(
        confirm.in_reply_to, cancel.reply_with,
        "the confirmation answers the CANCEL"
    );
    assert_eq!(
        initiator.handle(&confirm, DEADLINE + 201).unwrap().kind,
        EventKind::Cancelled
    );
    assert_eq!(
        initiator.sessions()[0].state(),
        SessionState::Done(Outcome::Cancelled)
    );
    assert!(matches!(
        responder.reply(P::Inform, DEADLINE + 300),
        Err(Error::OutOfProtocol { .. })
    ));
    assert!(matches!(
        initiator.cancel(&name("df")),
        Err(Error::OutOfProtocol { .. })
    ));
}

#[test]
fn subscription_can_be_refused_or_fail() {
    let (mut initiator, mut responders) = start(Protocol::Subscribe, P::Subscribe, &["a", "b"]);
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::Refuse, T0),
        Ok(EventKind::Refused)
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[1], P::Agree, T0),
        Ok(EventKind::Agreed)
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[1], P::Failure, T0 + 1),
        Ok(EventKind::Failed)
    );
}

#[test]
fn propose_is_accepted_or_rejected() {
    let (mut initiator, mut responders) = start(
        Protocol::Propose,
        P::Propose,
        &["user", "caregiver", "other"],
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[0], P::AcceptProposal, T0),
        Ok(EventKind::Accepted)
    );
    assert_eq!(
        answer(&mut initiator, &mut responders[1], P::RejectProposal, T0),
        Ok(EventKind::Rejected)
    );
    assert!(matches!(
        responders[2].reply(P::Refuse, T0),
        Err(Error::OutOfProtocol { .. })
    ));
    assert_eq!(
        answer(&mut initiator, &mut responders[2], P::NotUnderstood, T0),
        Ok(EventKind::NotUnderstood)
    );
    let states: Vec<_> = initiator.sessions().iter().map(|s| s.state()).collect();
    assert_eq!(
        states,
        [Outcome::Accepted, Outcome::Rejected, Outcome::NotUnderstood].map(SessionState::Done)
    );
}

#[test]
fn a_request_stream_goes_on_until_the_participant_ends_it() {
    let (mut initiator, mut responders) = start(Protocol::Request, P::Request, &["control"]);
    let next = AclMessage::new(P::Request).with_content("((action x (drive :linear 0.2)))");
    let opening_tag = responders[0].latest().reply_with.clone();
    assert!(opening_tag.is_some());
    // Before and after the AGREE, each item is a REQUEST in the same conversation, to the
    // participant, asking no reply of its own.
    for agreed in [false, true] {
        if agreed {
            let kind = answer(&mut initiator, &mut responders[0], P::Agree, T0 + 1).unwrap();
            assert_eq!(kind, EventKind::Agreed);
        }
        let items = initiator.stream(&next).unwrap();
        assert_eq!(items.len(), 1);
        let item = wire(&items[0]);
        assert_eq!(item.performative, P::Request);
        assert_eq!(item.conversation_id.as_deref(), Some("conv-1"));
        assert_eq!(item.protocol.as_deref(), Some("fipa-request"));
        assert_eq!(item.receivers, vec![aid("control")]);
        assert_eq!(item.reply_with, None);
        assert_eq!(item.content, next.content);
        // The participant takes the item as its stream's (the state stays) ...
        let state = responders[0].state();
        assert_eq!(responders[0].handle(&item, T0 + 1), Ok(state));
        // ... and refuses one from another agent or another conversation, changing nothing.
        let mut stranger = item.clone();
        stranger.sender = Some(aid("intruder"));
        assert!(matches!(
            responders[0].handle(&stranger, T0 + 1),
            Err(Error::WrongSender { .. })
        ));
        let elsewhere = item.clone().with_conversation_id("conv-2");
        assert!(matches!(
            responders[0].handle(&elsewhere, T0 + 1),
            Err(Error::WrongConversation { .. })
        ));
        assert_eq!(responders[0].state(), state);
    }
    // The participant's end answers the opening, and is matched to it; then nothing more is
    // streamed.
    assert_eq!(responders[0].latest().reply_with, opening_tag);
    let kind = answer(&mut initiator, &mut responders[0], P::Failure, T0 + 2).unwrap();
    assert_eq!(kind, EventKind::Failed);
    assert!(initiator.is_done());
    assert!(initiator.stream(&next).unwrap().is_empty());
    // Only fipa-request streams.
    let (query, _) = start(Protocol::Query, P::QueryRef, &["control"]);
    assert!(query.stream(&next).is_err());
}
