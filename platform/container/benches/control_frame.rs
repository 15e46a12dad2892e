//! Container control frames, CPU time (group `control_frame_cpu`): one control message written
//! and read back, as JSON (the wire before control frames were signed: the peer) and as a
//! [`iw_container::Signed`] frame (Ed25519 sign and verify by the container identity), for a
//! heartbeat and for a 20-agent global list. The group key's sealing on top is the `security`
//! row of `cargo bench -p iw-stack --bench layers`.
//!
//! Run: `cargo bench -p iw-container --bench control_frame` (or build it with `--profile test`
//! and run the binary with `--bench`)

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iw_bench_clock::cpu_iter;

fn control(c: &mut Criterion) {
    use iw_container::{AgentEntry, ContainerId, ContainerMsg, GlobalAgentList, Part, Signed};
    use iw_layer_security::Identity;
    let identity = Identity::generate().expect("identity");
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
                        addr: iw_bus::transport::PeerAddr(format!("10.0.0.{container}:7700")),
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
    for (name, msg) in [("heartbeat", &heartbeat), ("gal20", &gal)] {
        group.bench_function(format!("{name}_json"), |b| {
            cpu_iter(b, || {
                let frame = msg.encode().expect("encodes");
                black_box(ContainerMsg::decode(&frame).expect("decodes"));
            })
        });
        let mut seq = 0;
        group.bench_function(format!("{name}_signed"), |b| {
            cpu_iter(b, || {
                seq += 1;
                let frame = Signed::seal(&identity, seq, msg).expect("seals");
                black_box(Signed::open(&frame).expect("opens"));
            })
        });
    }
    group.finish();
}

criterion_group!(benches, control);
criterion_main!(benches);
