//! The EN 50159 threat table, tested: every threat is injected and the defence is shown acting.
//!
//! | threat        | defence (layer)                                        | tests (name contains the threat)          |
//! |---------------|--------------------------------------------------------|-------------------------------------------|
//! | repetition    | message-id window (comm), sequence numbers (temporal)  | `repetition_*`, `udp_system_*`            |
//! | deletion      | acknowledgement + retransmission (comm)                | `deletion_*`, `udp_system_*`              |
//! | insertion     | AEAD sealing (security), registered senders (parser)   | `insertion_*`, `udp_system_*`             |
//! | resequencing  | sequence numbers (temporal)                            | `resequencing_*`, `udp_system_*`          |
//! | corruption    | AEAD tag over header and payload (security)            | `corruption_*`, `udp_system_*`            |
//! | delay         | timestamps, max age, reply-by (temporal)               | `delay_*`, `udp_system_*`                 |
//! | masquerade    | signed key agreement (security), sender match (parser) | `masquerade_*`, `udp_system_*`            |
//!
//! Unit level: two stacks joined by seeded fault-injecting in-process transports, in simulated
//! time ([`iw_tests::Link`]). System level: this process (agent `a`) and the `iw-peer` process
//! (agent `b`) on real UDP sockets through the seeded impairment proxy of `iw-transport-net`.
//! Every test prints the rejection counters.

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use hex::FromHex;
use iw_bus::{Bus, BusConfig, Clock, Envelope, FrameCodec, Impairments, Reason, Time};
use iw_stack::{LayerSet, Ordering, Platform, StackConfig};
use iw_tests::peer::Report;
use iw_tests::{Link, Side, acl, number_of};
use iw_transport_net::{ImpairConfig, ImpairProxy, UdpTransport};

const N: u64 = 300;

fn all_layers() -> StackConfig {
    StackConfig::default()
}

fn no_faults() -> Impairments {
    Impairments::default()
}

/// Sends `0..n` from `a`, a few per simulated millisecond, then runs until quiet.
fn send_all(link: &mut Link, n: u64) {
    for i in 0..n {
        link.send(Side::A, i);
        if i % 10 == 9 {
            link.step();
            link.time.advance(Duration::from_millis(1));
        }
    }
    let took = link.run(Duration::from_secs(600));
    println!("simulated time to quiescence: {took:?}");
}

/// Asserts `b` got exactly `0..n`, each once and byte for byte as sent.
fn assert_exactly_once(link: &Link, n: u64) {
    for env in &link.b.delivered {
        let k = number_of(&env.payload).expect("a numbered message");
        assert_eq!(env.payload, acl("a", "b", k), "altered message delivered");
        assert_eq!(env.header.sender, "a");
    }
    let mut got = link.numbers(Side::B);
    assert_eq!(
        got.len() as u64,
        n,
        "lost or duplicated: {} delivered",
        got.len()
    );
    got.sort_unstable();
    assert_eq!(got, (0..n).collect::<Vec<_>>());
}

fn report(name: &str, link: &Link) {
    println!("[{name}] faults a->b {:?}", link.a.transport.stats());
    println!("[{name}] faults b->a {:?}", link.b.transport.stats());
    println!("[{name}] rejections: {}", link.counters());
}

/// A message from `a` sealed after the key agreement, ready to be replayed, delayed or altered.
fn warmed_up(config: &StackConfig) -> Link {
    let mut link = Link::new(config, no_faults(), no_faults(), 1);
    link.send(Side::A, 0);
    link.run(Duration::from_secs(1));
    assert_eq!(link.numbers(Side::B), vec![0]);
    link
}

fn sealed(link: &mut Link, n: u64, at: Time) -> Vec<u8> {
    let id = link.fresh_id(Side::A);
    link.seal(Side::A, Envelope::new(id, "a", "b", acl("a", "b", n)), at)
        .expect("passes a's stack")
}

// ---- repetition ------------------------------------------------------------------------------

