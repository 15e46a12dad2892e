//! Election and list distribution in simulated time: containers exchange messages through a
//! simulated network that can lose a container or split in two.

use std::collections::BTreeSet;
use std::time::Duration;

use iw_bus::Time;
use iw_bus::transport::PeerAddr;
use iw_container::{
    AgentEntry, Authenticated, Container, ContainerConfig, ContainerId, ContainerMsg,
};

const STEP: Duration = Duration::from_millis(10);

fn addr(i: u64) -> PeerAddr {
    PeerAddr(format!("c{i}"))
}

/// Container `i`'s identity key (the state machine takes signatures as checked).
fn key(i: u64) -> [u8; 32] {
    [i as u8; 32]
}

fn config(id: u64, at: PeerAddr, seeds: Vec<PeerAddr>) -> ContainerConfig {
    ContainerConfig {
        key: key(id),
        ..ContainerConfig::new(ContainerId(id), at, seeds)
    }
}

/// `msg` as it comes out of a session with identity `signer`, with sequence number `seq`.
fn signed(signer: [u8; 32], seq: u64, msg: ContainerMsg) -> Authenticated {
    Authenticated {
        key: signer,
        seq,
        msg,
    }
}

fn agent(name: &str, container: u64) -> AgentEntry {
    AgentEntry {
        name: name.into(),
        public_key: key(container).to_vec(),
        addr: addr(container),
    }
}

struct SimNet {
    nodes: Vec<Option<Container>>,
    /// Partition group of each node: messages cross only within a group.
    group: Vec<u8>,
    now: Time,
    /// Messages that could not be delivered (dead node or other side of a partition).
    lost: u64,
    /// Sequence numbers: one counter for all, so each sender's grow.
    seq: u64,
    /// Frames each node took.
    received: Vec<u64>,
    /// The longest message seen, bytes of JSON.
    longest: usize,
}

impl SimNet {
    /// `n` containers, each greeting all.
    fn new(n: u64) -> Self {
        Self::with_seeds(n, |_| (1..=n).map(addr).collect())
    }

    fn with_seeds(n: u64, seeds: impl Fn(u64) -> Vec<PeerAddr>) -> Self {
        let nodes = (1..=n)
            .map(|i| Some(Container::new(config(i, addr(i), seeds(i)))))
            .collect();
        Self {
            nodes,
            group: vec![0; n as usize],
            now: Time::from_ns(1_000_000_000),
            lost: 0,
            seq: 0,
            received: vec![0; n as usize],
            longest: 0,
        }
    }

    fn node(&mut self, id: u64) -> &mut Container {
        self.nodes[(id - 1) as usize].as_mut().expect("node is up")
    }

    fn index_of(a: &PeerAddr) -> usize {
        a.0[1..].parse::<usize>().unwrap() - 1
    }

    /// Advances time by `d` in steps, delivering every message of a step within that step.
    fn run(&mut self, d: Duration) {
        let end = self.now.plus(d);
        while self.now < end {
            self.now = self.now.plus(STEP);
            let mut queue: Vec<(usize, PeerAddr, ContainerMsg)> = Vec::new();
            for (i, node) in self.nodes.iter_mut().enumerate() {
                if let Some(n) = node {
                    queue.extend(n.on_tick(self.now).into_iter().map(|o| (i, o.to, o.msg)));
                }
            }
            let mut rounds = 0;
            while !queue.is_empty() && rounds < 10 {
                rounds += 1;
                let mut next = Vec::new();
                for (from, to, msg) in queue.drain(..) {
                    let t = Self::index_of(&to);
                    match self.nodes.get_mut(t) {
                        Some(Some(n)) if self.group[t] == self.group[from] => {
                            self.seq += 1;
                            self.received[t] += 1;
                            self.longest = self.longest.max(msg.encode().unwrap().len());
                            let sender = from as u64 + 1;
                            next.extend(
                                n.on_message(
                                    &addr(sender),
                                    signed(key(sender), self.seq, msg),
                                    self.now,
                                )
                                .into_iter()
                                .map(|o| (t, o.to, o.msg)),
                            );
                        }
                        _ => self.lost += 1,
                    }
                }
                queue = next;
            }
        }
    }

    fn leaders(&self) -> BTreeSet<(u64, u64)> {
        self.nodes
            .iter()
            .flatten()
            .map(|n| (n.id().0, n.leader().0))
            .collect()
    }

    fn gal_names(&mut self, id: u64) -> BTreeSet<String> {
        self.node(id)
            .gal()
            .entries()
            .map(|(_, e)| e.name.clone())
            .collect()
    }
}

