//! The watcher alone on an in-process bus with a mock clock, driven by chairs sending real ACL.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, MockController, Stack, Time};
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
    let network = InProcNetwork::new();
    let (clock, controller) = Clock::mock(Time::from_ns(1_000_000_000));
    let bus = Bus::start(
        Stack::new(),
        Arc::new(network.endpoint("c1").unwrap()),
        clock,
        BusConfig::default(),
    )
    .unwrap();
    let mut host = AgentHost::new(Arc::new(bus));
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

/// chair `c`'s request to pass `passage` going `direction`.
fn pass(c: usize, passage: usize, direction: &str) -> AclMessage {
    let action = WheelchairAction::Pass {
        passage: PASSAGES[passage].into(),
        direction: direction.into(),
    };
    WheelchairContent::Request {
        actor: AgentId::new("watcher"),
        action,
    }
    .fill(
        AclMessage::new(Performative::Request)
            .with_receiver(AgentId::new("watcher"))
            .with_protocol("fipa-request")
            .with_conversation_id(conversation(c, passage)),
    )
}

const DIRECTIONS: [&str; 2] = ["forward", "backward"];

fn conversation(chair: usize, passage: usize) -> String {
    format!("chair{chair}-{}", PASSAGES[passage])
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
        // (chair, passage) -> the direction it holds, as the chairs see it; the directions it
        // asked for since it last cancelled; messages read so far per chair.
        let mut holds: BTreeMap<(usize, usize), Option<usize>> = BTreeMap::new();
        let mut asked: BTreeMap<(usize, usize), std::collections::BTreeSet<usize>> = BTreeMap::new();
        let mut read = [0usize; CHAIRS];
        for op in ops {
            match op {
                Op::Request(c, p, d) => {
                    asked.entry((c, p)).or_default().insert(d);
                    rig.chairs[c].1.lock().unwrap().push(pass(c, p, DIRECTIONS[d]));
                }
                Op::Cancel(c, p) => {
                    holds.insert((c, p), None);
                    asked.remove(&(c, p));
                    rig.chairs[c].1.lock().unwrap().push(
                        AclMessage::new(Performative::Cancel).with_receiver(AgentId::new("watcher")).with_conversation_id(conversation(c, p)),
                    );
                }
                Op::Wait(ms) => rig.clock.advance(Duration::from_millis(ms)),
            }
            rig.host.step(rig.clock.now());
            rig.clock.advance(Duration::from_millis(5));
            for (c, (inbox, _)) in rig.chairs.iter().enumerate() {
                let inbox = inbox.lock().unwrap();
                for m in &inbox[read[c]..] {
                    let p = PASSAGES.iter().position(|p| m.conversation_id.as_deref() == Some(conversation(c, 0).replace(PASSAGES[0], p).as_str())).unwrap();
                    match m.performative {
                        Performative::Inform => {
                            let Ok(WheelchairContent::Done { action: WheelchairAction::Pass { direction, .. }, .. }) = WheelchairContent::from_message(m) else {
                                panic!("a grant is a done pass: {m:?}");
                            };
                            let d = DIRECTIONS.iter().position(|x| *x == direction).unwrap();
                            prop_assert!(asked.get(&(c, p)).is_some_and(|a| a.contains(&d)), "granted a direction never asked");
                            holds.insert((c, p), Some(d));
                        }
                        Performative::Failure => { holds.insert((c, p), None); }
                        Performative::Agree | Performative::Refuse => {}
                        other => prop_assert!(false, "unexpected {other}"),
                    }
                }
                read[c] = inbox.len();
            }
            for (p, name) in PASSAGES.iter().enumerate() {
                let directions: std::collections::BTreeSet<usize> = (0..CHAIRS).filter_map(|c| holds.get(&(c, p)).copied().flatten()).collect();
                prop_assert!(directions.len() <= 1, "{name} held both ways");
            }
        }
    }
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
    rig.chairs[0].1.lock().unwrap().push(
        AclMessage::new(Performative::Cancel)
            .with_receiver(AgentId::new("watcher"))
            .with_conversation_id(conversation(0, 0)),
    );
    rig.host.step(rig.clock.now());
    assert_eq!(granted(&rig), [true, true, false, false]);
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
fn other_requests_are_not_understood_and_unknown_passages_refused() {
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
    let unknown = WheelchairContent::Request {
        actor: AgentId::new("watcher"),
        action: WheelchairAction::Pass {
            passage: "attic".into(),
            direction: "forward".into(),
        },
    };
    rig.chairs[1].1.lock().unwrap().push(
        unknown.fill(AclMessage::new(Performative::Request).with_receiver(AgentId::new("watcher"))),
    );
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
}