#[test]
fn repetition_duplicated_and_replayed_frames_delivered_once() {
    let faults = Impairments {
        duplicate: 0.3,
        replay: 0.2,
        ..no_faults()
    };
    let mut link = Link::new(&all_layers(), faults, faults, 11);
    send_all(&mut link, N);
    report("repetition", &link);
    assert_exactly_once(&link, N);
    assert!(link.counters().get(Reason::Duplicate) > 0);
}

#[test]
fn repetition_replay_after_the_id_window_rejected_by_sequence_number() {
    let mut cfg = all_layers();
    cfg.comm.dedup_window = 8;
    let mut link = warmed_up(&cfg);
    let now = link.clock.now();
    let frame = sealed(&mut link, 1, now);
    link.inject(Side::B, &frame);
    link.run(Duration::from_secs(1));
    send_all(&mut link, 20); // pushes id of `frame` out of the 8-id window
    link.inject(Side::B, &frame);
    link.run(Duration::from_secs(1));
    report("repetition-late", &link);
    assert_eq!(
        link.numbers(Side::B).iter().filter(|n| **n == 1).count(),
        2,
        "message 1 from send_all and the original, once each"
    );
    assert_eq!(link.counters().get(Reason::ReplayedSequence), 1);
}

// ---- deletion --------------------------------------------------------------------------------

#[test]
fn deletion_20pct_loss_10pct_duplication_and_reordering_lose_nothing() {
    let faults = Impairments {
        drop: 0.2,
        duplicate: 0.1,
        reorder: 0.1,
        ..no_faults()
    };
    let mut link = Link::new(&all_layers(), faults, faults, 7);
    send_all(&mut link, N);
    report("deletion", &link);
    assert_exactly_once(&link, N);
    assert!(link.a.transport.stats().dropped > 0 && link.b.transport.stats().dropped > 0);
    assert_eq!(link.counters().get(Reason::Undeliverable), 0);
}

#[test]
fn deletion_on_a_dead_link_is_detected_not_silent() {
    let mut cfg = all_layers();
    cfg.comm.max_attempts = 5;
    let mut link = warmed_up(&cfg);
    link.a.transport = iw_bus::FaultyTransport::new(
        iw_bus::InProcNetwork::new()
            .endpoint("a")
            .expect("fresh network"),
        Impairments {
            drop: 1.0,
            ..no_faults()
        },
        3,
    );
    link.send(Side::A, 1);
    link.run(Duration::from_secs(60));
    report("deletion-dead", &link);
    assert_eq!(link.numbers(Side::B), vec![0]);
    assert_eq!(link.counters().get(Reason::Undeliverable), 1);
}

// ---- insertion -------------------------------------------------------------------------------

#[test]
fn insertion_random_and_plaintext_frames_never_delivered() {
    let faults = Impairments {
        inject: 0.3,
        ..no_faults()
    };
    let mut link = Link::new(&all_layers(), faults, faults, 5);
    send_all(&mut link, N);
    // A well-formed but unsealed frame claiming to come from `a`.
    let mut plain = Envelope::new(iw_bus::MsgId(u64::MAX), "a", "b", acl("a", "b", 999));
    plain.header.timestamp = link.clock.now();
    link.inject(
        Side::B,
        &FrameCodec::new().encode_to_vec(&plain).expect("encodable"),
    );
    link.run(Duration::from_secs(1));
    report("insertion", &link);
    assert_exactly_once(&link, N);
    let c = link.counters();
    assert!(c.get(Reason::BadFrame) > 0, "random frames");
    assert_eq!(c.get(Reason::NotSealed), 1, "the plaintext frame");
}

