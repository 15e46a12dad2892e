//! Attacks on the container control channel (issue 20 items 1-3), on real UDP sockets with the
//! containers `intellwheels spawn` runs ([`iw_node::Runtime`], in this process):
//! - a container refuses to start without a control key unless told it is a development run;
//! - forged heartbeats and agent lists from a socket, even with no control key, re-route
//!   nothing: lists are taken only from the elected leader's address, and no generation, even
//!   `u64::MAX`, pins a route;
//! - a second services container with the id of a live one is refused, the first undisturbed;
//! - a holder of the group key, speaking over TCP from the services' own address, cannot speak
//!   for the services: control frames travel in sessions agreed with each container's
//!   identity, and the agreement's reply goes to the address she claims;
//! - a receiver restarted with its sessions lost gets the message sealed under the old session.
//! - under a roster (`security.roster`), a holder of the group key cannot claim a free low id
//!   or a pinned one, cannot stop a container with a forged `Duplicate`, and a member cannot
//!   list another container's agents.

use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use iw_bus::transport::FrameTransport;
use iw_bus::transport::PeerAddr;
use iw_bus::{Bus, BusConfig, Clock};
use iw_container::{AgentEntry, ContainerId, ContainerMsg, ControlChannel, GlobalAgentList, Part};
use iw_node::{Event, NodeError, Role, Runtime, SpawnConfig};
use iw_stack::{Platform, StackConfig};
use iw_transport_net::UdpTransport;

/// Upper bound of every wait: generous for a loaded 2-core machine, never the expected time.
const LIMIT: Duration = Duration::from_secs(60);

/// Two consecutive free UDP ports on loopback (bus and control channel).
fn free_port_pair() -> u16 {
    loop {
        let a = UdpSocket::bind("127.0.0.1:0").unwrap();
        let port = a.local_addr().unwrap().port();
        if port < u16::MAX && UdpSocket::bind(("127.0.0.1", port + 1)).is_ok() {
            return port;
        }
    }
}

/// A container running on its own thread, with its events.
struct Running {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), NodeError>>>,
    events: Receiver<Event>,
    seen: Vec<Event>,
    port: u16,
}

impl Running {
    fn start(role: Role, mut config: SpawnConfig) -> Running {
        let port = free_port_pair();
        config.transport.listen = format!("127.0.0.1:{port}");
        let (tx, events) = channel();
        let runtime = Runtime::start(&role, config, tx).expect("container starts");
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            std::thread::spawn(move || runtime.run(&stop))
        };
        Running {
            stop,
            thread: Some(thread),
            events,
            seen: Vec::new(),
            port,
        }
    }

    fn bus(&self) -> String {
        format!("127.0.0.1:{}", self.port)
    }

    fn control(&self) -> String {
        format!("127.0.0.1:{}", self.port + 1)
    }

    /// Waits for an event matching `want` (also among those seen); panics after LIMIT.
    fn wait_for(&mut self, what: &str, want: impl Fn(&Event) -> bool) {
        let deadline = Instant::now() + LIMIT;
        while !self.seen.iter().any(&want) {
            match self
                .events
                .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            {
                Ok(e) => self.seen.push(e),
                Err(_) => panic!("no {what} within {LIMIT:?}; saw {:#?}", self.seen),
            }
        }
    }

    /// Collects events for `d`.
    fn drain_for(&mut self, d: Duration) {
        let end = Instant::now() + d;
        while let Ok(e) = self
            .events
            .recv_timeout(end.saturating_duration_since(Instant::now()))
        {
            self.seen.push(e);
        }
    }

    fn stop(mut self) -> Result<(), NodeError> {
        self.stop.store(true, Ordering::Release);
        self.thread
            .take()
            .expect("running")
            .join()
            .expect("no panic")
    }
}

fn joined(agent: &str) -> impl Fn(&Event) -> bool + '_ {
    move |e| matches!(e, Event::Joined { agent: a, .. } if a == agent)
}