fn names(list: &[&str]) -> BTreeSet<String> {
    list.iter().map(|s| s.to_string()).collect()
}

#[test]
fn lowest_id_is_elected_and_the_gal_reaches_everyone() {
    let mut net = SimNet::new(3);
    net.node(1).register(agent("a1", 1));
    net.node(2).register(agent("a2", 2));
    net.node(3).register(agent("a3", 3));
    net.run(Duration::from_millis(500));
    assert_eq!(net.leaders(), [(1, 1), (2, 1), (3, 1)].into());
    for id in 1..=3 {
        assert_eq!(
            net.gal_names(id),
            names(&["a1", "a2", "a3"]),
            "container {id}"
        );
    }
    let key = net.node(3).resolve("a2").unwrap().public_key.clone();
    assert_eq!(key, self::key(2), "an agent carries its container's key");
    // A later registration travels follower -> leader -> followers.
    net.node(3).register(agent("late", 3));
    net.run(Duration::from_millis(300));
    assert!(net.gal_names(2).contains("late"));
}

#[test]
fn losing_the_leader_elects_the_next_and_local_agents_keep_resolving() {
    let mut net = SimNet::new(3);
    net.node(2).register(agent("wheel", 2));
    net.node(2).register(agent("joystick", 2));
    net.node(3).register(agent("camera", 3));
    net.run(Duration::from_millis(500));
    net.nodes[0] = None; // the leader dies
    for _ in 0..50 {
        net.run(STEP);
        // Throughout the outage, container 2's own agents resolve and so does 3's (in its GAL).
        assert!(
            net.node(2).resolve("wheel").is_some() && net.node(2).resolve("joystick").is_some()
        );
        assert!(net.node(2).resolve("camera").is_some());
    }
    assert_eq!(net.leaders(), [(2, 2), (3, 2)].into());
    net.node(3).register(agent("after", 3));
    net.run(Duration::from_millis(300));
    assert!(
        net.gal_names(2).contains("after"),
        "the new leader distributes"
    );
}

#[test]
fn a_partition_elects_on_both_sides_and_lists_resync_when_it_heals() {
    let mut net = SimNet::new(4);
    for i in 1..=4 {
        net.node(i).register(agent(&format!("base{i}"), i));
    }
    net.run(Duration::from_millis(500));
    net.group = vec![0, 0, 1, 1]; // {1,2} | {3,4}
    net.run(Duration::from_millis(500));
    assert_eq!(net.leaders(), [(1, 1), (2, 1), (3, 3), (4, 3)].into());
    net.node(2).register(agent("left", 2));
    net.node(4).register(agent("right", 4));
    assert!(net.node(4).deregister("base4"));
    net.run(Duration::from_millis(300));
    assert!(net.gal_names(3).contains("right") && !net.gal_names(3).contains("left"));
    net.group = vec![0; 4];
    net.run(Duration::from_millis(600));
    assert_eq!(net.leaders(), [(1, 1), (2, 1), (3, 1), (4, 1)].into());
    let all = names(&["base1", "base2", "base3", "left", "right"]);
    for id in 1..=4 {
        assert_eq!(net.gal_names(id), all, "container {id}");
    }
}

#[test]
fn a_restarted_container_supersedes_its_old_list() {
    let mut net = SimNet::new(2);
    net.node(2).register(agent("old", 2));
    net.run(Duration::from_millis(500));
    let mut config = config(2, addr(2), vec![addr(1), addr(2)]);
    config.incarnation = 1;
    let mut reborn = Container::new(config);
    reborn.register(agent("new", 2));
    net.nodes[1] = Some(reborn);
    net.run(Duration::from_millis(500));
    assert_eq!(net.gal_names(1), names(&["new"]));
}

#[test]
fn same_inputs_same_history() {
    let history = || {
        let mut net = SimNet::new(3);
        net.node(3).register(agent("x", 3));
        net.run(Duration::from_millis(300));
        net.nodes[0] = None;
        net.run(Duration::from_millis(400));
        (net.leaders(), net.lost, net.gal_names(2))
    };
    assert_eq!(history(), history());
}

#[test]
fn malformed_control_frames_are_refused() {
    let err = ContainerMsg::decode(b"{\"Heartbeat\":42}").unwrap_err();
    assert!(err.to_string().contains("16 bytes"));
    let msg = ContainerMsg::Lal {
        id: ContainerId(1),
        part: iw_container::Part {
            generation: 3,
            agents: vec![agent("a", 1)],
        },
    };
    assert_eq!(ContainerMsg::decode(&msg.encode().unwrap()).unwrap(), msg);
}

