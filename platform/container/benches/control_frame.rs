//! Container control frames, CPU time (group `control_frame_cpu`): one control message written
//! and read back, for a heartbeat and for a 20-agent global list, three ways in the same run:
//! - `json`: the message alone (the wire before control frames were authenticated);
//! - `signed`: JSON with an Ed25519 signature by the container identity, made and checked (the
//!   wire before the control sessions: what every frame cost then);
//! - `session`: a [`iw_container::ControlChannel`] frame, AES-256-GCM sealed and opened under
//!   an agreed Noise session (the wire now).
//!
//! And `handshake`: agreeing one session (hello and reply, both ends), paid once per peer.
//! The group key's sealing on top is the `security` row of `cargo bench -p iw-stack --bench
//! layers`.
//!
//! Run: `cargo bench -p iw-container --bench control_frame` (or build it with `--profile test`
//! and run the binary with `--bench`)

use std::hint::black_box;
use std::sync::Arc;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iw_bench_clock::cpu_iter;
use iw_bus::Time;
use iw_bus::transport::PeerAddr;
use iw_container::{ContainerMsg, ControlChannel};
use iw_layer_security::{Identity, verify};

/// Agrees a session from `a` (at "a") to `b` (at `at_b`), and delivers `msg` in it.
fn agreed(a: &mut ControlChannel, b: &mut ControlChannel, at_b: &PeerAddr, msg: &ContainerMsg) {
    let at_a = PeerAddr("a".into());
    let hello = a.seal(at_b, msg, Time(1)).expect("seals");
    let mut reply = Vec::new();
    for d in hello {
        b.open(&at_a, &d, Time(1), &mut reply).expect("hello taken");
    }
    let mut frames = Vec::new();
    for d in reply {
        a.open(at_b, &d, Time(1), &mut frames).expect("reply taken");
    }
    for d in frames {
        let opened = b.open(&at_a, &d, Time(1), &mut Vec::new()).expect("opens");
        assert!(
            opened.is_some(),
            "the first message arrives after the handshake"
        );
    }
}

fn control(c: &mut Criterion) {
    use iw_container::{AgentEntry, ContainerId, GlobalAgentList, Part};
    let identity = Arc::new(Identity::generate().expect("identity"));
    let heartbeat = ContainerMsg::Heartbeat {
        id: ContainerId(1001),
        incarnation: 1_764_000_000,
        leader: ContainerId(1),
        lal_generation: (1_764_000_000 << 32) | 7,
        gal_versions: (0..3).map(|i| (ContainerId(i), i << 32)).collect(),
    };
    let mut gal = GlobalAgentList::default();
    for container in 0..4u64 {
        gal.merge_part(
            ContainerId(container),
            Part {
                generation: (container << 32) | 5,
                agents: (0..5)
                    .map(|a| AgentEntry {
                        name: format!("agent{a}@chair-{container}"),
                        public_key: identity.public_key().to_vec(),
                        addr: PeerAddr(format!("10.0.0.{container}:7700")),
                    })
                    .collect(),
            },
        );
    }
    let gal = ContainerMsg::Gal {
        leader: ContainerId(1),
        versions: gal.versions(),
        gal,
    };
    let mut group = c.benchmark_group("control_frame_cpu");
    group.throughput(Throughput::Elements(1));
    group.measurement_time(Duration::from_secs(3));
    group.warm_up_time(Duration::from_secs(1));
    let key = identity.public_key();
    let (at_a, at_b) = (PeerAddr("a".into()), PeerAddr("b".into()));
    for (name, msg) in [("heartbeat", &heartbeat), ("gal20", &gal)] {
        group.bench_function(format!("{name}_json"), |b| {
            cpu_iter(b, || {
                let frame = msg.encode().expect("encodes");
                black_box(ContainerMsg::decode(&frame).expect("decodes"));
            })
        });
        group.bench_function(format!("{name}_signed"), |b| {
            cpu_iter(b, || {
                let frame = msg.encode().expect("encodes");
                let sig = identity.sign(&frame);
                assert!(verify(&key, &frame, &sig));
                black_box(ContainerMsg::decode(&frame).expect("decodes"));
            })
        });
        let mut a = ControlChannel::new(identity.clone()).expect("channel");
        let mut peer = ControlChannel::new(Arc::new(Identity::generate().expect("identity")))
            .expect("channel");
        agreed(&mut a, &mut peer, &at_b, msg);
        let mut back = Vec::new();
        group.bench_function(format!("{name}_session"), |b| {
            cpu_iter(b, || {
                let frames = a.seal(&at_b, msg, Time(1)).expect("seals");
                let opened = peer.open(&at_a, &frames[0], Time(1), &mut back);
                black_box(opened.expect("opens").expect("a message"));
            })
        });
    }
    // each iteration greets a peer address of its own: a new session, as with a new chair
    let mut a = ControlChannel::new(identity.clone()).expect("channel");
    let mut peer = ControlChannel::new(identity.clone()).expect("channel");
    let mut n = 0u64;
    group.bench_function("heartbeat_handshake", |b| {
        cpu_iter(b, || {
            n += 1;
            agreed(&mut a, &mut peer, &PeerAddr(format!("b{n}")), &heartbeat);
        })
    });
    group.finish();
}

criterion_group!(benches, control);
criterion_main!(benches);