fn config(control_key: Option<&str>, peers: &[String]) -> SpawnConfig {
    let mut c = SpawnConfig::default();
    match control_key {
        Some(path) => c.security.control_key = path.into(),
        None => c.security.insecure_dev = true,
    }
    c.transport.peers = peers.to_vec();
    // A lease no scheduling stall on a loaded machine outlasts: a `left` here is an attack's.
    c.container.lease = Duration::from_millis(3000);
    c
}

#[test]
fn a_container_without_a_control_key_refuses_to_start() {
    let mut c = SpawnConfig::default();
    c.transport.listen = format!("127.0.0.1:{}", free_port_pair());
    let (tx, _rx) = channel();
    let err = Runtime::start(&Role::Services, c, tx)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        err.contains("security.control_key") && err.contains("--insecure-dev"),
        "{err}"
    );
}

/// The chair still routes to the real services, and no forged agent joined it.
fn assert_services_kept(chair: &Running) {
    assert!(
        !chair
            .seen
            .iter()
            .any(|e| matches!(e, Event::Left { agent, .. } if agent == "assistant@services")),
        "the services' route was taken: {:#?}",
        chair.seen
    );
    assert!(
        !chair.seen.iter().any(joined("evil@x")),
        "{:#?}",
        chair.seen
    );
}

/// The services' take-over, as a forger sends it: a heartbeat claiming the services' id, and the
/// services' list (assistant re-routed, an agent added) at a generation that would pin it forever.
fn takeover(evil: impl Fn(&str) -> AgentEntry) -> [ContainerMsg; 2] {
    takeover_as(1, evil)
}

/// The take-over as container `id` (the services' id, or a free one lower than theirs, which
/// wins the election): its heartbeat, and its list as the leader's.
fn takeover_as(id: u64, evil: impl Fn(&str) -> AgentEntry) -> [ContainerMsg; 2] {
    let mut pinned = GlobalAgentList::default();
    pinned.merge_part(
        ContainerId(id),
        Part {
            generation: u64::MAX,
            agents: vec![evil("assistant@services"), evil("evil@x")],
        },
    );
    [
        ContainerMsg::Heartbeat {
            id: ContainerId(id),
            incarnation: u32::MAX,
            leader: ContainerId(id),
            lal_generation: u64::MAX,
            gal_versions: Default::default(),
        },
        ContainerMsg::Gal {
            leader: ContainerId(id),
            versions: pinned.versions(),
            gal: pinned,
        },
    ]
}

/// Even in a development run with no control key, forged lists from a socket re-route nothing.
#[test]
fn forged_heartbeats_and_agent_lists_reroute_nothing() {
    let mut services = Running::start(Role::Services, config(None, &[]));
    let peers = [services.bus()];
    let chair = Role::Chair {
        name: "chair-f".into(),
    };
    let mut chair = Running::start(chair, config(None, &peers));
    chair.wait_for("the services joined", joined("assistant@services"));
    services.wait_for("the chair joined", joined("control@chair-f"));

    let mut attacker = Forger::new(
        forger(),
        Arc::new(UdpTransport::bind("127.0.0.1:0").unwrap()),
    );
    let here = PeerAddr(attacker.addr());
    let evil = |name: &str| AgentEntry {
        name: name.into(),
        public_key: vec![0xee; 32],
        addr: here.clone(),
    };
    let forged = takeover(evil);
    attacker.flood(&chair.control(), &forged, Duration::from_secs(2));
    let duplicate_told = attacker.heard.iter().any(|m| {
        matches!(m, ContainerMsg::Duplicate { id: ContainerId(1), holder, .. } if holder.0 == services.control())
    });
    chair.drain_for(Duration::from_millis(500));
    assert!(duplicate_told, "the claim on a live id was answered");
    assert_services_kept(&chair);
    chair.stop().unwrap();
    services.stop().unwrap();
}