/// Issue 20 items 1 and 2 at the state machine: agent lists are taken only under the elected
/// leader's own key and address, a part for a container only under that container's, no
/// generation pins a route, and a second container claiming a live id is told so and refuses to
/// run.
#[test]
fn forged_lists_are_ignored_and_no_generation_pins_a_route() {
    let mut net = SimNet::new(2);
    net.node(1).register(agent("dispatcher", 1));
    net.node(2).register(agent("control", 2));
    net.run(Duration::from_millis(500));
    let now = net.now;
    let attacker = PeerAddr("evil".into());
    let evil = [0xee; 32];
    let pinned = |leader: u64| {
        let mut gal = iw_container::GlobalAgentList::default();
        gal.merge_part(
            ContainerId(leader),
            iw_container::Part {
                generation: u64::MAX,
                agents: vec![AgentEntry {
                    name: "dispatcher".into(),
                    public_key: b"evil".to_vec(),
                    addr: attacker.clone(),
                }],
            },
        );
        gal.merge_part(
            ContainerId(66),
            iw_container::Part {
                generation: u64::MAX,
                agents: vec![agent("evil@x", 66)],
            },
        );
        ContainerMsg::Gal {
            leader: ContainerId(leader),
            versions: gal.versions(),
            gal,
        }
    };
    let seq = u64::MAX;
    // From the attacker's own address: ignored outright.
    assert!(
        net.node(2)
            .on_message(&attacker, signed(evil, seq, pinned(1)), now)
            .is_empty()
    );
    assert_eq!(net.node(2).resolve("dispatcher").unwrap().addr, addr(1));
    assert!(net.node(2).resolve("evil@x").is_none());
    // A LAL for container 2 sent to the leader from elsewhere, or from container 2's address
    // under another key: ignored.
    let lal = ContainerMsg::Lal {
        id: ContainerId(2),
        part: iw_container::Part {
            generation: u64::MAX,
            agents: vec![agent("evil@x", 2)],
        },
    };
    net.node(1)
        .on_message(&attacker, signed(evil, seq, lal.clone()), now);
    net.node(1)
        .on_message(&addr(2), signed(evil, seq, lal), now);
    assert!(net.node(1).resolve("evil@x").is_none());
    // Spoofed from the leader's address (a group-key holder can: UDP sources are not checked,
    // and TCP takes the sender's word for its address), under the attacker's own key: ignored.
    net.node(2)
        .on_message(&addr(1), signed(evil, seq, pinned(1)), now);
    assert_eq!(net.node(2).resolve("dispatcher").unwrap().addr, addr(1));
    assert!(net.node(2).resolve("evil@x").is_none());
    assert_eq!(net.gal_names(2), names(&["dispatcher", "control"]));
}

/// A forged heartbeat for a live container, from its address under another key and with a
/// higher incarnation (what a restart says), neither replaces it nor keeps it alive; a replayed
/// list under the right key is not taken either.
#[test]
fn a_heartbeat_under_another_key_is_a_duplicate_and_a_replayed_list_is_ignored() {
    let mut net = SimNet::new(2);
    net.node(1).register(agent("dispatcher", 1));
    net.node(2).register(agent("control", 2));
    net.run(Duration::from_millis(500));
    let now = net.now;
    let evil = [0xee; 32];
    let claim = ContainerMsg::Heartbeat {
        id: ContainerId(1),
        incarnation: u32::MAX,
        leader: ContainerId(1),
        lal_generation: u64::MAX,
        gal_versions: Default::default(),
    };
    let answers = net
        .node(2)
        .on_message(&addr(1), signed(evil, u64::MAX, claim), now);
    assert!(
        matches!(
            &answers[..],
            [iw_container::Outgoing {
                msg: ContainerMsg::Duplicate {
                    id: ContainerId(1),
                    ..
                },
                ..
            }]
        ),
        "{answers:?}"
    );
    // The real leader's next heartbeat is still taken: the forger did not become container 1.
    net.run(Duration::from_millis(300));
    assert_eq!(net.leaders(), [(1, 1), (2, 1)].into());

    // The leader's list, from the leader, replayed with a sequence number already used.
    let mut stale = iw_container::GlobalAgentList::default();
    stale.merge_part(
        ContainerId(1),
        iw_container::Part {
            generation: 1,
            agents: vec![agent("replayed", 1)],
        },
    );
    let replay = ContainerMsg::Gal {
        leader: ContainerId(1),
        versions: stale.versions(),
        gal: stale,
    };
    net.node(2)
        .on_message(&addr(1), signed(key(1), 1, replay), now);
    assert!(net.node(2).resolve("replayed").is_none());
    assert_eq!(net.gal_names(2), names(&["dispatcher", "control"]));
}

