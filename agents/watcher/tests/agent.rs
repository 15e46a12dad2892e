//! The watcher alone on an in-process bus with a mock clock, driven by chairs sending real ACL.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_bus::{MockController, Time};
use iw_interaction::{Error, EventKind, Initiator, Protocol, Responder, SessionState};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};
use iw_watcher::{WatcherAgent, WatcherConfig};
use proptest::prelude::*;

type Mailbag = Arc<Mutex<Vec<AclMessage>>>;

struct Chair {
    inbox: Mailbag,
    outbox: Mailbag,
}

impl Agent for Chair {
    fn handle(&mut self, _ctx: &mut Context<'_>, message: AclMessage) {
        self.inbox.lock().unwrap().push(message);
    }
    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_millis(1))
    }
    fn tick(&mut self, ctx: &mut Context<'_>) {
        for m in self.outbox.lock().unwrap().drain(..) {
            ctx.send(m).unwrap();
        }
    }
}

const CHAIRS: usize = 4;
const PASSAGES: [&str; 2] = ["door-a", "corridor-b"];

struct Rig {
    host: AgentHost,
    clock: MockController,
    chairs: Vec<(Mailbag, Mailbag)>,
}

fn rig() -> Rig {
    let (mut host, controller) = AgentHost::on_a_mock_clock(Time::from_ns(1_000_000_000));
    let config = WatcherConfig {
        passages: PASSAGES.iter().map(|p| p.to_string()).collect(),
        lease: Duration::from_secs(2),
        period: Duration::from_millis(50),
    };
    host.add(
        AgentId::new("watcher"),
        Box::new(WatcherAgent::new(config).unwrap()),
    )
    .unwrap();
    let chairs = (0..CHAIRS)
        .map(|i| {
            let (inbox, outbox): (Mailbag, Mailbag) = (Arc::default(), Arc::default());
            host.add(
                AgentId::new(format!("chair{i}")),
                Box::new(Chair {
                    inbox: Arc::clone(&inbox),
                    outbox: Arc::clone(&outbox),
                }),
            )
            .unwrap();
            (inbox, outbox)
        })
        .collect();
    Rig {
        host,
        clock: controller,
        chairs,
    }
}

/// `act` with `((action watcher (pass :passage P :direction D)))`.
fn asking(act: Performative, passage: &str, direction: &str) -> AclMessage {
    let action = WheelchairAction::Pass {
        passage: passage.into(),
        direction: direction.into(),
    };
    WheelchairContent::Request {
        actor: AgentId::new("watcher"),
        action,
    }
    .fill(AclMessage::new(act).with_receiver(AgentId::new("watcher")))
}

/// chair `c`'s subscription to pass `passage` going `direction`, in conversation `id`.
fn pass_in(c: usize, passage: usize, direction: &str, id: &str) -> AclMessage {
    asking(Performative::Subscribe, PASSAGES[passage], direction)
        .with_sender(AgentId::new(format!("chair{c}")))
        .with_protocol(Protocol::Subscribe.fipa_name())
        .with_conversation_id(id)
}

/// chair `c`'s one subscription to pass `passage` going `direction`.
fn pass(c: usize, passage: usize, direction: &str) -> AclMessage {
    pass_in(c, passage, direction, &conversation(c, passage))
}

fn cancel(c: usize, passage: usize) -> AclMessage {
    AclMessage::new(Performative::Cancel)
        .with_receiver(AgentId::new("watcher"))
        .with_protocol(Protocol::Subscribe.fipa_name())
        .with_conversation_id(conversation(c, passage))
}

const DIRECTIONS: [&str; 2] = ["forward", "backward"];

fn conversation(chair: usize, passage: usize) -> String {
    format!("chair{chair}-{}", PASSAGES[passage])
}

/// One subscription as its chair sees it, run on fipa-subscribe's state machine.
struct Asked {
    chair: usize,
    passage: usize,
    direction: usize,
    initiator: Initiator,
    /// Whether the chair cancelled it: a notification may cross the CANCEL, and the
    /// confirmation then comes after the end.
    cancelled: bool,
}

