//! The watcher alone on an in-process bus with a mock clock, driven by chairs sending real ACL.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, AgentHost, Context};
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, MockController, Stack, Time};
use iw_watcher::{WatcherAgent, WatcherConfig, pass_content};
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
    let bus = Bus::start(Stack::new(), Arc::new(network.endpoint("c1").unwrap()), clock, BusConfig::default()).unwrap();
    let mut host = AgentHost::new(Arc::new(bus));
    let config = WatcherConfig { passages: PASSAGES.iter().map(|p| p.to_string()).collect(), lease: Duration::from_secs(2), period: Duration::from_millis(50) };
    host.add(AgentId::new("watcher"), Box::new(WatcherAgent::new(config).unwrap())).unwrap();
    let chairs = (0..CHAIRS)
        .map(|i| {
            let (inbox, outbox): (Mailbag, Mailbag) = (Arc::default(), Arc::default());
            host.add(AgentId::new(format!("chair{i}")), Box::new(Chair { inbox: Arc::clone(&inbox), outbox: Arc::clone(&outbox) })).unwrap();
            (inbox, outbox)
        })
        .collect();
    Rig { host, clock: controller, chairs }
}

fn conversation(chair: usize, passage: usize) -> String {
    format!("chair{chair}-{}", PASSAGES[passage])
}

#[derive(Debug, Clone)]
enum Op {
    Request(usize, usize),
    Cancel(usize, usize),
    Wait(u64),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0..CHAIRS, 0..PASSAGES.len()).prop_map(|(c, p)| Op::Request(c, p)),
        (0..CHAIRS, 0..PASSAGES.len()).prop_map(|(c, p)| Op::Cancel(c, p)),
        (10u64..1500).prop_map(Op::Wait),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn no_passage_is_ever_granted_to_two_chairs(ops in proptest::collection::vec(op(), 1..60)) {
        let mut rig = rig();
        // (chair, passage) -> holds, as the chairs see it; messages read so far per chair.
        let mut holds: BTreeMap<(usize, usize), bool> = BTreeMap::new();
        let mut read = [0usize; CHAIRS];
        for op in ops {
            match op {
                Op::Request(c, p) => rig.chairs[c].1.lock().unwrap().push(
                    AclMessage::new(Performative::Request).with_receiver(AgentId::new("watcher")).with_protocol("fipa-request")
                        .with_conversation_id(conversation(c, p)).with_content(pass_content("watcher", PASSAGES[p], "east")),
                ),
                Op::Cancel(c, p) => {
                    holds.insert((c, p), false);
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
                        Performative::Inform => { holds.insert((c, p), true); }
                        Performative::Failure => { holds.insert((c, p), false); }
                        Performative::Agree | Performative::Refuse => {}
                        other => prop_assert!(false, "unexpected {other}"),
                    }
                }
                read[c] = inbox.len();
            }
            for p in 0..PASSAGES.len() {
                let holders = (0..CHAIRS).filter(|c| holds.get(&(*c, p)).copied().unwrap_or(false)).count();
                prop_assert!(holders <= 1, "{} held by {holders} chairs", PASSAGES[p]);
            }
        }
    }
}

#[test]
fn grants_are_fifo_and_a_stuck_holder_loses_its_lease() {
    let mut rig = rig();
    for c in 0..3 {
        rig.chairs[c].1.lock().unwrap().push(
            AclMessage::new(Performative::Request).with_receiver(AgentId::new("watcher")).with_conversation_id(conversation(c, 0)).with_content(pass_content("watcher", "door-a", "west")),
        );
        rig.host.step(rig.clock.now());
        rig.clock.advance(Duration::from_millis(10));
    }
    let granted = |rig: &Rig| -> Vec<bool> { rig.chairs.iter().map(|(i, _)| i.lock().unwrap().iter().any(|m| m.performative == Performative::Inform)).collect() };
    assert_eq!(granted(&rig), [true, false, false, false]);
    let grant = rig.chairs[0].0.lock().unwrap().iter().find(|m| m.performative == Performative::Inform).unwrap().clone();
    let content = iw_sl::parse(grant.content_text().unwrap(), iw_sl::Level::Sl0).unwrap();
    assert!(content.to_string().starts_with("((done (action"), "{content}");
    // chair0 releases: chair1 is next, not chair2.
    rig.chairs[0].1.lock().unwrap().push(AclMessage::new(Performative::Cancel).with_receiver(AgentId::new("watcher")).with_conversation_id(conversation(0, 0)));
    rig.host.step(rig.clock.now());
    assert_eq!(granted(&rig), [true, true, false, false]);
    // chair1 never releases: after the 2 s lease it gets FAILURE and chair2 passes.
    for _ in 0..50 {
        rig.clock.advance(Duration::from_millis(50));
        rig.host.step(rig.clock.now());
    }
    assert!(rig.chairs[1].0.lock().unwrap().iter().any(|m| m.performative == Performative::Failure));
    assert_eq!(granted(&rig), [true, true, true, false]);
}