#[test]
fn a_second_container_with_a_live_id_is_refused_and_the_first_is_undisturbed() {
    let mut net = SimNet::new(2);
    net.node(1).register(agent("dispatcher", 1));
    net.run(Duration::from_millis(500));
    let now = net.now;
    let impostor_key = [0x77; 32];
    let mut impostor = Container::new(ContainerConfig {
        key: impostor_key,
        ..ContainerConfig::new(ContainerId(1), PeerAddr("impostor".into()), vec![addr(2)])
    });
    impostor.register(agent("dispatcher", 1));
    let heartbeats = impostor.on_tick(now);
    assert_eq!(heartbeats.len(), 1);
    let answers = net.node(2).on_message(
        &PeerAddr("impostor".into()),
        signed(impostor_key, 1, heartbeats[0].msg.clone()),
        now,
    );
    assert!(
        matches!(&answers[..], [iw_container::Outgoing { to, msg: ContainerMsg::Duplicate { id: ContainerId(1), holder, .. } }] if to.0 == "impostor" && *holder == addr(1)),
        "{answers:?}"
    );
    for a in answers {
        impostor.on_message(&addr(2), signed(key(2), u64::MAX, a.msg), now);
    }
    let refusal = impostor.refusal().expect("the impostor refuses to run");
    assert!(
        refusal.contains("already held") && refusal.contains("c1"),
        "{refusal}"
    );
    assert!(
        impostor
            .on_tick(now.plus(Duration::from_secs(1)))
            .is_empty(),
        "silent once refused"
    );
    net.run(Duration::from_millis(300));
    assert_eq!(net.leaders(), [(1, 1), (2, 1)].into());
    assert_eq!(net.node(2).resolve("dispatcher").unwrap().addr, addr(1));
    // The holder itself, told of the impostor, keeps running.
    let claim = ContainerMsg::Heartbeat {
        id: ContainerId(1),
        incarnation: 7,
        leader: ContainerId(1),
        lal_generation: 7 << 32,
        gal_versions: Default::default(),
    };
    let answers = net.node(1).on_message(
        &PeerAddr("impostor".into()),
        signed(impostor_key, 2, claim),
        now,
    );
    assert!(matches!(
        &answers[..],
        [iw_container::Outgoing {
            msg: ContainerMsg::Duplicate { .. },
            ..
        }]
    ));
    assert!(net.node(1).refusal().is_none());
}

/// The holder of an id itself tells a newcomer with the same id and the same incarnation (both
/// started in the same second) and a lower address: the newcomer refuses (it used to win the
/// tie on its address and run on beside the holder), and the holder, told in turn by a
/// container that ran longer than it, refuses.
#[test]
fn told_by_the_holder_the_younger_refuses_whatever_the_incarnations_and_addresses() {
    let start = Time::from_ns(1_000_000_000);
    let container = |at: &str, k: u8| {
        Container::new(ContainerConfig {
            key: [k; 32],
            incarnation: 1_700_000_000,
            ..ContainerConfig::new(ContainerId(1), PeerAddr(at.into()), vec![])
        })
    };
    let mut holder = container("127.0.0.1:7701", 1);
    holder.on_tick(start);
    let later = start.plus(Duration::from_millis(800));
    let mut newcomer = container("127.0.0.1:40001", 2);
    let hello = newcomer.on_tick(later);
    assert!(hello.is_empty(), "no seeds: it says nothing unasked");
    let claim = ContainerMsg::Heartbeat {
        id: ContainerId(1),
        incarnation: 1_700_000_000,
        leader: ContainerId(1),
        lal_generation: 1_700_000_000 << 32,
        gal_versions: Default::default(),
    };
    let now = later.plus(STEP);
    let told = holder.on_message(
        &PeerAddr("127.0.0.1:40001".into()),
        signed([2; 32], 1, claim.clone()),
        now,
    );
    let [iw_container::Outgoing { msg, .. }] = &told[..] else {
        panic!("{told:?}")
    };
    let answer = newcomer.on_message(
        &PeerAddr("127.0.0.1:7701".into()),
        signed([1; 32], 1, msg.clone()),
        now,
    );
    assert!(answer.is_empty(), "{answer:?}");
    assert!(
        newcomer.refusal().is_some_and(|r| r.contains("refuses")),
        "the newcomer runs on"
    );
    assert!(holder.refusal().is_none());

    // Roles swapped: a container that ran a lease longer than the one telling it answers in
    // kind, and the teller refuses.
    let mut elder = container("127.0.0.1:40001", 2);
    elder.on_tick(start);
    let mut young = container("127.0.0.1:7701", 1);
    let then = start.plus(Duration::from_secs(5));
    young.on_tick(then);
    let told = young.on_message(
        &PeerAddr("127.0.0.1:40001".into()),
        signed([2; 32], 1, claim),
        then,
    );
    let [iw_container::Outgoing { msg, .. }] = &told[..] else {
        panic!("{told:?}")
    };
    let answer = elder.on_message(
        &PeerAddr("127.0.0.1:7701".into()),
        signed([1; 32], 1, msg.clone()),
        then,
    );
    assert!(elder.refusal().is_none(), "the elder runs on");
    let [iw_container::Outgoing { msg, .. }] = &answer[..] else {
        panic!("{answer:?}")
    };
    young.on_message(
        &PeerAddr("127.0.0.1:40001".into()),
        signed([2; 32], 2, msg.clone()),
        then,
    );
    assert!(young.refusal().is_some(), "the younger one refuses");
}

