//! Real shared memory between threads and between two processes.

use std::process::Command;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use iw_bus::transport::{FrameTransport, PeerAddr, TransportError};
use iw_transport_shm::ShmTransport;

const WAIT: Duration = Duration::from_secs(10);
/// Set in the child process of `echo_between_two_processes`: the address to echo on.
const CHILD_ENV: &str = "IW_SHM_ECHO_CHILD";

/// A service name no other test or run uses.
fn unique(tag: &str) -> String {
    let nanos = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    format!("test/{}/{tag}/{nanos}", std::process::id())
}

#[test]
fn round_trips_between_threads_keep_content_order_and_sender() {
    let a = ShmTransport::open(&unique("rt-a")).unwrap();
    let b_addr = unique("rt-b");
    let b = ShmTransport::open(&b_addr).unwrap();
    let echo = std::thread::spawn(move || {
        for _ in 0..1000 {
            let (from, frame) = b.recv_timeout(WAIT).unwrap().unwrap();
            b.send(&from, &frame).unwrap();
        }
    });
    let to = PeerAddr(b_addr);
    for i in 0..1000u32 {
        let frame: Vec<u8> = i.to_le_bytes().iter().copied().cycle().take(300).collect();
        a.send(&to, &frame).unwrap();
        let (from, back) = a.recv_timeout(WAIT).unwrap().unwrap();
        assert_eq!((&from, &back), (&to, &frame));
    }
    echo.join().unwrap();
    assert!(a.recv_timeout(Duration::from_millis(5)).unwrap().is_none());
}

#[test]
fn one_inbox_hears_several_senders_in_order_each() {
    let inbox_addr = unique("fan-in");
    let inbox = ShmTransport::open(&inbox_addr).unwrap();
    let senders: Vec<_> = (0..3)
        .map(|i| ShmTransport::open(&unique(&format!("fan-{i}"))).unwrap())
        .collect();
    let to = PeerAddr(inbox_addr);
    for n in 0..20u8 {
        for s in &senders {
            s.send(&to, &[n]).unwrap();
        }
    }
    let mut last = std::collections::HashMap::new();
    for _ in 0..60 {
        let (from, frame) = inbox.recv_timeout(WAIT).unwrap().unwrap();
        let prev = last.insert(from, frame[0]);
        assert_eq!(prev.map_or(0, |p| p + 1), frame[0]);
    }
    assert_eq!(last.len(), 3);
}

#[test]
fn frames_grow_up_to_the_limit_and_not_beyond() {
    let a = ShmTransport::open_with(&unique("big-a"), 100_000, Default::default()).unwrap();
    let b_addr = unique("big-b");
    let b = ShmTransport::open(&b_addr).unwrap();
    let to = PeerAddr(b_addr);
    let big: Vec<u8> = (0..40_000u32).map(|i| i as u8).collect();
    a.send(&to, b"small first").unwrap();
    a.send(&to, &big).unwrap();
    assert_eq!(b.recv_timeout(WAIT).unwrap().unwrap().1, b"small first");
    assert_eq!(b.recv_timeout(WAIT).unwrap().unwrap().1, big);
    let err = a.send(&to, &vec![0; 100_001]).unwrap_err();
    assert!(matches!(
        err,
        TransportError::FrameTooLarge {
            len: 100_001,
            max: 100_000
        }
    ));
    assert!(matches!(
        a.send(&PeerAddr("no spaces".into()), b"x"),
        Err(TransportError::BadAddress { .. })
    ));
}

#[test]
fn echo_between_two_processes() {
    let child_addr = unique("proc-child");
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "echo_child", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, &child_addr)
        .spawn()
        .unwrap();
    let me = ShmTransport::open(&unique("proc-parent")).unwrap();
    let to = PeerAddr(child_addr);
    // The child may not have opened its inbox yet: retry the first frame until it answers.
    let mut answered = false;
    for _ in 0..500 {
        me.send(&to, b"hello").unwrap();
        if me
            .recv_timeout(Duration::from_millis(20))
            .unwrap()
            .is_some()
        {
            answered = true;
            break;
        }
    }
    assert!(answered, "child process never answered");
    while me
        .recv_timeout(Duration::from_millis(50))
        .unwrap()
        .is_some()
    {}
    for i in 0..200u32 {
        me.send(&to, &i.to_be_bytes()).unwrap();
        let (from, back) = me.recv_timeout(WAIT).unwrap().unwrap();
        assert_eq!((from, back), (to.clone(), i.to_be_bytes().to_vec()));
    }
    me.send(&to, b"stop").unwrap();
    assert!(child.wait().unwrap().success());
}

/// The child half of `echo_between_two_processes`; does nothing when run on its own.
#[test]
fn echo_child() {
    let Ok(addr) = std::env::var(CHILD_ENV) else {
        return;
    };
    let t = ShmTransport::open(&addr).unwrap();
    while let Some((from, frame)) = t.recv_timeout(WAIT).unwrap() {
        if frame == b"stop" {
            return;
        }
        t.send(&from, &frame).unwrap();
    }
    panic!("parent went quiet");
}

/// An inbox takes at most four subscribers: a fifth endpoint on the same address is refused by
/// iceoryx2 itself, and `TransportError::Middleware` keeps iceoryx2's own error as its source.
#[test]
fn a_refused_endpoint_keeps_the_middlewares_error() {
    let addr = unique("crowded");
    let open: Vec<_> = (0..4)
        .map(|_| ShmTransport::open(&addr).expect("four subscribers fit"))
        .collect();
    let err = ShmTransport::open(&addr).expect_err("a fifth subscriber is refused");
    assert!(matches!(err, TransportError::Middleware { .. }), "{err}");
    let source = std::error::Error::source(&err)
        .and_then(|s| s.downcast_ref::<iceoryx2::port::subscriber::SubscriberCreateError>())
        .unwrap_or_else(|| panic!("no iceoryx2 error under `{err}`"));
    assert!(
        matches!(
            source,
            iceoryx2::port::subscriber::SubscriberCreateError::ExceedsMaxSupportedSubscribers
        ),
        "{source:?}"
    );
    drop(open);
}
