//! Identities pinned in advance ([`Roster`]) and list entries checked against their container:
//! what a holder of the group key can no longer do, at the state machine, in simulated time.
//! Each attack is also run without a roster where that mode still lets it through, so the
//! difference is the roster's.

use std::sync::Arc;
use std::time::Duration;

use iw_bus::transport::{FrameTransport, PeerAddr};
use iw_bus::{Reason, Time};
use iw_container::{
    AgentEntry, Authenticated, Container, ContainerConfig, ContainerId, ContainerMsg,
    GlobalAgentList, Outgoing, Part, Pin, Roster,
};

const STEP: Duration = Duration::from_millis(10);

fn addr(i: u64) -> PeerAddr {
    PeerAddr(format!("c{i}"))
}

fn key(i: u64) -> [u8; 32] {
    [i as u8; 32]
}

const EVIL: [u8; 32] = [0xee; 32];

/// Containers 1..=4 pinned as `c1`..`c4` under `key(i)`.
fn roster() -> Arc<Roster> {
    let pins = (1..=4).map(|i| {
        (
            ContainerId(i),
            Pin {
                name: format!("c{i}"),
                key: key(i),
            },
        )
    });
    Arc::new(Roster::new("test roster", pins).unwrap())
}

/// Agent `role@c{i}` of container `i`, carrying its key.
fn agent(role: &str, i: u64) -> AgentEntry {
    AgentEntry {
        name: format!("{role}@c{i}"),
        public_key: key(i).to_vec(),
        addr: addr(i),
    }
}

fn container(i: u64, roster: Option<Arc<Roster>>, seeds: &[u64]) -> Container {
    let mut c = Container::new(ContainerConfig {
        key: key(i),
        roster,
        ..ContainerConfig::new(
            ContainerId(i),
            addr(i),
            seeds.iter().map(|s| addr(*s)).collect(),
        )
    });
    c.register(agent("main", i));
    c
}

/// Containers 1 and 2, each greeting the other, run until their lists agree.
struct Net {
    nodes: Vec<Container>,
    now: Time,
    seq: u64,
}

impl Net {
    fn new(roster: Option<Arc<Roster>>) -> Net {
        let mut net = Net {
            nodes: vec![
                container(1, roster.clone(), &[2]),
                container(2, roster, &[1]),
            ],
            now: Time::from_ns(1_000_000_000),
            seq: 0,
        };
        net.run(Duration::from_millis(500));
        assert_eq!(net.node(2).leader(), ContainerId(1));
        assert!(net.node(2).resolve("main@c1").is_some());
        net
    }

    fn node(&mut self, i: u64) -> &mut Container {
        &mut self.nodes[(i - 1) as usize]
    }

    fn run(&mut self, d: Duration) {
        let end = self.now.plus(d);
        while self.now < end {
            self.now = self.now.plus(STEP);
            let mut queue: Vec<(u64, Outgoing)> = Vec::new();
            for (i, n) in self.nodes.iter_mut().enumerate() {
                queue.extend(n.on_tick(self.now).into_iter().map(|o| (i as u64 + 1, o)));
            }
            for _ in 0..10 {
                let mut next = Vec::new();
                for (from, o) in queue.drain(..) {
                    let Ok(to) = o.to.0[1..].parse::<u64>() else {
                        continue; // an address outside the net
                    };
                    if let Some(n) = self.nodes.get_mut((to - 1) as usize) {
                        self.seq += 1;
                        let signed = Authenticated {
                            key: key(from),
                            seq: self.seq,
                            msg: o.msg,
                        };
                        next.extend(
                            n.on_message(&addr(from), signed, self.now)
                                .into_iter()
                                .map(|o| (to, o)),
                        );
                    }
                }
                queue = next;
            }
        }
    }

    /// Container `to` hears `msg` from `from` under identity `signer`.
    fn hear(
        &mut self,
        to: u64,
        from: &PeerAddr,
        signer: [u8; 32],
        msg: ContainerMsg,
    ) -> Vec<Outgoing> {
        self.seq += 1;
        let (now, seq) = (self.now, self.seq);
        self.node(to).on_message(
            from,
            Authenticated {
                key: signer,
                seq,
                msg,
            },
            now,
        )
    }
}