#[test]
fn insertion_by_unregistered_sender_gets_nothing_through() {
    // With every layer: an outsider has no key in the directory.
    let mut link = Link::new(&all_layers(), no_faults(), no_faults(), 2);
    link.add_rogue("x", &all_layers(), false);
    let id = link.fresh_id(Side::Rogue);
    let now = link.clock.now();
    link.send_envelope(
        Side::Rogue,
        Envelope::new(id, "x", "b", acl("x", "b", 1)),
        now,
    );
    link.run(Duration::from_secs(5));
    report("insertion-unregistered", &link);
    assert!(link.b.delivered.is_empty());
    assert!(link.counters().get(Reason::UnknownPeer) > 0);

    // Without the security layer, the parser alone refuses unregistered senders.
    let open: LayerSet = "parser,temporal,comm".parse().expect("layer list");
    let cfg = StackConfig::with_layers(open);
    let mut link = Link::new(&cfg, no_faults(), no_faults(), 2);
    link.add_rogue(
        "x",
        &StackConfig::with_layers("temporal,comm".parse().expect("layer list")),
        false,
    );
    let id = link.fresh_id(Side::Rogue);
    let now = link.clock.now();
    link.send_envelope(
        Side::Rogue,
        Envelope::new(id, "x", "b", acl("x", "b", 1)),
        now,
    );
    link.run(Duration::from_secs(5));
    report("insertion-parser", &link);
    assert!(link.b.delivered.is_empty());
    assert_eq!(link.counters().get(Reason::Unregistered), 1);
}

// ---- resequencing ----------------------------------------------------------------------------

#[test]
fn resequencing_reordered_frames_detected_and_each_delivered_once() {
    let faults = Impairments {
        reorder: 0.4,
        ..no_faults()
    };
    let mut link = Link::new(&all_layers(), faults, no_faults(), 9);
    send_all(&mut link, N);
    report("resequencing", &link);
    assert_exactly_once(&link, N);
    let got = link.numbers(Side::B);
    let inversions = got.windows(2).filter(|w| w[1] < w[0]).count();
    println!("[resequencing] arrivals out of order: {inversions}");
    assert!(inversions > 0, "the fault injector reordered frames");
}

#[test]
fn resequencing_strict_ordering_drops_late_frames() {
    let mut cfg = all_layers();
    cfg.temporal.ordering = Ordering::Strict;
    let mut link = warmed_up(&cfg);
    let now = link.clock.now();
    let first = sealed(&mut link, 1, now);
    let second = sealed(&mut link, 2, now);
    link.inject(Side::B, &second);
    link.inject(Side::B, &first);
    link.run(Duration::from_secs(1));
    report("resequencing-strict", &link);
    assert_eq!(link.numbers(Side::B), vec![0, 2]);
    assert_eq!(link.counters().get(Reason::OutOfOrder), 1);
}

// ---- corruption ------------------------------------------------------------------------------

#[test]
fn corruption_random_bit_flips_rejected_and_repaired_by_retransmission() {
    let faults = Impairments {
        corrupt: 0.3,
        ..no_faults()
    };
    let mut link = Link::new(&all_layers(), faults, faults, 13);
    send_all(&mut link, N);
    report("corruption", &link);
    assert_exactly_once(&link, N);
    let c = link.counters();
    assert!(c.get(Reason::BadTag) + c.get(Reason::BadFrame) > 0);
}

#[test]
fn corruption_every_single_bit_flip_of_a_sealed_frame_rejected() {
    let mut link = warmed_up(&all_layers());
    let now = link.clock.now();
    let frame = sealed(&mut link, 1, now);
    for bit in 0..frame.len() * 8 {
        let mut bad = frame.clone();
        bad[bit / 8] ^= 1 << (bit % 8);
        link.inject(Side::B, &bad);
        link.step();
    }
    link.run(Duration::from_secs(5));
    report("corruption-every-bit", &link);
    // What got through is the genuine frame, once, via the sender's retransmission.
    assert_eq!(link.numbers(Side::B), vec![0, 1]);
    for env in &link.b.delivered {
        assert_eq!(
            env.payload,
            acl("a", "b", number_of(&env.payload).expect("numbered"))
        );
    }
    assert!(link.counters().get(Reason::BadTag) > 0);
}

// ---- delay -----------------------------------------------------------------------------------