#[derive(Debug, Clone)]
enum Op {
    Request(usize, usize, usize),
    Cancel(usize, usize),
    Wait(u64),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0..CHAIRS, 0..PASSAGES.len(), 0..DIRECTIONS.len())
            .prop_map(|(c, p, d)| Op::Request(c, p, d)),
        (0..CHAIRS, 0..PASSAGES.len()).prop_map(|(c, p)| Op::Cancel(c, p)),
        (10u64..1500).prop_map(Op::Wait),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn chairs_in_a_passage_never_go_opposite_ways(ops in proptest::collection::vec(op(), 1..60)) {
        let mut rig = rig();
        // Every subscription by conversation id, each answer checked against fipa-subscribe as
        // the chair's initiator runs it; which conversations hold a grant; messages read so far
        // per chair.
        let mut asked: BTreeMap<String, Asked> = BTreeMap::new();
        let mut holds: BTreeSet<String> = BTreeSet::new();
        let mut read = [0usize; CHAIRS];
        for (n, op) in ops.into_iter().enumerate() {
            match op {
                Op::Request(c, p, d) => {
                    let id = format!("{}-{n}", conversation(c, p));
                    let (initiator, opening) = Initiator::start(pass_in(c, p, DIRECTIONS[d], &id), 0).unwrap();
                    asked.insert(id, Asked { chair: c, passage: p, direction: d, initiator, cancelled: false });
                    rig.chairs[c].1.lock().unwrap().extend(opening);
                }
                Op::Cancel(c, p) => {
                    // The chair's latest live subscription for the passage.
                    let live = asked.iter_mut().rev().find(|(_, a)| a.chair == c && a.passage == p && !a.initiator.is_done());
                    if let Some((id, a)) = live {
                        let cancel = a.initiator.cancel("watcher").unwrap();
                        a.cancelled = true;
                        holds.remove(id);
                        rig.chairs[c].1.lock().unwrap().push(cancel);
                    }
                }
                Op::Wait(ms) => rig.clock.advance(Duration::from_millis(ms)),
            }
            rig.host.step(rig.clock.now());
            rig.clock.advance(Duration::from_millis(5));
            for (c, (inbox, _)) in rig.chairs.iter().enumerate() {
                let inbox = inbox.lock().unwrap();
                for m in &inbox[read[c]..] {
                    let id = m.conversation_id.clone().unwrap_or_default();
                    let Some(a) = asked.get_mut(&id) else {
                        return Err(TestCaseError::fail(format!("an answer in no conversation of chair{c}: {m:?}")));
                    };
                    prop_assert_eq!(a.chair, c);
                    let content = WheelchairContent::from_message(m);
                    let event = match a.initiator.handle(m, 0) {
                        Ok(event) => event,
                        // a grant crossed the CANCEL and was taken for its confirmation: the
                        // real confirmation, told apart by its content, comes after
                        Err(Error::OutOfProtocol { state: SessionState::Done(_), .. })
                            if a.cancelled && matches!(content, Ok(WheelchairContent::Cancelled { .. })) => continue,
                        Err(err) => {
                            return Err(TestCaseError::fail(format!("the watcher broke fipa-subscribe: {err}: {m:?}")));
                        }
                    };
                    match event.kind {
                        EventKind::Notified => {
                            let Ok(WheelchairContent::Done { action: WheelchairAction::Pass { direction, .. }, .. }) = WheelchairContent::from_message(m) else {
                                panic!("a grant is a done pass: {m:?}");
                            };
                            prop_assert_eq!(direction.as_str(), DIRECTIONS[a.direction], "granted a direction never asked");
                            holds.insert(id);
                        }
                        EventKind::Failed => { holds.remove(&id); }
                        EventKind::Cancelled => {
                            holds.remove(&id);
                            let passage = PASSAGES[a.passage];
                            let direction = DIRECTIONS[a.direction];
                            // the confirmation, or a grant that crossed the CANCEL (its
                            // confirmation follows)
                            prop_assert!(
                                matches!(
                                    &content,
                                    Ok(WheelchairContent::Cancelled { action: WheelchairAction::Pass { passage: p, direction: d }, .. }
                                        | WheelchairContent::Done { action: WheelchairAction::Pass { passage: p, direction: d }, .. })
                                        if p == passage && d == direction
                                ),
                                "not the cancel's confirmation: {:?}", m
                            );
                        }
                        EventKind::Agreed | EventKind::Refused => {}
                        other => prop_assert!(false, "unexpected {other:?}"),
                    }
                }
                read[c] = inbox.len();
            }
            for (p, name) in PASSAGES.iter().enumerate() {
                let directions: BTreeSet<usize> = holds.iter().map(|id| &asked[id]).filter(|a| a.passage == p).map(|a| a.direction).collect();
                prop_assert!(directions.len() <= 1, "{name} held both ways");
            }
        }
    }
}

/// The decision the watcher's protocol rests on: the answers it once sent (INFORM done when
/// granted, then FAILURE "lease expired" in the same conversation) are refused by
/// fipa-request's state machine, while fipa-subscribe allows the grant, its release and its
/// expiry.
#[test]
fn fipa_request_refuses_a_failure_after_the_grant_and_fipa_subscribe_allows_it() {
    let open = |act, protocol: Protocol| {
        let opening = asking(act, "door-a", "forward")
            .with_sender(AgentId::new("chair0"))
            .with_protocol(protocol.fipa_name())
            .with_conversation_id("c1");
        (
            Responder::accept(&opening, AgentId::new("watcher"), 0).unwrap(),
            opening,
        )
    };
    let (mut request, _) = open(Performative::Request, Protocol::Request);
    request.reply(Performative::Agree, 0).unwrap();
    request.reply(Performative::Inform, 0).unwrap();
    assert!(matches!(
        request.reply(Performative::Failure, 0),
        Err(Error::OutOfProtocol {
            protocol: Protocol::Request,
            state: SessionState::Done(_),
            act: Performative::Failure,
            ..
        })
    ));
    // The lease runs out.
    let (mut expiring, _) = open(Performative::Subscribe, Protocol::Subscribe);
    for act in [
        Performative::Agree,
        Performative::Inform,
        Performative::Failure,
    ] {
        expiring.reply(act, 0).unwrap();
    }
    assert!(expiring.state().is_done());
    // The chair lets go.
    let (mut released, opening) = open(Performative::Subscribe, Protocol::Subscribe);
    released.reply(Performative::Agree, 0).unwrap();
    released.reply(Performative::Inform, 0).unwrap();
    let cancel = AclMessage::new(Performative::Cancel)
        .with_sender(AgentId::new("chair0"))
        .with_conversation_id(opening.conversation_id.unwrap());
    released.handle(&cancel, 0).unwrap();
    released.reply(Performative::Inform, 0).unwrap();
    assert!(released.state().is_done());
}