/// Issue 20 item 2: a second services container, holding the group key, with the id of the
/// live one and the chair as its peer, is refused; the chair keeps its services.
#[test]
fn a_second_services_container_with_a_live_id_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let key = dir.path().join("control.key");
    iw_stack::write_group_key(&key).unwrap();
    let key = key.to_str().unwrap();
    let mut services = Running::start(Role::Services, config(Some(key), &[]));
    let chair = Role::Chair {
        name: "chair-i".into(),
    };
    let mut chair = Running::start(chair, config(Some(key), &[services.bus()]));
    chair.wait_for("the services joined", joined("assistant@services"));
    services.wait_for("the chair joined", joined("control@chair-i"));

    let mut impostor_config = config(Some(key), &[chair.bus()]);
    impostor_config.services.goals.push(iw_node::GoalSpec {
        chair: "chair-i".into(),
        place: "office".into(),
    });
    let mut impostor = Running::start(Role::Services, impostor_config);
    let deadline = Instant::now() + LIMIT;
    while !impostor.thread.as_ref().unwrap().is_finished() {
        assert!(Instant::now() < deadline, "the impostor kept running");
        std::thread::sleep(Duration::from_millis(20));
    }
    impostor.drain_for(Duration::ZERO);
    let said = std::mem::take(&mut impostor.seen);
    let err = impostor.stop().expect_err("refused").to_string();
    assert!(err.contains("already held"), "{err}");
    assert!(
        !said.iter().any(|e| matches!(e, Event::Goal { .. })),
        "{said:#?}"
    );
    chair.drain_for(Duration::from_millis(500));
    assert!(
        !chair.seen.iter().any(|e| matches!(e, Event::Left { .. })),
        "the chair kept its services: {:#?}",
        chair.seen
    );
    chair.stop().unwrap();
    services.stop().unwrap();
}

/// Issue 20 item 3: a receiver killed and restarted (same key, same address, no sessions) gets
/// the next message, which its sender sealed under the session the receiver lost.
#[test]
fn a_restarted_receiver_gets_the_message_sealed_under_its_lost_session() {
    let platform = Platform::new();
    let na = platform.node(&["a"]).unwrap();
    let nb = platform.node(&["b"]).unwrap();
    let config = StackConfig::default();
    let bus = |node: &iw_stack::Node, addr: &str| {
        let transport = UdpTransport::bind(addr).unwrap();
        Bus::start(
            platform.stack(node, &config),
            Arc::new(transport),
            Clock::system(),
            BusConfig::default(),
        )
        .unwrap()
    };
    let a = bus(&na, "127.0.0.1:0");
    let b = bus(&nb, "127.0.0.1:0");
    let b_addr = b.local_addr().clone();
    a.add_route("b", b_addr.clone());
    b.add_route("a", a.local_addr().clone());
    let mut inbox = b.register("b").unwrap();
    let msg = |n: u64| iw_tests::acl("a", "b", n);
    a.send("a", "b", msg(1)).unwrap();
    let got = inbox.recv_timeout(LIMIT).expect("first message");
    assert_eq!(got.payload, msg(1));

    drop(inbox);
    b.shutdown(); // killed: its sessions are gone
    let b = bus(&nb, &b_addr.0);
    b.add_route("a", a.local_addr().clone());
    let mut inbox = b.register("b").unwrap();
    a.send("a", "b", msg(2)).unwrap();
    // Message 1 may come again first: if its acknowledgement was lost with the old life, it was
    // still in flight, and is re-sealed like message 2 (the restarted receiver cannot know it
    // had it).
    loop {
        let got = inbox
            .recv_timeout(LIMIT)
            .unwrap_or_else(|| panic!("lost: a {} b {}", a.counters(), b.counters()));
        if got.payload == msg(2) {
            break;
        }
        assert_eq!(got.payload, msg(1));
    }
    assert!(b.counters().get(iw_bus::Reason::UnknownSession) >= 1);
}