/// Issue 16 item 8 at the state machine: 100 chairs greeting the services only (as deployed),
/// five agents each. Every list reaches everyone although the whole list would not fit one
/// datagram; once the lists agree, heartbeats slow to a fifth of the lease, and the services
/// hear each chair, and each chair the services only: linear in the chairs.
#[test]
fn a_hundred_chairs_converge_in_frames_that_fit_a_datagram_and_idle_linearly() {
    const CHAIRS: u64 = 100;
    let mut net = SimNet::with_seeds(CHAIRS + 1, |i| if i == 1 { vec![] } else { vec![addr(1)] });
    for i in 1..=CHAIRS + 1 {
        for role in ["cognitive", "control", "perception", "interface", "body"] {
            net.node(i).register(AgentEntry {
                name: format!("{role}@chair-{i:03}"),
                public_key: key(i).to_vec(),
                addr: PeerAddr(format!("127.0.0.1:{}", 40000 + i)),
            });
        }
    }
    net.run(Duration::from_secs(3));
    let everyone = net.node(1).gal().clone();
    assert_eq!(everyone.len(), 5 * (CHAIRS as usize + 1));
    for i in 2..=CHAIRS + 1 {
        assert_eq!(net.node(i).gal(), &everyone, "container {i}");
        assert_eq!(net.node(i).leader(), ContainerId(1));
    }
    let whole = ContainerMsg::Gal {
        leader: ContainerId(1),
        versions: everyone.versions(),
        gal: everyone,
    };
    assert!(
        whole.encode().unwrap().len() > 65_507,
        "the whole list would not fit"
    );
    assert!(
        net.longest <= 40 * 1024,
        "longest frame {} bytes",
        net.longest
    );

    // Idle: over 10 s, the services hear every chair 5 times a second (lease 250 ms, heartbeat
    // every 50 ms), and a chair hears the services alone at that rate.
    let before = net.received.clone();
    net.run(Duration::from_secs(10));
    let heard: Vec<u64> = net
        .received
        .iter()
        .zip(&before)
        .map(|(a, b)| a - b)
        .collect();
    let per_second = |n: u64| n as f64 / 10.0;
    let idle_rate = 1000.0 / config(1, addr(1), vec![]).idle_heartbeat().as_millis() as f64;
    assert!(
        per_second(heard[0]) <= 1.1 * idle_rate * CHAIRS as f64,
        "the services took {} frames/s",
        per_second(heard[0])
    );
    for (i, n) in heard.iter().enumerate().skip(1) {
        assert!(
            per_second(*n) <= 1.1 * idle_rate,
            "chair {} took {} frames/s",
            i + 1,
            per_second(*n)
        );
    }
    assert_eq!(net.lost, 0);
}

#[test]
fn a_tick_before_next_due_does_nothing_and_one_at_it_does() {
    let mut net = SimNet::new(3);
    net.run(Duration::from_secs(2));
    let now = net.now;
    let settings = config(1, addr(1), Vec::new());
    let lease = settings.lease;
    let node = net.node(1);
    let due = node.next_due();
    assert!(due > now, "something overdue after a tick: {due} at {now}");
    // no later than the next heartbeat, which goes at least every fifth of the lease
    assert!(due <= now.plus(settings.idle_heartbeat()));
    let revision = node.revision();
    let just_before = Time::from_ns(due.as_ns() - 1);
    assert!(node.on_tick(just_before).is_empty());
    assert_eq!(node.revision(), revision);
    assert!(!node.on_tick(due).is_empty(), "the heartbeat due then");
    // with the peers silent from now on, their leases come due no later than a lease from now
    assert!(node.next_due() <= now.plus(lease));
}
