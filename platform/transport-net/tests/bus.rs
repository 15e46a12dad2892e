//! Two buses over UDP loopback, each agent on its own thread blocked on its mailbox: the blocked
//! threads receive from the sockets themselves (the bus's leader/follower pump).

use std::sync::Arc;
use std::time::Duration;

use iw_bus::{Bus, BusConfig, Clock, Stack};
use iw_transport_net::UdpTransport;

fn bus() -> Arc<Bus> {
    let transport = UdpTransport::bind("127.0.0.1:0").unwrap();
    Arc::new(
        Bus::start(
            Stack::new(),
            Arc::new(transport),
            Clock::system(),
            BusConfig::default(),
        )
        .unwrap(),
    )
}

#[test]
fn blocked_agent_threads_exchange_messages_in_order_over_udp() {
    let (one, two) = (bus(), bus());
    one.add_route("b", two.local_addr().clone());
    two.add_route("a", one.local_addr().clone());
    let mut a = one.register("a").unwrap();
    let mut b = two.register("b").unwrap();
    let echo = {
        let two = two.clone();
        std::thread::spawn(move || {
            let mut got = Vec::new();
            while let Some(env) = b.blocking_recv() {
                two.send("b", "a", env.payload.clone()).unwrap();
                got.push(u64::from_be_bytes(env.payload.try_into().unwrap()));
            }
            got
        })
    };
    // One message in flight at a time: loopback UDP does not lose or reorder them.
    for n in 0..300u64 {
        one.send("a", "b", n.to_be_bytes().to_vec()).unwrap();
        let env = a.recv_timeout(Duration::from_secs(10)).expect("echo");
        assert_eq!(env.payload, n.to_be_bytes());
    }
    two.deregister("b");
    assert_eq!(echo.join().unwrap(), (0..300).collect::<Vec<_>>());
}
