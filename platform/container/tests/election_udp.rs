//! Containers over real UDP loopback: the leader dies, another is elected, the lists survive;
//! the old leader returns and everything resyncs.

use std::sync::Arc;
use std::time::{Duration, Instant};

use iw_bus::Clock;
use iw_bus::transport::{FrameTransport, PeerAddr};
use iw_container::{AgentEntry, Container, ContainerConfig, ContainerId, ContainerNode};
use iw_transport_net::UdpTransport;

const TICK: Duration = Duration::from_millis(5);

/// Polls `cond` until it holds or 10 s pass; returns whether it held.
fn eventually(mut cond: impl FnMut() -> bool) -> bool {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(10) {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    false
}

fn start(
    id: u64,
    incarnation: u32,
    transport: UdpTransport,
    seeds: &[PeerAddr],
    agents: &[&str],
) -> ContainerNode {
    let addr = transport.local_addr().clone();
    let mut config = ContainerConfig::new(ContainerId(id), addr.clone(), seeds.to_vec());
    config.incarnation = incarnation;
    config.heartbeat = Duration::from_millis(20);
    config.lease = Duration::from_millis(150);
    let mut container = Container::new(config);
    let identity = Arc::new(iw_layer_security::Identity::generate().unwrap());
    for a in agents {
        container.register(AgentEntry {
            name: a.to_string(),
            public_key: identity.public_key().to_vec(),
            addr: addr.clone(),
        });
    }
    let transport: Arc<dyn FrameTransport> = Arc::new(transport);
    ContainerNode::start(container, identity, transport, Clock::system(), TICK).unwrap()
}

fn leader(node: &ContainerNode) -> u64 {
    node.with(|c| c.leader().0)
}

fn gal_len(node: &ContainerNode) -> usize {
    node.with(|c| c.gal().len())
}

#[test]
fn leader_dies_another_is_elected_and_lists_resync_on_return() {
    let transports: Vec<UdpTransport> = (0..3)
        .map(|_| UdpTransport::bind("127.0.0.1:0").unwrap())
        .collect();
    let seeds: Vec<PeerAddr> = transports.iter().map(|t| t.local_addr().clone()).collect();
    let mut it = transports.into_iter();
    let (t1, t2, t3) = (it.next().unwrap(), it.next().unwrap(), it.next().unwrap());
    let c1 = start(1, 0, t1, &seeds, &["nav"]);
    let c2 = start(2, 0, t2, &seeds, &["wheel", "joystick"]);
    let c3 = start(3, 0, t3, &seeds, &["camera"]);
    assert!(
        eventually(|| [&c1, &c2, &c3]
            .iter()
            .all(|c| leader(c) == 1 && gal_len(c) == 4)),
        "initial election and GAL"
    );

    c1.stop(); // the elected container dies
    assert!(
        eventually(|| leader(&c2) == 2 && leader(&c3) == 2),
        "container 2 takes over"
    );
    assert!(c2.with(|c| c.resolve("wheel").is_some() && c.resolve("camera").is_some()));
    let addr3 = seeds[2].clone();
    c3.with(|c| {
        // carrying its container's key, as every entry must
        let key = c.lal().entries().next().expect("hosted").public_key.clone();
        c.register(AgentEntry {
            name: "lidar".into(),
            public_key: key,
            addr: addr3,
        })
    });
    assert!(
        eventually(|| c2.with(|c| c.resolve("lidar").is_some())),
        "the new leader distributes"
    );

    // Container 1 comes back on its old address, in a new incarnation, with a new agent.
    let t1 = UdpTransport::bind(&seeds[0].0).unwrap();
    let c1 = start(1, 1, t1, &seeds, &["nav", "planner"]);
    assert!(
        eventually(|| [&c1, &c2, &c3]
            .iter()
            .all(|c| leader(c) == 1 && gal_len(c) == 6)),
        "resync after return"
    );
    assert!(c3.with(|c| c.resolve("planner").is_some()));
    assert!(c1.with(|c| c.resolve("lidar").is_some()));
}