/// Issue 20 item 7: garbage on the bus and control ports is counted per reason and reported in
/// a `security` event (the warnings about it are rate-limited, see `iw_bus::WarnEvery`).
#[test]
fn rejections_are_counted_and_reported_in_a_security_event() {
    let dir = tempfile::tempdir().unwrap();
    let key = dir.path().join("control.key");
    iw_stack::write_group_key(&key).unwrap();
    let mut services = Running::start(Role::Services, config(key.to_str(), &[]));
    let attacker = UdpSocket::bind("127.0.0.1:0").unwrap();
    for n in 0..200u32 {
        let garbage = n.to_be_bytes();
        attacker.send_to(&garbage, services.control()).unwrap();
        attacker.send_to(&garbage, services.bus()).unwrap();
    }
    let count = |e: &Event, channel: &str| match e {
        Event::Security { bus, control, .. } => {
            let of = if channel == "bus" { bus } else { control };
            of.get("bad_frame").copied().unwrap_or(0)
        }
        _ => 0,
    };
    services.wait_for("a security event counting both ports", |e| {
        count(e, "bus") > 0 && count(e, "control") > 0
    });
    services.stop().unwrap();
}

/// A group-key holder's TCP connection to `to` whose hello names `claimed`: the TCP transport
/// takes the sender's word for its address, so this is how a key holder speaks "from" another
/// container's address without raw sockets.
struct SpoofedTcp {
    claimed: PeerAddr,
    stream: std::sync::Mutex<std::net::TcpStream>,
    codec: iw_transport_net::frame::FrameCodec,
}

impl SpoofedTcp {
    fn connect(to: &str, claimed: &str) -> SpoofedTcp {
        use iw_transport_net::frame::{FrameCodec, FrameKind};
        use std::io::Write;
        let codec = FrameCodec::new(1 << 20);
        let mut stream = std::net::TcpStream::connect(to).unwrap();
        let mut hello = Vec::new();
        codec
            .encode(FrameKind::Hello, claimed.as_bytes(), &mut hello)
            .unwrap();
        stream.write_all(&hello).unwrap();
        SpoofedTcp {
            claimed: PeerAddr(claimed.into()),
            stream: std::sync::Mutex::new(stream),
            codec,
        }
    }
}

impl iw_bus::transport::FrameTransport for SpoofedTcp {
    fn local_addr(&self) -> &PeerAddr {
        &self.claimed
    }

    fn max_frame_len(&self) -> usize {
        self.codec.max_frame_len()
    }

    fn send(&self, _to: &PeerAddr, frame: &[u8]) -> Result<(), iw_bus::transport::TransportError> {
        use std::io::Write;
        let mut bytes = Vec::new();
        self.codec
            .encode(iw_transport_net::frame::FrameKind::Data, frame, &mut bytes)
            .unwrap();
        self.stream
            .lock()
            .unwrap()
            .write_all(&bytes)
            .map_err(|source| iw_bus::transport::TransportError::Io {
                context: "the spoofed connection".into(),
                source,
            })
    }

    fn recv_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, iw_bus::transport::TransportError> {
        std::thread::sleep(timeout);
        Ok(None)
    }
}

/// Issue 20, the control channel: a holder of the group key, speaking over TCP from the
/// services' control address, forges the services' heartbeat (a higher incarnation, as a
/// restart would say) and the services' agent list. The chair obeys neither: control frames
/// travel in sessions agreed with the sender container's identity, and the chair answers her
/// hello at the address she claims, the services', which refuses the reply (counted there as
/// `bad_handshake`): she never holds a session with the chair. Had she one, her own key would
/// not speak for container 1 either (a live id is bound to the key it was first heard with; the
/// other tests here show that).
#[test]
fn a_key_holder_forging_another_containers_heartbeat_and_list_is_not_obeyed() {
    let dir = tempfile::tempdir().unwrap();
    let key = dir.path().join("control.key");
    iw_stack::write_group_key(&key).unwrap();
    let tcp = |peers: &[String]| {
        let mut c = config(key.to_str(), peers);
        c.transport.kind = iw_node::TransportKind::Tcp;
        c
    };
    let mut services = Running::start(Role::Services, tcp(&[]));
    let chair = Role::Chair {
        name: "chair-k".into(),
    };
    let mut chair = Running::start(chair, tcp(&[services.bus()]));
    chair.wait_for("the services joined", joined("assistant@services"));
    services.wait_for("the chair joined", joined("control@chair-k"));

    let spoofed = Arc::new(SpoofedTcp::connect(&chair.control(), &services.control()));
    let group_key = iw_stack::read_group_key(&key).unwrap();
    let guarded = iw_stack::GuardedTransport::new(
        spoofed,
        "container-1.4294967295",
        group_key,
        Clock::system(),
    )
    .unwrap();
    let mut attacker = Forger::new(forger(), Arc::new(guarded));
    let evil = |name: &str| AgentEntry {
        name: name.into(),
        public_key: forger_key().to_vec(),
        addr: PeerAddr("127.0.0.1:9".into()),
    };
    let forged = takeover(evil);
    attacker.flood(&chair.control(), &forged, Duration::from_secs(3));
    chair.drain_for(Duration::from_secs(1));
    assert_services_kept(&chair);
    services.wait_for("the chair's reply to her hello refused at the services", |e| {
        matches!(e, Event::Security { control, .. } if control.get("bad_handshake").is_some_and(|n| *n > 0))
    });
    chair.stop().unwrap();
    services.stop().unwrap();
}