#[test]
fn delay_stale_frames_dropped_in_simulated_time() {
    // Without the communication layer, so the sender does not retransmit what the attacker holds.
    let mut link = warmed_up(&StackConfig::with_layers(
        "parser,temporal,security".parse().expect("layer list"),
    ));
    let now = link.clock.now();
    let late = sealed(&mut link, 1, now);
    let in_time = sealed(&mut link, 2, now);
    link.time.advance(Duration::from_millis(1500));
    link.inject(Side::B, &in_time);
    link.step();
    link.time.advance(Duration::from_millis(1000)); // 2.5 s > max age 2 s + skew 0.1 s
    link.inject(Side::B, &late);
    link.run(Duration::from_secs(1));
    report("delay-stale", &link);
    assert_eq!(link.numbers(Side::B), vec![0, 2]);
    assert_eq!(link.counters().get(Reason::Stale), 1);
}

#[test]
fn delay_future_timestamps_beyond_clock_skew_dropped() {
    let mut link = warmed_up(&all_layers());
    let now = link.clock.now();
    // `a`'s clock runs 50 ms ahead (tolerated) or 500 ms ahead (not).
    let skewed = sealed(&mut link, 1, now.plus(Duration::from_millis(50)));
    let future = sealed(&mut link, 2, now.plus(Duration::from_millis(500)));
    link.inject(Side::B, &skewed);
    link.inject(Side::B, &future);
    link.step();
    report("delay-future", &link);
    assert_eq!(link.numbers(Side::B), vec![0, 1]);
    assert_eq!(link.counters().get(Reason::FromFuture), 1);
}

#[test]
fn delay_past_reply_by_dropped() {
    let mut link = warmed_up(&all_layers());
    let now = link.clock.now();
    let id = link.fresh_id(Side::A);
    let env = Envelope::new(id, "a", "b", acl("a", "b", 1))
        .with_reply_by(now.plus(Duration::from_millis(20)));
    let frame = link.seal(Side::A, env, now).expect("passes a's stack");
    link.time.advance(Duration::from_millis(300));
    link.inject(Side::B, &frame);
    link.step();
    report("delay-reply-by", &link);
    assert_eq!(link.numbers(Side::B), vec![0]);
    assert_eq!(link.counters().get(Reason::PastReplyBy), 1);
}

// ---- masquerade ------------------------------------------------------------------------------

#[test]
fn masquerade_registered_agent_claiming_another_identity_rejected() {
    let mut link = warmed_up(&all_layers());
    // `m` is a legitimate, registered agent with its own key; it claims to be `a`.
    link.add_rogue(
        "m",
        &StackConfig::with_layers("temporal,security,comm".parse().expect("layer list")),
        true,
    );
    let id = link.fresh_id(Side::Rogue);
    let now = link.clock.now();
    link.send_envelope(
        Side::Rogue,
        Envelope::new(id, "a", "b", acl("a", "b", 666)),
        now,
    );
    link.run(Duration::from_secs(5));
    report("masquerade-identity", &link);
    assert_eq!(link.numbers(Side::B), vec![0]);
    assert!(link.counters().get(Reason::BadSignature) > 0);
}

#[test]
fn masquerade_authenticated_agent_cannot_sign_acl_as_another() {
    let mut link = warmed_up(&all_layers());
    // `m` authenticates as itself but writes `:sender a` inside the ACL message.
    link.add_rogue(
        "m",
        &StackConfig::with_layers("temporal,security,comm".parse().expect("layer list")),
        true,
    );
    let id = link.fresh_id(Side::Rogue);
    let now = link.clock.now();
    link.send_envelope(
        Side::Rogue,
        Envelope::new(id, "m", "b", acl("a", "b", 666)),
        now,
    );
    link.run(Duration::from_secs(5));
    report("masquerade-acl", &link);
    assert_eq!(link.numbers(Side::B), vec![0]);
    assert_eq!(link.counters().get(Reason::Mismatch), 1);
}

