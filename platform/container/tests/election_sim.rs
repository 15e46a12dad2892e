//! Election and list distribution in simulated time: containers exchange messages through a
//! simulated network that can lose a container or split in two.

use std::collections::BTreeSet;
use std::time::Duration;

use iw_bus::Time;
use iw_bus::transport::PeerAddr;
use iw_container::{AgentEntry, Container, ContainerConfig, ContainerId, ContainerMsg};

const STEP: Duration = Duration::from_millis(10);

fn addr(i: u64) -> PeerAddr {
    PeerAddr(format!("c{i}"))
}

fn agent(name: &str, container: u64) -> AgentEntry {
    AgentEntry {
        name: name.into(),
        public_key: name.as_bytes().to_vec(),
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
}

impl SimNet {
    fn new(n: u64) -> Self {
        let nodes = (1..=n)
            .map(|i| {
                let seeds = (1..=n).map(addr).collect();
                Some(Container::new(ContainerConfig::new(
                    ContainerId(i),
                    addr(i),
                    seeds,
                )))
            })
            .collect();
        Self {
            nodes,
            group: vec![0; n as usize],
            now: Time::from_ns(1_000_000_000),
            lost: 0,
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
                            next.extend(
                                n.on_message(&addr(from as u64 + 1), msg, self.now)
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
    assert_eq!(key, b"a2");
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
    let mut config = ContainerConfig::new(ContainerId(2), addr(2), vec![addr(1), addr(2)]);
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

/// Issue 20 items 1 and 2 at the state machine: agent lists are taken only from the elected
/// leader's own address, a part for a container only from that container, no generation pins a
/// route, and a second container claiming a live id is told so and refuses to run.
#[test]
fn forged_lists_are_ignored_and_no_generation_pins_a_route() {
    let mut net = SimNet::new(2);
    net.node(1).register(agent("dispatcher", 1));
    net.node(2).register(agent("control", 2));
    net.run(Duration::from_millis(500));
    let now = net.now;
    let attacker = PeerAddr("evil".into());
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
            gal,
        }
    };
    // From the attacker's own address: ignored outright.
    assert!(net.node(2).on_message(&attacker, pinned(1), now).is_empty());
    assert_eq!(net.node(2).resolve("dispatcher").unwrap().addr, addr(1));
    assert!(net.node(2).resolve("evil@x").is_none());
    // A LAL for container 2 sent to the leader from elsewhere: ignored.
    let lal = ContainerMsg::Lal {
        id: ContainerId(2),
        part: iw_container::Part {
            generation: u64::MAX,
            agents: vec![agent("evil@x", 2)],
        },
    };
    net.node(1).on_message(&attacker, lal, now);
    assert!(net.node(1).resolve("evil@x").is_none());
    // Spoofed from the leader's address (possible without a control key): taken, but the
    // leader's next list replaces it, however high its generation.
    net.node(2).on_message(&addr(1), pinned(1), now);
    assert_eq!(net.node(2).resolve("dispatcher").unwrap().addr, attacker);
    net.run(Duration::from_millis(300));
    assert_eq!(net.node(2).resolve("dispatcher").unwrap().addr, addr(1));
    assert!(net.node(2).resolve("evil@x").is_none());
    assert_eq!(net.gal_names(2), names(&["dispatcher", "control"]));
}

#[test]
fn a_second_container_with_a_live_id_is_refused_and_the_first_is_undisturbed() {
    let mut net = SimNet::new(2);
    net.node(1).register(agent("dispatcher", 1));
    net.run(Duration::from_millis(500));
    let now = net.now;
    let mut impostor = Container::new(ContainerConfig::new(
        ContainerId(1),
        PeerAddr("impostor".into()),
        vec![addr(2)],
    ));
    impostor.register(agent("dispatcher", 1));
    let heartbeats = impostor.on_tick(now);
    assert_eq!(heartbeats.len(), 1);
    let answers =
        net.node(2)
            .on_message(&PeerAddr("impostor".into()), heartbeats[0].msg.clone(), now);
    assert!(
        matches!(&answers[..], [iw_container::Outgoing { to, msg: ContainerMsg::Duplicate { id: ContainerId(1), holder, .. } }] if to.0 == "impostor" && *holder == addr(1)),
        "{answers:?}"
    );
    for a in answers {
        impostor.on_message(&addr(2), a.msg, now);
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
    let answers = net
        .node(1)
        .on_message(&PeerAddr("impostor".into()), claim, now);
    assert!(matches!(
        &answers[..],
        [iw_container::Outgoing {
            msg: ContainerMsg::Duplicate { .. },
            ..
        }]
    ));
    assert!(net.node(1).refusal().is_none());
}