/// The forger's own identity (one she may well hold: the group key admits any identity).
fn forger() -> Arc<iw_stack::Identity> {
    static FORGER: std::sync::OnceLock<Arc<iw_stack::Identity>> = std::sync::OnceLock::new();
    FORGER
        .get_or_init(|| Arc::new(iw_stack::Identity::generate().unwrap()))
        .clone()
}

fn forger_key() -> [u8; 32] {
    forger().public_key()
}

/// An attacker's end of the control channel: an identity she holds, over a transport of hers.
/// She agrees sessions as any container does (the real control channel's code), then says in
/// them what she likes.
struct Forger {
    channel: ControlChannel,
    transport: Arc<dyn FrameTransport>,
    /// Every message she was sent.
    heard: Vec<ContainerMsg>,
}

impl Forger {
    fn new(identity: Arc<iw_stack::Identity>, transport: Arc<dyn FrameTransport>) -> Forger {
        Forger {
            channel: ControlChannel::new(identity).unwrap(),
            transport,
            heard: Vec::new(),
        }
    }

    fn addr(&self) -> String {
        self.transport.local_addr().0.clone()
    }

    /// Sends `msgs` to `to`, and again every 20 ms for `d`, answering handshakes meanwhile.
    fn flood(&mut self, to: &str, msgs: &[ContainerMsg], d: Duration) {
        let to = PeerAddr(to.into());
        let end = Instant::now() + d;
        loop {
            for msg in msgs {
                let now = Clock::system().now();
                for datagram in self.channel.seal(&to, msg, now).unwrap() {
                    self.transport.send(&to, &datagram).unwrap();
                }
            }
            self.pump(Duration::from_millis(20));
            if Instant::now() >= end {
                return;
            }
        }
    }

    /// Takes what arrives for `d`: handshakes answered, messages kept in `heard`.
    fn pump(&mut self, d: Duration) {
        let end = Instant::now() + d;
        while let Ok(Some((from, datagram))) = self
            .transport
            .recv_timeout(end.saturating_duration_since(Instant::now()))
        {
            let mut back = Vec::new();
            let opened = self
                .channel
                .open(&from, &datagram, Clock::system().now(), &mut back);
            for d in back {
                let _ = self.transport.send(&from, &d);
            }
            if let Ok(Some(m)) = opened {
                self.heard.push(m.msg);
            }
        }
    }
}

// ---- a deployment with a roster (`security.roster`): identities pinned in advance ------------

/// A deployment's group key, identity keys and roster in a temporary directory.
struct Pinned {
    dir: tempfile::TempDir,
}

impl Pinned {
    fn new(members: &[&str]) -> Pinned {
        let dir = tempfile::tempdir().unwrap();
        iw_stack::write_group_key(&dir.path().join("control.key")).unwrap();
        let members: Vec<(String, u64)> = members.iter().map(|m| (m.to_string(), 0)).collect();
        iw_node::write_roster(&dir.path().join("roster"), dir.path(), &members).unwrap();
        Pinned { dir }
    }

