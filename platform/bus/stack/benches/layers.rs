//! Cost of each bus layer, and of all four, on a 300-byte FIPA-ACL message, in process:
//! one message sent by stack A and received by stack B, acknowledgement included.
//!
//! Group `layers_300B` is wall time; `layers_300B_cpu` the bench thread's CPU time.
//!
//! Run: `cargo bench -p iw-stack --bench layers`

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iw_acl::{AclMessage, AgentId, Performative};
use iw_bus::{Envelope, Layer, MsgId, Time, Verdict};
use iw_stack::{Platform, StackConfig};

/// A 300-byte ACL message from `a` to `b`.
fn message() -> Vec<u8> {
    let base = AclMessage::new(Performative::Inform)
        .with_sender(AgentId::new("a"))
        .with_receiver(AgentId::new("b"))
        .with_ontology("intellwheels")
        .with_conversation_id("c-1");
    let empty = iw_acl::codec::print(&base.clone().with_content("")).len();
    let text = iw_acl::codec::print(&base.with_content("x".repeat(300 - empty)));
    assert_eq!(text.len(), 300);
    text.into_bytes()
}

/// CPU time of this thread (the machine is shared: wall time also counts other processes).
fn thread_cpu() -> Duration {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant the kernel knows.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

fn bench(c: &mut Criterion) {
    for cpu in [false, true] {
        run(c, cpu);
    }
}

fn run(c: &mut Criterion, cpu: bool) {
    let payload = message();
    let mut group = c.benchmark_group(if cpu { "layers_300B_cpu" } else { "layers_300B" });
    group.throughput(Throughput::Elements(1));
    group.measurement_time(Duration::from_secs(3));
    group.warm_up_time(Duration::from_secs(1));
    for set in ["none", "comm", "security", "temporal", "parser", "all"] {
        let platform = Platform::new();
        let na = platform.node(&["a"]).expect("identity");
        let nb = platform.node(&["b"]).expect("identity");
        let cfg = StackConfig::with_layers(set.parse().expect("layer set"));
        let (mut a, mut b) = (platform.stack(&na, &cfg), platform.stack(&nb, &cfg));
        let now = Time::from_ns(1_700_000_000_000_000_000);
        let mut id = 0u64;
        let mut one = || {
                id += 1;
                let env = Envelope::new(MsgId(id), "a", "b", payload.clone());
                let mut delivered = 0;
                let mut wire = match a.outbound(env, now) {
                    Verdict::Pass(e) => vec![e],
                    _ => Vec::new(),
                };
                // The first message of the security run also carries the key agreement.
                loop {
                    while let Some(e) = a.poll_transmit(now) {
                        wire.push(e);
                    }
                    if wire.is_empty() {
                        break;
                    }
                    for e in wire.drain(..) {
                        if let Verdict::Pass(e) = b.inbound(e, now) {
                            delivered += black_box(e).payload.len();
                        }
                    }
                    while let Some(back) = b.poll_transmit(now) {
                        let _ = a.inbound(back, now);
                    }
                }
                delivered
        };
        group.bench_function(set, |bench| {
            if cpu {
                bench.iter_custom(|iters| {
                    let start = thread_cpu();
                    for _ in 0..iters {
                        black_box(one());
                    }
                    thread_cpu() - start
                })
            } else {
                bench.iter(&mut one)
            }
        });
        assert_eq!(b.counters().total(), 0, "{set}: {}", b.counters());
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