#[test]
fn grants_are_fifo_one_direction_at_a_time_and_a_stuck_holder_loses_its_lease() {
    let mut rig = rig();
    // chair0 and chair2 go forward, chair1 backward, asking in that order.
    for (c, direction) in [(0, "forward"), (1, "backward"), (2, "forward")] {
        rig.chairs[c].1.lock().unwrap().push(pass(c, 0, direction));
        rig.host.step(rig.clock.now());
        rig.clock.advance(Duration::from_millis(10));
    }
    let granted = |rig: &Rig| -> Vec<bool> {
        rig.chairs
            .iter()
            .map(|(i, _)| {
                i.lock()
                    .unwrap()
                    .iter()
                    .any(|m| m.performative == Performative::Inform)
            })
            .collect()
    };
    // chair2 could follow chair0, but chair1 asked first: it does not overtake.
    assert_eq!(granted(&rig), [true, false, false, false]);
    let grant = rig.chairs[0]
        .0
        .lock()
        .unwrap()
        .iter()
        .find(|m| m.performative == Performative::Inform)
        .unwrap()
        .clone();
    let content = iw_sl::parse(grant.content_text().unwrap(), iw_sl::Level::Sl0).unwrap();
    assert!(
        content.to_string().starts_with("((done (action"),
        "{content}"
    );
    // chair0 releases: chair1 is next.
    rig.chairs[0].1.lock().unwrap().push(cancel(0, 0));
    rig.host.step(rig.clock.now());
    assert_eq!(granted(&rig), [true, true, false, false]);
    // the release is confirmed by the cancel's inform-done, not a second grant
    let confirmation = rig.chairs[0].0.lock().unwrap().last().unwrap().clone();
    assert_eq!(confirmation.performative, Performative::Inform);
    assert_ne!(confirmation.content, grant.content);
    assert_eq!(
        WheelchairContent::from_message(&confirmation).unwrap(),
        WheelchairContent::Cancelled {
            actor: AgentId::new("watcher"),
            action: WheelchairAction::Pass {
                passage: PASSAGES[0].into(),
                direction: "forward".into(),
            },
        }
    );
    // chair1 never releases: after the 2 s lease it gets FAILURE and chair2 passes.
    for _ in 0..50 {
        rig.clock.advance(Duration::from_millis(50));
        rig.host.step(rig.clock.now());
    }
    assert!(
        rig.chairs[1]
            .0
            .lock()
            .unwrap()
            .iter()
            .any(|m| m.performative == Performative::Failure)
    );
    assert_eq!(granted(&rig), [true, true, true, false]);
}

#[test]
fn chairs_going_the_same_way_follow_each_other() {
    let mut rig = rig();
    for c in 0..3 {
        rig.chairs[c].1.lock().unwrap().push(pass(c, 1, "backward"));
    }
    rig.host.step(rig.clock.now());
    let grants = |c: usize| {
        rig.chairs[c]
            .0
            .lock()
            .unwrap()
            .iter()
            .filter(|m| m.performative == Performative::Inform)
            .count()
    };
    assert_eq!((0..CHAIRS).map(grants).collect::<Vec<_>>(), [1, 1, 1, 0]);
}

#[test]
fn requests_are_not_understood_and_unknown_passages_refused() {
    let mut rig = rig();
    let go_to = WheelchairContent::Request {
        actor: AgentId::new("watcher"),
        action: WheelchairAction::GoTo {
            place: "hall".into(),
        },
    };
    rig.chairs[0].1.lock().unwrap().push(
        go_to.fill(AclMessage::new(Performative::Request).with_receiver(AgentId::new("watcher"))),
    );
    rig.chairs[1]
        .1
        .lock()
        .unwrap()
        .push(asking(Performative::Subscribe, "attic", "forward"));
    // A grant is a subscription: asking with fipa-request is not understood.
    rig.chairs[2]
        .1
        .lock()
        .unwrap()
        .push(asking(Performative::Request, PASSAGES[0], "forward"));
    rig.host.step(rig.clock.now());
    rig.host.step(rig.clock.now());
    let answers = |c: usize| {
        rig.chairs[c]
            .0
            .lock()
            .unwrap()
            .iter()
            .map(|m| m.performative)
            .collect::<Vec<_>>()
    };
    assert_eq!(answers(0), [Performative::NotUnderstood]);
    assert_eq!(answers(1), [Performative::Refuse]);
    assert_eq!(answers(2), [Performative::NotUnderstood]);
}