/// A group-key holder's take-over under an id nobody holds: her heartbeat, then her list as
/// the leader, listing container 1's agent at her address and an agent of her own.
fn claim(id: u64) -> [ContainerMsg; 2] {
    let mut gal = GlobalAgentList::default();
    let evil = |name: &str| AgentEntry {
        name: name.into(),
        public_key: EVIL.to_vec(),
        addr: PeerAddr("evil".into()),
    };
    gal.merge_part(
        ContainerId(id),
        Part {
            generation: 1,
            agents: vec![evil("main@c1"), evil("spy@evil")],
        },
    );
    [
        ContainerMsg::Heartbeat {
            id: ContainerId(id),
            incarnation: 1,
            leader: ContainerId(id),
            lal_generation: 1,
            gal_versions: Default::default(),
        },
        ContainerMsg::Gal {
            leader: ContainerId(id),
            versions: gal.versions(),
            gal,
        },
    ]
}

fn hijacked(net: &mut Net) -> bool {
    net.node(2).leader() != ContainerId(1)
        || net.node(2).resolve("spy@evil").is_some()
        || net.node(2).resolve("main@c1").map(|e| e.addr.0.as_str()) != Some("c1")
}

#[test]
fn a_key_holder_claiming_a_free_low_id_leads_only_without_a_roster() {
    let evil = PeerAddr("evil".into());
    let mut weak = Net::new(None);
    for msg in claim(0) {
        weak.hear(2, &evil, EVIL, msg);
    }
    assert!(hijacked(&mut weak), "the weaker mode's known limit");

    let mut net = Net::new(Some(roster()));
    // id 0: not in the roster; id 3: in it, not running, pinned to another key.
    for id in [0, 3] {
        for msg in claim(id) {
            net.hear(2, &evil, EVIL, msg);
        }
    }
    assert!(!hijacked(&mut net), "{:?}", net.node(2).gal());
    assert!(!net.node(2).live_peers().contains(&ContainerId(0)));
    let counters = net.node(2).counters().clone();
    assert!(counters.get(Reason::UnknownPeer) >= 2, "{counters}");
    assert!(counters.get(Reason::Mismatch) >= 2, "{counters}");
    net.run(Duration::from_millis(300));
    assert!(!hijacked(&mut net));
}

#[test]
fn a_forged_duplicate_stops_a_container_only_without_a_roster() {
    let forged = ContainerMsg::Duplicate {
        id: ContainerId(2),
        holder: PeerAddr("evil".into()),
        holder_incarnation: 0,
        holder_uptime_ms: u64::MAX,
    };
    let evil = PeerAddr("evil".into());
    let mut weak = Net::new(None);
    weak.hear(2, &evil, EVIL, forged.clone());
    assert!(
        weak.node(2).refusal().is_some(),
        "the weaker mode's known limit"
    );

    let mut net = Net::new(Some(roster()));
    // From the forger, and as if from container 1 (a third party) under its own pinned key.
    let probes = net.hear(2, &evil, EVIL, forged.clone());
    net.hear(2, &addr(1), key(1), forged.clone());
    assert!(net.node(2).refusal().is_none());
    assert!(
        matches!(&probes[..], [Outgoing { to, msg: ContainerMsg::Heartbeat { id: ContainerId(2), .. } }] if to.0 == "evil"),
        "the named holder is greeted, once per heartbeat period: {probes:?}"
    );
    assert!(net.node(2).counters().get(Reason::Mismatch) >= 2);
    net.run(Duration::from_millis(300));
    assert!(net.node(2).refusal().is_none());
    assert_eq!(net.node(1).live_peers(), [ContainerId(2)].into());
}

/// A copy of container 2's own identity started elsewhere is still refused under a roster: told
/// by a third party it is not believed, but it greets the named holder, which answers itself
/// under the pinned key.
#[test]
fn a_second_holder_of_the_pinned_identity_is_refused_through_the_holder() {
    let mut net = Net::new(Some(roster()));
    let now = net.now;
    let mut copy = Container::new(ContainerConfig {
        key: key(2),
        roster: Some(roster()),
        ..ContainerConfig::new(ContainerId(2), PeerAddr("copy".into()), vec![addr(1)])
    });
    let hello = copy.on_tick(now);
    let [Outgoing { msg, .. }] = &hello[..] else {
        panic!("{hello:?}")
    };
    let told = net.hear(1, &PeerAddr("copy".into()), key(2), msg.clone());
    let [Outgoing { msg: duplicate, .. }] = &told[..] else {
        panic!("{told:?}")
    };
    let later = now.plus(STEP);
    let probe = copy.on_message(
        &addr(1),
        Authenticated {
            key: key(1),
            seq: 1,
            msg: duplicate.clone(),
        },
        later,
    );
    assert!(
        copy.refusal().is_none(),
        "a third party's word is not enough"
    );
    let [Outgoing { to, msg: probe }] = &probe[..] else {
        panic!("{probe:?}")
    };
    assert_eq!(*to, addr(2));
    let answer = net.hear(2, &PeerAddr("copy".into()), key(2), probe.clone());
    let [Outgoing { msg: answer, .. }] = &answer[..] else {
        panic!("{answer:?}")
    };
    copy.on_message(
        &addr(2),
        Authenticated {
            key: key(2),
            seq: 2,
            msg: answer.clone(),
        },
        later,
    );
    let refusal = copy.refusal().expect("refused by the holder's own word");
    assert!(refusal.contains("already held"), "{refusal}");
    assert!(net.node(2).refusal().is_none());
}

