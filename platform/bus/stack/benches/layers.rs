//! Cost of each bus layer, and of all four, on a 300-byte FIPA-ACL message, in process:
//! one message sent by stack A and received by stack B, acknowledgement included.
//!
//! Group `layers_300B` is wall time; `layers_300B_cpu` the bench thread's CPU time.
//!
//! Container control frames are timed beside their code: `cargo bench -p iw-container --bench
//! control_frame`.
//!
//! Run: `cargo bench -p iw-stack --bench layers` (or build it with `--profile test` and run the
//! binary with `--bench`)

mod common;

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iw_bench_clock::cpu_iter;

fn bench(c: &mut Criterion) {
    for cpu in [false, true] {
        run(c, cpu);
    }
}

fn run(c: &mut Criterion, cpu: bool) {
    let mut group = c.benchmark_group(if cpu {
        "layers_300B_cpu"
    } else {
        "layers_300B"
    });
    group.throughput(Throughput::Elements(1));
    group.measurement_time(Duration::from_secs(3));
    group.warm_up_time(Duration::from_secs(1));
    for set in ["none", "comm", "security", "temporal", "parser", "all"] {
        let mut exchange = common::Exchange::new(set);
        let mut one = || exchange.one();
        group.bench_function(set, |bench| {
            if cpu {
                cpu_iter(bench, &mut one)
            } else {
                bench.iter(&mut one)
            }
        });
        assert_eq!(
            exchange.rejected().total(),
            0,
            "{set}: {}",
            exchange.rejected()
        );
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
