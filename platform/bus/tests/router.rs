//! The bus router over in-process transports: local delivery, remote routing, refusals, and who
//! receives (agent threads blocked on their mailbox, the pump thread, layer timers).

use std::collections::HashSet;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use iw_bus::transport::{FrameTransport, PeerAddr, TransportError};
use iw_bus::{
    Bus, BusConfig, BusError, Clock, Envelope, InProcNetwork, Layer, Mailbox, MsgId, Reason, Stack,
    Time, Verdict,
};

fn wait(mailbox: &mut Mailbox) -> Envelope {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(env) = mailbox.try_recv() {
            return env;
        }
        assert!(
            Instant::now() < deadline,
            "nothing arrived for {}",
            mailbox.name()
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn routes_locally_and_to_remote_buses() {
    let net = InProcNetwork::new();
    let one = Bus::start(
        Stack::new(),
        Arc::new(net.endpoint("one").unwrap()),
        Clock::system(),
        BusConfig::default(),
    )
    .unwrap();
    let two = Bus::start(
        Stack::new(),
        Arc::new(net.endpoint("two").unwrap()),
        Clock::system(),
        BusConfig::default(),
    )
    .unwrap();
    let mut a = one.register("a").unwrap();
    let mut b = one.register("b").unwrap();
    let mut c = two.register("c").unwrap();
    one.add_route("c", two.local_addr().clone());
    two.add_route("a", one.local_addr().clone());

    one.send("a", "b", b"local".to_vec()).unwrap();
    assert_eq!(wait(&mut b).payload, b"local");
    one.send("a", "c", b"remote".to_vec()).unwrap();
    let got = wait(&mut c);
    assert_eq!(
        (got.header.sender.as_str(), got.payload.as_slice()),
        ("a", &b"remote"[..])
    );
    two.send("c", "a", b"reply".to_vec()).unwrap();
    assert_eq!(wait(&mut a).payload, b"reply");

    assert!(matches!(
        one.register("a"),
        Err(BusError::AgentExists { .. })
    ));
    assert!(matches!(
        one.send("a", "nobody", Vec::new()),
        Err(BusError::NoRoute { .. })
    ));
    assert_eq!(one.counters().get(Reason::NoRoute), 1);
    one.shutdown();
    two.shutdown();
}

#[test]
fn undecodable_frames_are_counted() {
    let net = InProcNetwork::new();
    let bus = Bus::start(
        Stack::new(),
        Arc::new(net.endpoint("bus").unwrap()),
        Clock::system(),
        BusConfig::default(),
    )
    .unwrap();
    let attacker = net.endpoint("x").unwrap();
    attacker.send(bus.local_addr(), b"not a frame").unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while bus.counters().get(Reason::BadFrame) == 0 {
        assert!(Instant::now() < deadline);
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn a_burst_of_waiting_frames_is_delivered_in_order() {
    use iw_bus::FrameCodec;
    let net = InProcNetwork::new();
    let sender = net.endpoint("x").unwrap();
    let bus = Bus::start(
        Stack::new(),
        Arc::new(net.endpoint("bus").unwrap()),
        Clock::system(),
        BusConfig::default(),
    )
    .unwrap();
    let mut b = bus.register("b").unwrap();
    // More frames than the pump takes in one batch, queued before it can take any, with an
    // undecodable one in the middle.
    let codec = FrameCodec::new();
    for n in 0..200u64 {
        if n == 100 {
            sender.send(bus.local_addr(), b"not a frame").unwrap();
        }
        let frame = codec
            .encode_to_vec(&Envelope::new(MsgId(n), "x", "b", n.to_be_bytes().to_vec()))
            .unwrap();
        sender.send(bus.local_addr(), &frame).unwrap();
    }
    for n in 0..200u64 {
        assert_eq!(wait(&mut b).payload, n.to_be_bytes());
    }
    assert_eq!(bus.counters().get(Reason::BadFrame), 1);
    assert_eq!(bus.counters().total(), 1);
    bus.shutdown();
}

/// A transport that notes which threads took frames from it.
struct Recorder {
    inner: iw_bus::InProcTransport,
    receivers: Arc<Mutex<HashSet<String>>>,
}

impl FrameTransport for Recorder {
    fn local_addr(&self) -> &PeerAddr {
        self.inner.local_addr()
    }
    fn max_frame_len(&self) -> usize {
        self.inner.max_frame_len()
    }
    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError> {
        self.inner.send(to, frame)
    }
    fn recv_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError> {
        let got = self.inner.recv_timeout(timeout)?;
        if got.is_some() {
            self.receivers.lock().unwrap().insert(thread_name());
        }
        Ok(got)
    }
}

fn thread_name() -> String {
    std::thread::current().name().unwrap_or("").to_string()
}

/// Two buses on one in-process network, `one` routing to agents of `two` and back.
fn pair(
    net: &InProcNetwork,
    stack_two: Stack,
) -> (Arc<Bus>, Arc<Bus>, Arc<Mutex<HashSet<String>>>) {
    let receivers = Arc::new(Mutex::new(HashSet::new()));
    let recorder = Recorder {
        inner: net.endpoint("two").unwrap(),
        receivers: receivers.clone(),
    };
    let one = Bus::start(
        Stack::new(),
        Arc::new(net.endpoint("one").unwrap()),
        Clock::system(),
        BusConfig::default(),
    )
    .unwrap();
    let two = Bus::start(
        stack_two,
        Arc::new(recorder),
        Clock::system(),
        BusConfig::default(),
    )
    .unwrap();
    (Arc::new(one), Arc::new(two), receivers)
}

#[test]
fn a_blocked_agent_thread_receives_from_the_transport_itself_in_order() {
    let net = InProcNetwork::new();
    let (one, two, receivers) = pair(&net, Stack::new());
    let mut a = one.register("a").unwrap();
    let mut b = two.register("b").unwrap();
    one.add_route("b", two.local_addr().clone());
    two.add_route("a", one.local_addr().clone());
    let echo = {
        let two = two.clone();
        std::thread::Builder::new()
            .name("echo".into())
            .spawn(move || {
                let mut got = Vec::new();
                while let Some(env) = b.blocking_recv() {
                    two.send("b", "a", env.payload.clone()).unwrap();
                    got.push(env.payload);
                }
                got
            })
            .unwrap()
    };
    // Bursts, each answered before the next: the echo thread is mostly blocked, so it leads.
    let mut sent = Vec::new();
    for burst in 0..100u64 {
        for k in 0..5u64 {
            let payload = (burst * 5 + k).to_be_bytes().to_vec();
            one.send("a", "b", payload.clone()).unwrap();
            sent.push(payload);
        }
        for k in 0..5u64 {
            let env = a.recv_timeout(Duration::from_secs(10)).expect("echo");
            assert_eq!(env.payload, (burst * 5 + k).to_be_bytes());
        }
    }
    two.deregister("b");
    assert_eq!(echo.join().unwrap(), sent);
    assert!(
        receivers.lock().unwrap().contains("echo"),
        "the echo thread never led: {:?}",
        receivers.lock().unwrap()
    );
    assert!(a.recv_timeout(Duration::from_millis(1)).is_none());
}

#[test]
fn two_agent_threads_blocked_on_one_bus_both_get_all_their_messages() {
    const N: u64 = 300;
    let net = InProcNetwork::new();
    let (one, two, _) = pair(&net, Stack::new());
    one.add_route("b1", two.local_addr().clone());
    one.add_route("b2", two.local_addr().clone());
    let (done_tx, done_rx) = std::sync::mpsc::channel();
    let mut threads = Vec::new();
    for name in ["b1", "b2"] {
        let mut mailbox = two.register(name).unwrap();
        let done = done_tx.clone();
        threads.push(std::thread::spawn(move || {
            let mut got = Vec::new();
            while let Some(env) = mailbox.blocking_recv() {
                got.push(u64::from_be_bytes(env.payload.try_into().unwrap()));
                if got.len() as u64 == N {
                    done.send(()).unwrap();
                }
            }
            got
        }));
    }
    for n in 0..N {
        one.send("a", "b1", n.to_be_bytes().to_vec()).unwrap();
        one.send("a", "b2", n.to_be_bytes().to_vec()).unwrap();
        if n % 16 == 15 {
            std::thread::yield_now();
        }
    }
    for _ in 0..2 {
        // Generous: a failure here means a lost frame or a deadlock, not a slow machine.
        done_rx
            .recv_timeout(Duration::from_secs(60))
            .expect("a thread is missing messages");
    }
    two.deregister("b1");
    two.deregister("b2");
    for t in threads {
        assert_eq!(t.join().unwrap(), (0..N).collect::<Vec<_>>());
    }
    assert_eq!(two.counters().total(), 0);
}

/// Originates an envelope to agent `t` every `period`, noting the thread that sent it.
struct Ticker {
    next: Time,
    period: Duration,
    n: u64,
    senders: Arc<Mutex<Vec<String>>>,
}

impl Layer for Ticker {
    fn name(&self) -> &'static str {
        "ticker"
    }
    fn outbound(&mut self, _env: &mut Envelope, _now: Time) -> Verdict {
        Verdict::Pass
    }
    fn inbound(&mut self, _env: &mut Envelope, _now: Time) -> Verdict {
        Verdict::Pass
    }
    fn poll_transmit(&mut self, now: Time) -> Option<Envelope> {
        if now < self.next {
            return None;
        }
        self.next = now.plus(self.period);
        self.n += 1;
        self.senders.lock().unwrap().push(thread_name());
        Some(Envelope::new(MsgId(self.n), "ticker", "t", Vec::new()))
    }
    fn next_deadline(&self) -> Option<Time> {
        Some(self.next)
    }
}

/// Waits until a tick sent by a thread named `name` (by prefix) has reached `t`.
fn wait_for_tick_from(t: &mut Mailbox, senders: &Mutex<Vec<String>>, name: &str) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        while t.try_recv().is_some() {}
        if senders.lock().unwrap().iter().any(|s| s.starts_with(name)) {
            return;
        }
        assert!(Instant::now() < deadline, "no tick sent by {name}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn layer_timers_run_while_an_agent_thread_leads_and_after_it_stops() {
    let senders = Arc::new(Mutex::new(Vec::new()));
    let ticker = Ticker {
        next: Time::ZERO,
        period: Duration::from_millis(2),
        n: 0,
        senders: senders.clone(),
    };
    let net = InProcNetwork::new();
    let bus = Arc::new(
        Bus::start(
            Stack::new().push(ticker),
            Arc::new(net.endpoint("bus").unwrap()),
            Clock::system(),
            BusConfig::default(),
        )
        .unwrap(),
    );
    let mut t = bus.register("t").unwrap();
    let mut x = bus.register("x").unwrap();
    let leader = std::thread::Builder::new()
        .name("leader".into())
        .spawn(move || x.blocking_recv())
        .unwrap();
    wait_for_tick_from(&mut t, &senders, "leader");
    bus.deregister("x");
    assert!(leader.join().unwrap().is_none(), "nothing was sent to x");
    senders.lock().unwrap().clear();
    wait_for_tick_from(&mut t, &senders, "bus-pump");
}

#[test]
fn async_agents_receive_from_the_pump_thread_before_and_after_a_thread_led() {
    let net = InProcNetwork::new();
    let (one, two, _) = pair(&net, Stack::new());
    one.add_route("b", two.local_addr().clone());
    one.add_route("c", two.local_addr().clone());
    let mut b = two.register("b").unwrap();
    let mut c = two.register("c").unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .unwrap();
    let mut recv_c = |payload: &[u8]| {
        let got = runtime
            .block_on(async { tokio::time::timeout(Duration::from_secs(10), c.recv()).await });
        assert_eq!(
            got.expect("c got nothing")
                .expect("c's stream ended")
                .payload,
            payload
        );
    };
    one.send("a", "c", b"before".to_vec()).unwrap();
    recv_c(b"before");
    // `b` leads while it waits, and gets what is sent to `c` delivered as well.
    let leader = std::thread::spawn(move || {
        let got = b.blocking_recv().map(|env| env.payload);
        (b, got)
    });
    one.send("a", "c", b"while".to_vec()).unwrap();
    one.send("a", "b", b"for b".to_vec()).unwrap();
    let (_b, got) = leader.join().unwrap();
    assert_eq!(got.as_deref(), Some(&b"for b"[..]));
    recv_c(b"while");
    one.send("a", "c", b"after".to_vec()).unwrap();
    recv_c(b"after");
}

#[test]
fn a_blocked_receiver_sees_the_end_of_the_stream_and_timeouts() {
    let net = InProcNetwork::new();
    let bus = Bus::start(
        Stack::new(),
        Arc::new(net.endpoint("bus").unwrap()),
        Clock::system(),
        BusConfig::default(),
    )
    .unwrap();
    let mut a = bus.register("a").unwrap();
    assert!(a.recv_timeout(Duration::from_millis(5)).is_none());
    bus.send("b", "a", b"kept".to_vec()).unwrap();
    let waiting = std::thread::spawn(move || {
        let first = a.blocking_recv().map(|env| env.payload);
        (first, a.blocking_recv().is_none())
    });
    std::thread::sleep(Duration::from_millis(5));
    // Dropping the bus ends the stream of a thread blocked in it.
    drop(bus);
    assert_eq!(waiting.join().unwrap(), (Some(b"kept".to_vec()), true));
}

/// Answers every inbound envelope but an acknowledgement with an acknowledgement to its sender.
#[derive(Default)]
struct Acker {
    pending: Vec<Envelope>,
}

impl Layer for Acker {
    fn name(&self) -> &'static str {
        "acker"
    }
    fn outbound(&mut self, _env: &mut Envelope, _now: Time) -> Verdict {
        Verdict::Pass
    }
    fn inbound(&mut self, env: &mut Envelope, _now: Time) -> Verdict {
        if env.payload != b"ack" {
            self.pending.push(Envelope::new(
                env.header.id,
                env.header.receiver.clone(),
                env.header.sender.clone(),
                b"ack".to_vec(),
            ));
        }
        Verdict::Pass
    }
    fn poll_transmit(&mut self, _now: Time) -> Option<Envelope> {
        self.pending.pop()
    }
    fn next_deadline(&self) -> Option<Time> {
        (!self.pending.is_empty()).then_some(Time::ZERO)
    }
}

#[test]
fn an_acknowledgement_left_by_a_leading_thread_goes_out_though_it_never_sends_again() {
    let net = InProcNetwork::new();
    let (one, two, _) = pair(&net, Stack::new().push(Acker::default()));
    one.add_route("b", two.local_addr().clone());
    two.add_route("a", one.local_addr().clone());
    let mut a = one.register("a").unwrap();
    let mut b = two.register("b").unwrap();
    // `b` takes one envelope, then neither sends nor receives again.
    let taker = std::thread::spawn(move || b.blocking_recv().map(|env| env.payload));
    one.send("a", "b", b"hello".to_vec()).unwrap();
    assert_eq!(taker.join().unwrap().as_deref(), Some(&b"hello"[..]));
    let ack = a
        .recv_timeout(Duration::from_secs(10))
        .expect("the acknowledgement");
    assert_eq!(
        (ack.header.sender.as_str(), ack.payload.as_slice()),
        ("b", &b"ack"[..])
    );
}

#[test]
fn a_local_sender_is_told_when_its_receivers_mailbox_is_full_and_a_remote_drop_is_counted() {
    let net = InProcNetwork::new();
    let start = |name: &str, mailbox_capacity: usize| {
        let config = BusConfig {
            mailbox_capacity,
            ..BusConfig::default()
        };
        let transport = Arc::new(net.endpoint(name).unwrap());
        Bus::start(Stack::new(), transport, Clock::system(), config).unwrap()
    };
    let one = start("one", 2);
    let two = start("two", 1024);
    let mut slow = one.register("slow").unwrap();
    two.add_route("slow", one.local_addr().clone());
    for n in 0..2u8 {
        one.send("a", "slow", vec![n]).unwrap();
    }
    // the third does not fit: the sender hears it, not only the counter
    match one.send("a", "slow", vec![2]) {
        Err(BusError::MailboxFull { receiver }) => assert_eq!(receiver, "slow"),
        other => panic!("expected MailboxFull, got {other:?}"),
    }
    assert_eq!(one.counters().get(Reason::MailboxFull), 1);
    // from another bus the send itself succeeds (the frame left); the drop is counted where it
    // happened
    two.send("b", "slow", vec![3]).unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while one.counters().get(Reason::MailboxFull) < 2 {
        assert!(Instant::now() < deadline, "the remote drop was not counted");
        std::thread::sleep(Duration::from_millis(1));
    }
    // what fitted is delivered, in order; room again once the agent caught up
    assert_eq!(wait(&mut slow).payload, [0]);
    assert_eq!(wait(&mut slow).payload, [1]);
    one.send("a", "slow", vec![4]).unwrap();
    assert_eq!(wait(&mut slow).payload, [4]);
    one.shutdown();
    two.shutdown();
}