#[test]
fn a_list_carrying_another_containers_agents_is_refused() {
    for pinned in [false, true] {
        let mut net = Net::new(pinned.then(roster));
        let before = net.node(1).counters().get(Reason::Mismatch);
        let lal = |agents: Vec<AgentEntry>| ContainerMsg::Lal {
            id: ContainerId(2),
            part: Part {
                generation: 5,
                agents,
            },
        };
        // Container 2, under its own key, lists an agent under container 1's key.
        let mut foreign_key = agent("main", 1);
        foreign_key.name = "other@c2".into();
        net.hear(
            1,
            &addr(2),
            key(2),
            lal(vec![agent("main", 2), foreign_key]),
        );
        assert!(net.node(1).resolve("other@c2").is_none(), "pinned {pinned}");
        // Container 2 names container 1's agent, under its own key.
        let mut foreign_name = agent("main", 2);
        foreign_name.name = "main@c1".into();
        net.hear(
            1,
            &addr(2),
            key(2),
            lal(vec![agent("main", 2), foreign_name]),
        );
        let owner = net.node(1).gal().lookup("main@c1").map(|(id, _)| id);
        let counted = net.node(1).counters().get(Reason::Mismatch) - before;
        if pinned {
            assert_eq!(owner, Some(ContainerId(1)));
            assert_eq!(
                net.gal_names_of(1, 2),
                vec!["main@c2".to_string()],
                "the whole part refused"
            );
            assert_eq!(counted, 2);
        } else {
            // Without a roster names are not bound to containers: only the key is checked.
            assert_eq!(counted, 1);
        }
    }
}

#[test]
fn a_follower_drops_the_parts_of_the_leaders_list_that_carry_foreign_agents() {
    let mut net = Net::new(Some(roster()));
    let mut gal = net.node(1).gal().clone();
    // A part for container 3 (not live) naming container 2's agent, one for an unlisted id,
    // and a sound one for container 4.
    gal.merge_part(
        ContainerId(3),
        Part {
            generation: 1,
            agents: vec![AgentEntry {
                name: "main@c2".into(),
                ..agent("main", 3)
            }],
        },
    );
    gal.merge_part(
        ContainerId(9),
        Part {
            generation: 1,
            agents: vec![agent("x", 9)],
        },
    );
    gal.merge_part(
        ContainerId(4),
        Part {
            generation: 1,
            agents: vec![agent("fine", 4)],
        },
    );
    let msg = ContainerMsg::Gal {
        leader: ContainerId(1),
        versions: gal.versions(),
        gal: gal.clone(),
    };
    net.hear(2, &addr(1), key(1), msg);
    assert!(
        net.node(2).resolve("fine@c4").is_some(),
        "a sound part is kept"
    );
    assert!(
        net.gal_names_of(2, 3).is_empty(),
        "the foreign part is dropped"
    );
    assert!(net.node(2).resolve("x@c9").is_none());
    assert_eq!(net.node(2).counters().get(Reason::UnknownPeer), 1);
    assert!(
        net.node(2).resolve("main@c1").is_some(),
        "the leader's own part is kept"
    );
}

impl Net {
    fn gal_names_of(&mut self, at: u64, of: u64) -> Vec<String> {
        self.node(at)
            .gal()
            .entries()
            .filter(|(id, _)| id.0 == of)
            .map(|(_, e)| e.name.clone())
            .collect()
    }
}

#[test]
fn a_container_whose_key_is_not_pinned_refuses_to_start() {
    let transport = iw_transport_net::UdpTransport::bind("127.0.0.1:0").unwrap();
    let config = ContainerConfig {
        roster: Some(roster()),
        ..ContainerConfig::new(ContainerId(2), transport.local_addr().clone(), vec![])
    };
    let identity = Arc::new(iw_layer_security::Identity::generate().unwrap());
    let err = iw_container::ContainerNode::start(
        Container::new(config),
        identity,
        Arc::new(transport),
        iw_bus::Clock::system(),
        STEP,
    )
    .expect_err("refused")
    .to_string();
    assert!(
        err.contains("test roster")
            && err.contains("container id 2")
            && err.contains("identity key"),
        "{err}"
    );
}