    /// Container `name`'s configuration: its own key, the roster, the group key.
    fn config(&self, name: &str, peers: &[String]) -> SpawnConfig {
        let path = |f: &str| self.dir.path().join(f).display().to_string();
        let mut c = config(Some(&path("control.key")), peers);
        c.security.identity_key = path(&format!("{name}.pk8"));
        c.security.roster = path("roster");
        c
    }

    /// Container `name`'s pinned id.
    fn id(&self, name: &str) -> u64 {
        let roster = iw_container::Roster::load(&self.dir.path().join("roster")).unwrap();
        let (id, _) = roster.pins().find(|(_, p)| p.name == name).unwrap();
        id.0
    }

    /// A group-key holder's own UDP endpoint on the control channel, speaking as `identity`.
    fn attacker(&self, name: &str, identity: Arc<iw_stack::Identity>) -> Forger {
        let key = iw_stack::read_group_key(&self.dir.path().join("control.key")).unwrap();
        let guarded = iw_stack::GuardedTransport::new(
            Arc::new(UdpTransport::bind("127.0.0.1:0").unwrap()),
            name,
            key,
            Clock::system(),
        )
        .unwrap();
        Forger::new(identity, Arc::new(guarded))
    }
}

/// Services and chair `chair` of deployment `pinned`, joined.
fn pinned_pair(pinned: &Pinned, chair: &str) -> (Running, Running) {
    let mut services = Running::start(Role::Services, pinned.config("services", &[]));
    let mut chair_c = Running::start(
        Role::Chair { name: chair.into() },
        pinned.config(chair, &[services.bus()]),
    );
    chair_c.wait_for("the services joined", joined("assistant@services"));
    services.wait_for("the chair joined", joined(&format!("control@{chair}")));
    (services, chair_c)
}

/// `container`'s control rejections for `reason` in its latest `security` event.
fn control_rejections(container: &Running, reason: &str) -> u64 {
    container
        .seen
        .iter()
        .filter_map(|e| match e {
            Event::Security { control, .. } => control.get(reason).copied(),
            _ => None,
        })
        .max()
        .unwrap_or(0)
}

/// Under a roster, a holder of the group key claims id 0 (free, lower than the services', so it
/// would lead) and id 2 (the world's, pinned to a key she does not hold), each with a list as
/// the leader's re-routing the assistant. Without a roster the claim of id 0 is obeyed (the
/// weaker mode's known limit); with one the chair obeys neither, and counts them.
#[test]
fn under_a_roster_a_key_holder_claiming_a_free_low_id_is_not_obeyed() {
    let pinned = Pinned::new(&["services", "world", "chair-p"]);
    let (services, mut chair) = pinned_pair(&pinned, "chair-p");
    let mut attacker = pinned.attacker("container-0.1.attacker", forger());
    let evil = |name: &str| AgentEntry {
        name: name.into(),
        public_key: forger_key().to_vec(),
        addr: PeerAddr("127.0.0.1:9".into()),
    };
    let forged: Vec<ContainerMsg> = [0, 2]
        .into_iter()
        .flat_map(|id| takeover_as(id, evil))
        .collect();
    attacker.flood(&chair.control(), &forged, Duration::from_secs(3));
    chair.drain_for(Duration::from_secs(1));
    assert_services_kept(&chair);
    chair.wait_for("the claims counted", |e| {
        matches!(e, Event::Security { control, .. }
            if control.get("unknown_peer").is_some_and(|n| *n > 0)
                && control.get("mismatch").is_some_and(|n| *n > 0))
    });
    println!(
        "chair refused: unknown_peer {}, mismatch {}",
        control_rejections(&chair, "unknown_peer"),
        control_rejections(&chair, "mismatch")
    );
    chair.stop().unwrap();
    services.stop().unwrap();
}