/// Container control traffic (join, heartbeat, election, GAL) passes the temporal and security
/// layers under the deployment's group key, on real UDP sockets: a container without the key
/// cannot join, win the election, or put an entry of its own (its key for our agent) in the GAL,
/// whether it speaks plaintext, unsealed envelopes or sealed ones under a wrong key.
#[test]
fn masquerade_container_without_the_group_key_cannot_join_or_inject_gal_entries() {
    use iw_bus::transport::{FrameTransport, PeerAddr};
    use iw_container::{
        AgentEntry, Container, ContainerConfig, ContainerId, ContainerMsg, ContainerNode,
        GlobalAgentList, Part,
    };
    use iw_stack::GuardedTransport;

    let clock = Clock::system();
    let guarded = |name: &str, key: [u8; 32]| {
        Arc::new(
            GuardedTransport::new(
                Arc::new(UdpTransport::bind("127.0.0.1:0").expect("bind")),
                name,
                key,
                clock.clone(),
            )
            .expect("guard"),
        )
    };
    let entry = |name: &str, key: u8, addr: &str| AgentEntry {
        name: name.into(),
        public_key: vec![key; 32],
        addr: PeerAddr(addr.into()),
    };
    let start =
        |id: u64, transport: Arc<dyn FrameTransport>, seeds: Vec<PeerAddr>, agent: AgentEntry| {
            let config = ContainerConfig {
                heartbeat: Duration::from_millis(20),
                lease: Duration::from_millis(200),
                ..ContainerConfig::new(ContainerId(id), transport.local_addr().clone(), seeds)
            };
            let mut container = Container::new(config);
            let identity = Arc::new(iw_stack::Identity::generate().expect("identity"));
            // an agent carries its container's identity key
            let key = identity.public_key();
            container.register(AgentEntry {
                public_key: key.to_vec(),
                ..agent
            });
            let node = ContainerNode::start(
                container,
                identity,
                transport,
                clock.clone(),
                Duration::from_millis(5),
            )
            .expect("container");
            (node, key)
        };
    let group = [7u8; 32];
    let a_guard = guarded("container-1.1", group);
    let a_addr = a_guard.local_addr().clone();
    let (a, a_key) = start(1, a_guard.clone(), vec![], entry("door", 1, "bus-a"));
    let (b, _) = start(
        2,
        guarded("container-2.1", group),
        vec![a_addr.clone()],
        entry("nav", 2, "bus-b"),
    );
    // Id 0 would win the election; it claims `door` with its own key and adds `spy`.
    let (rogue, _) = start(
        0,
        guarded("container-0.1", [9u8; 32]),
        vec![a_addr.clone()],
        entry("door", 9, "bus-rogue"),
    );

    let mut gal = GlobalAgentList::default();
    gal.merge_part(
        ContainerId(0),
        Part {
            generation: 99,
            agents: vec![entry("door", 9, "bus-rogue"), entry("spy", 9, "bus-rogue")],
        },
    );
    let forged = [
        ContainerMsg::Gal {
            leader: ContainerId(0),
            versions: gal.versions(),
            gal,
        },
        ContainerMsg::Lal {
            id: ContainerId(0),
            part: Part {
                generation: 99,
                agents: vec![entry("spy", 9, "bus-rogue")],
            },
        },
        ContainerMsg::Heartbeat {
            id: ContainerId(0),
            incarnation: 0,
            leader: ContainerId(0),
            lal_generation: 99,
            gal_versions: Default::default(),
        },
    ];
    let codec = FrameCodec::new();
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut joined = false;
    while Instant::now() < deadline {
        for msg in &forged {
            let json = msg.encode().expect("encodes");
            let unsealed = codec
                .encode_to_vec(&Envelope::new(
                    iw_bus::MsgId(1),
                    "container-0.1",
                    iw_stack::GROUP,
                    json.clone(),
                ))
                .expect("encodes");
            for frame in [&json, &unsealed] {
                socket.send_to(frame, a_addr.0.as_str()).expect("send");
            }
        }
        joined = a.with(|c| c.gal().lookup("nav").is_some())
            && b.with(|c| c.gal().lookup("door").is_some());
        if joined && a_guard.counters().get(Reason::BadTag) > 0 {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let counters = a_guard.counters();
    println!("[masquerade-container] rejections at container 1: {counters}");
    assert!(joined, "the container with the group key joined");
    for node in [&a, &b] {
        node.with(|c| {
            assert_eq!(c.leader(), ContainerId(1), "the rogue won no election");
            assert!(
                !c.live_peers().contains(&ContainerId(0)),
                "the rogue is not a live peer"
            );
            assert!(
                c.gal().lookup("spy").is_none(),
                "the rogue's agent is not in the GAL"
            );
            let (owner, door) = c.gal().lookup("door").expect("door listed");
            assert_eq!(
                (owner, door.public_key.as_slice()),
                (ContainerId(1), &a_key[..]),
                "door keeps its own key"
            );
        });
    }
    assert!(
        counters.get(Reason::BadFrame) > 0,
        "plaintext control frames refused"
    );
    assert!(
        counters.get(Reason::NotSealed) > 0,
        "unsealed envelopes refused"
    );
    assert!(
        counters.get(Reason::BadTag) > 0,
        "frames sealed under another key refused"
    );
    rogue.stop();
    b.stop();
    a.stop();
}

// ---- system level: two processes, real UDP, impairment proxy ----------------------------------

struct Peer {
    child: std::process::Child,
    stdin: std::process::ChildStdin,
    stdout: BufReader<std::process::ChildStdout>,
    addr: std::net::SocketAddr,
    key: [u8; 32],
}

impl Peer {
    fn spawn() -> Peer {
        let mut child = Command::new(env!("CARGO_BIN_EXE_iw-peer"))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("spawning iw-peer");
        let stdin = child.stdin.take().expect("piped");
        let mut stdout = BufReader::new(child.stdout.take().expect("piped"));
        let mut line = String::new();
        stdout.read_line(&mut line).expect("READY line");
        let parts: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(parts.first(), Some(&"READY"), "peer said `{line}`");
        let addr = parts[1].parse().expect("socket address");
        let key = <[u8; 32]>::from_hex(parts[2]).expect("key");
        Peer {
            child,
            stdin,
            stdout,
            addr,
            key,
        }
    }

    fn finish(mut self) -> Report {
        writeln!(self.stdin, "REPORT").expect("peer stdin");
        let mut line = String::new();
        self.stdout.read_line(&mut line).expect("REPORT line");
        let status = self.child.wait().expect("peer exit");
        assert!(status.success(), "peer failed: {status}");
        Report::parse(&line).unwrap_or_else(|| panic!("bad report `{line}`"))
    }
}

/// Runs `a` here and `b` in the peer process through the proxy; returns the peer's report, the
/// numbers `a` got back, and `a`'s counters.
fn system_run(
    faults: ImpairConfig,
    attack: impl FnOnce(&std::net::SocketAddr, &Platform),
) -> (Report, Vec<u64>, String) {
    let mut peer = Peer::spawn();
    let platform = Platform::new();
    let node = platform.node(&["a"]).expect("identity");
    platform.register("b", peer.key);
    let transport = UdpTransport::bind("127.0.0.1:0").expect("bind");
    let proxy = ImpairProxy::start(transport.socket_addr().expect("addr"), peer.addr, faults)
        .expect("proxy");
    writeln!(
        peer.stdin,
        "PEER {} {}",
        hex::encode(node.identity.public_key()),
        proxy.addr()
    )
    .expect("peer stdin");

    let mut cfg = StackConfig::default();
    cfg.comm.max_attempts = 40;
    cfg.comm.initial_rto = Duration::from_millis(10);
    cfg.comm.max_rto = Duration::from_millis(200);
    let bus = Bus::start(
        platform.stack(&node, &cfg),
        Arc::new(transport),
        Clock::system(),
        BusConfig::default(),
    )
    .expect("bus");
    bus.add_route("b", proxy.peer_addr());
    let mut mailbox = bus.register("a").expect("register");
    for n in 0..N {
        bus.send("a", "b", acl("a", "b", n)).expect("send");
        if n % 20 == 19 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    attack(&peer.addr, &platform);
    let mut echoes = Vec::new();
    let give_up = Instant::now() + Duration::from_secs(90);
    while Instant::now() < give_up {
        // Waiting in `recv_timeout`, this thread receives from the socket itself.
        match mailbox.recv_timeout(Duration::from_millis(2)) {
            Some(env) => {
                if let Some(n) =
                    number_of(&env.payload).filter(|n| env.payload == acl("b", "a", *n))
                {
                    echoes.push(n);
                }
            }
            None if echoes.iter().collect::<BTreeSet<_>>().len() as u64 == N => break,
            None => {}
        }
    }
    // Let late duplicates arrive, so a double delivery would be seen.
    std::thread::sleep(Duration::from_millis(300));
    while let Some(env) = mailbox.try_recv() {
        if let Some(n) = number_of(&env.payload) {
            echoes.push(n);
        }
    }
    let counters = bus.counters().to_string();
    bus.shutdown();
    let stats = proxy.stop();
    let report = peer.finish();
    println!("proxy: {stats:?}");
    println!("peer (b) report: {report:?}");
    println!("a rejections: {counters}");
    (report, echoes, counters)
}

fn assert_system_exact(report: &Report, echoes: &[u64]) {
    assert_eq!(
        report.foreign, 0,
        "forged, replayed or altered message delivered"
    );
    assert_eq!(report.duplicates, 0, "delivered twice");
    assert_eq!((report.unique, report.delivered), (N, N), "lost messages");
    let unique: BTreeSet<_> = echoes.iter().collect();
    assert_eq!(echoes.len(), unique.len(), "an echo delivered twice");
    assert_eq!(unique.len() as u64, N, "echoes lost");
}

#[test]
fn udp_system_deletion_repetition_resequencing_nothing_lost_nothing_twice() {
    let faults = ImpairConfig {
        seed: 50159,
        drop: 0.2,
        duplicate: 0.1,
        reorder: 0.1,
        ..Default::default()
    };
    let (report, echoes, _) = system_run(faults, |_, _| {});
    assert_system_exact(&report, &echoes);
    assert!(
        report.counters.contains("duplicate"),
        "the proxy's duplicates were seen and dropped"
    );
}

#[test]
fn udp_system_corruption_insertion_delay_masquerade_repetition_rejected() {
    let faults = ImpairConfig {
        seed: 7,
        drop: 0.05,
        corrupt: 0.1,
        delay: 0.1,
        inject_forged: 0.1,
        inject_replay: 0.1,
        ..Default::default()
    };
    let attack = |peer: &std::net::SocketAddr, _: &Platform| {
        // Straight at b's socket, around the proxy: plaintext claiming to be `a`, and a key
        // agreement signed by an identity that is not `a`'s.
        let socket = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
        let codec = FrameCodec::new();
        let mut plain = Envelope::new(iw_bus::MsgId(1), "a", "b", acl("a", "b", 10_000));
        plain.header.timestamp = Clock::system().now();
        socket
            .send_to(&codec.encode_to_vec(&plain).expect("encodable"), peer)
            .expect("send");
        let rogue = Platform::new();
        let m = rogue.node(&["a"]).expect("identity");
        rogue.register("b", [0; 32]);
        let mut stack = rogue.stack(
            &m,
            &StackConfig::with_layers("security".parse().expect("layers")),
        );
        let mut env = Envelope::new(iw_bus::MsgId(2), "a", "b", acl("a", "b", 10_001));
        let _ = iw_bus::Layer::outbound(&mut stack, &mut env, Clock::system().now());
        while let Some(hello) = iw_bus::Layer::poll_transmit(&mut stack, Clock::system().now()) {
            socket
                .send_to(&codec.encode_to_vec(&hello).expect("encodable"), peer)
                .expect("send");
        }
    };
    let (report, echoes, _) = system_run(faults, attack);
    assert_system_exact(&report, &echoes);
    assert!(
        report.counters.contains("not_sealed"),
        "plaintext insertion rejected"
    );
    assert!(
        report.counters.contains("bad_signature"),
        "masquerading key agreement rejected"
    );
    assert!(
        report.counters.contains("bad_tag") || report.counters.contains("bad_frame"),
        "corruption rejected"
    );
}
