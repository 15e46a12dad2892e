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
