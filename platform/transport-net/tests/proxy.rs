//! The impairment proxy on real loopback sockets (as a process: `cli/tests/impair.rs`).

use std::collections::HashSet;
use std::time::Duration;

use iw_bus::transport::FrameTransport;
use iw_transport_net::{ImpairConfig, ImpairProxy, UdpTransport};

/// Receives until the link has been quiet for `quiet`.
fn drain(t: &UdpTransport, quiet: Duration) -> Vec<Vec<u8>> {
    let mut got = Vec::new();
    while let Some((_, frame)) = t.recv_timeout(quiet).unwrap() {
        got.push(frame);
    }
    got
}

#[test]
fn what_arrives_matches_the_counters_under_loss_duplication_and_reordering() {
    let a = UdpTransport::bind("127.0.0.1:0").unwrap();
    let b = UdpTransport::bind("127.0.0.1:0").unwrap();
    let config = ImpairConfig {
        seed: 11,
        drop: 0.2,
        duplicate: 0.1,
        reorder: 0.1,
        ..Default::default()
    };
    let proxy =
        ImpairProxy::start(a.socket_addr().unwrap(), b.socket_addr().unwrap(), config).unwrap();
    let n = 400u32;
    // Receive while sending: an unread socket buffer holds only ~270 small datagrams.
    let receiver = std::thread::spawn(move || drain(&b, Duration::from_millis(300)));
    for i in 0..n {
        a.send(&proxy.peer_addr(), &i.to_be_bytes()).unwrap();
        if i % 20 == 0 {
            std::thread::sleep(Duration::from_millis(1)); // the proxy's buffer is finite too
        }
    }
    let got = receiver.join().unwrap();
    let stats = proxy.stop();
    assert_eq!(stats.received, u64::from(n));
    assert_eq!(
        got.len() as u64,
        stats.forwarded,
        "got {} for {stats:?}",
        got.len()
    );
    assert!(
        stats.dropped > 40 && stats.duplicated > 10 && stats.reordered > 10,
        "{stats:?}"
    );
    let seqs: Vec<u32> = got
        .iter()
        .map(|f| u32::from_be_bytes(f[..4].try_into().unwrap()))
        .collect();
    let distinct: HashSet<_> = seqs.iter().collect();
    assert_eq!(distinct.len() as u64, u64::from(n) - stats.dropped);
    assert!(
        seqs.windows(2).any(|w| w[1] < w[0]),
        "reordering visible at the receiver"
    );
}

#[test]
fn replies_travel_back_through_the_proxy() {
    let a = UdpTransport::bind("127.0.0.1:0").unwrap();
    let b = UdpTransport::bind("127.0.0.1:0").unwrap();
    let proxy = ImpairProxy::start(
        a.socket_addr().unwrap(),
        b.socket_addr().unwrap(),
        ImpairConfig::default(),
    )
    .unwrap();
    a.send(&proxy.peer_addr(), b"ping").unwrap();
    let (from, frame) = b.recv_timeout(Duration::from_secs(5)).unwrap().unwrap();
    assert_eq!((from, frame.as_slice()), (proxy.peer_addr(), &b"ping"[..]));
    b.send(&proxy.peer_addr(), b"pong").unwrap();
    assert_eq!(
        a.recv_timeout(Duration::from_secs(5)).unwrap().unwrap().1,
        b"pong"
    );
    let stranger = UdpTransport::bind("127.0.0.1:0").unwrap();
    stranger.send(&proxy.peer_addr(), b"let me in").unwrap();
    assert!(
        b.recv_timeout(Duration::from_millis(100))
            .unwrap()
            .is_none()
    );
    let stats = proxy.stop();
    assert_eq!((stats.forwarded, stats.strangers), (2, 1));
}

#[test]
fn delayed_datagrams_arrive_late_but_arrive() {
    let a = UdpTransport::bind("127.0.0.1:0").unwrap();
    let b = UdpTransport::bind("127.0.0.1:0").unwrap();
    let config = ImpairConfig {
        delay: 1.0,
        delay_min: Duration::from_millis(30),
        delay_max: Duration::from_millis(30),
        ..Default::default()
    };
    let proxy =
        ImpairProxy::start(a.socket_addr().unwrap(), b.socket_addr().unwrap(), config).unwrap();
    a.send(&proxy.peer_addr(), b"late").unwrap();
    assert!(b.recv_timeout(Duration::from_millis(5)).unwrap().is_none());
    assert_eq!(
        b.recv_timeout(Duration::from_secs(5)).unwrap().unwrap().1,
        b"late"
    );
    assert_eq!(proxy.stop().delayed, 1);
}