/// Under a roster, a forged `Duplicate` (sent under a group-key holder's own identity, naming
/// herself as the holder of the chair's id, running "forever") does not stop the chair: only
/// the chair's own pinned key can say its id is held.
#[test]
fn under_a_roster_a_forged_duplicate_does_not_stop_a_running_container() {
    let pinned = Pinned::new(&["services", "chair-d"]);
    let (mut services, mut chair) = pinned_pair(&pinned, "chair-d");
    let mut attacker = pinned.attacker("container-9.1.attacker", forger());
    let forged = ContainerMsg::Duplicate {
        id: ContainerId(pinned.id("chair-d")),
        holder: PeerAddr(attacker.addr()),
        holder_incarnation: 0,
        holder_uptime_ms: u64::MAX,
    };
    attacker.flood(&chair.control(), &[forged], Duration::from_secs(3));
    chair.drain_for(Duration::from_secs(1));
    assert!(
        !chair.thread.as_ref().unwrap().is_finished(),
        "the chair stopped: {:#?}",
        chair.seen
    );
    chair.wait_for("the forgery counted", |e| {
        matches!(e, Event::Security { control, .. } if control.get("mismatch").is_some_and(|n| *n > 0))
    });
    services.drain_for(Duration::ZERO);
    assert!(
        !services
            .seen
            .iter()
            .any(|e| matches!(e, Event::Left { agent, .. } if agent == "control@chair-d")),
        "the services lost the chair: {:#?}",
        services.seen
    );
    chair.stop().expect("the chair ran on and stopped cleanly");
    services.stop().unwrap();
}

/// Under a roster, a member of the deployment (she holds chair-m's own pinned key, and the
/// group key) lists, as chair-m's agents, the services' assistant at her address and an agent
/// `evil@x`; and sends the chair a global list as if she led. The leader refuses her part (a
/// container's part carries only `ROLE@ITS-NAME` under its key), the chair refuses a list from a
/// non-leader: the chair keeps its services.
#[test]
fn under_a_roster_an_agent_list_with_foreign_agents_or_from_a_non_leader_is_ignored() {
    let pinned = Pinned::new(&["services", "chair-q", "chair-m"]);
    let (mut services, mut chair) = pinned_pair(&pinned, "chair-q");
    let member = Arc::new(
        iw_stack::Identity::from_pkcs8(
            &std::fs::read(pinned.dir.path().join("chair-m.pk8")).unwrap(),
        )
        .unwrap(),
    );
    let m = ContainerId(pinned.id("chair-m"));
    let mut attacker = pinned.attacker("container-m.1.attacker", member.clone());
    let here = PeerAddr(attacker.addr());
    let entry = |name: &str| AgentEntry {
        name: name.into(),
        public_key: member.public_key().to_vec(),
        addr: here.clone(),
    };
    let part = Part {
        generation: (1 << 32) + 7,
        agents: vec![
            entry("assistant@services"),
            entry("evil@x"),
            entry("control@chair-m"),
        ],
    };
    let mut as_leader = GlobalAgentList::default();
    as_leader.merge_part(m, part.clone());
    let heartbeat = ContainerMsg::Heartbeat {
        id: m,
        incarnation: 1,
        leader: ContainerId(1),
        lal_generation: part.generation,
        gal_versions: Default::default(),
    };
    let end = Instant::now() + Duration::from_secs(3);
    while Instant::now() < end {
        let to_services = [
            heartbeat.clone(),
            ContainerMsg::Lal {
                id: m,
                part: part.clone(),
            },
        ];
        attacker.flood(&services.control(), &to_services, Duration::ZERO);
        let to_chair = [ContainerMsg::Gal {
            leader: m,
            versions: as_leader.versions(),
            gal: as_leader.clone(),
        }];
        attacker.flood(&chair.control(), &to_chair, Duration::ZERO);
    }
    chair.drain_for(Duration::from_secs(1));
    assert_services_kept(&chair);
    assert!(
        !chair.seen.iter().any(joined("control@chair-m")),
        "the whole part was refused: {:#?}",
        chair.seen
    );
    services.wait_for("the foreign agents counted", |e| {
        matches!(e, Event::Security { control, .. } if control.get("mismatch").is_some_and(|n| *n > 0))
    });
    chair.stop().unwrap();
    services.stop().unwrap();
}
