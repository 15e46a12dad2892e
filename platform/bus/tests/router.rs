//! The bus router over in-process transports: local delivery, remote routing, refusals.

use std::sync::Arc;
use std::time::{Duration, Instant};

use iw_bus::{Bus, BusConfig, BusError, Clock, Envelope, InProcNetwork, Mailbox, Reason, Stack};

fn wait(mailbox: &mut Mailbox) -> Envelope {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(env) = mailbox.try_recv() {
            return env;
        }
        assert!(Instant::now() < deadline, "nothing arrived for {}", mailbox.name());
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn routes_locally_and_to_remote_buses() {
    let net = InProcNetwork::new();
    let one = Bus::start(Stack::new(), Arc::new(net.endpoint("one").unwrap()), Clock::system(), BusConfig::default()).unwrap();
    let two = Bus::start(Stack::new(), Arc::new(net.endpoint("two").unwrap()), Clock::system(), BusConfig::default()).unwrap();
    let mut a = one.register("a").unwrap();
    let mut b = one.register("b").unwrap();
    let mut c = two.register("c").unwrap();
    one.add_route("c", two.local_addr().clone());
    two.add_route("a", one.local_addr().clone());

    one.send("a", "b", b"local".to_vec()).unwrap();
    assert_eq!(wait(&mut b).payload, b"local");
    one.send("a", "c", b"remote".to_vec()).unwrap();
    let got = wait(&mut c);
    assert_eq!((got.header.sender.as_str(), got.payload.as_slice()), ("a", &b"remote"[..]));
    two.send("c", "a", b"reply".to_vec()).unwrap();
    assert_eq!(wait(&mut a).payload, b"reply");

    assert!(matches!(one.register("a"), Err(BusError::AgentExists { .. })));
    assert!(matches!(one.send("a", "nobody", Vec::new()), Err(BusError::NoRoute { .. })));
    assert_eq!(one.counters().get(Reason::NoRoute), 1);
    one.shutdown();
    two.shutdown();
}

#[test]
fn undecodable_frames_are_counted() {
    let net = InProcNetwork::new();
    let bus = Bus::start(Stack::new(), Arc::new(net.endpoint("bus").unwrap()), Clock::system(), BusConfig::default()).unwrap();
    let attacker = net.endpoint("x").unwrap();
    use iw_bus::transport::FrameTransport;
    attacker.send(bus.local_addr(), b"not a frame").unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while bus.counters().get(Reason::BadFrame) == 0 {
        assert!(Instant::now() < deadline);
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn a_burst_of_waiting_frames_is_delivered_in_order() {
    use iw_bus::transport::FrameTransport;
    use iw_bus::{FrameCodec, MsgId};
    let net = InProcNetwork::new();
    let sender = net.endpoint("x").unwrap();
    let bus = Bus::start(Stack::new(), Arc::new(net.endpoint("bus").unwrap()), Clock::system(), BusConfig::default()).unwrap();
    let mut b = bus.register("b").unwrap();
    // More frames than the pump takes in one batch, queued before it can take any, with an
    // undecodable one in the middle.
    let codec = FrameCodec::new();
    for n in 0..200u64 {
        if n == 100 {
            sender.send(bus.local_addr(), b"not a frame").unwrap();
        }
        let frame = codec.encode_to_vec(&Envelope::new(MsgId(n), "x", "b", n.to_be_bytes().to_vec())).unwrap();
        sender.send(bus.local_addr(), &frame).unwrap();
    }
    for n in 0..200u64 {
        assert_eq!(wait(&mut b).payload, n.to_be_bytes());
    }
    assert_eq!(bus.counters().get(Reason::BadFrame), 1);
    assert_eq!(bus.counters().total(), 1);
    bus.shutdown();
}
