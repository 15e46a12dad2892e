//! SL parse and print of a typical DF answer (a 489-byte `result` of a DF search, as JADE sent
//! in the wire captures), with serde_json reading the same tree as JSON as a peer in the same run.
//!
//! `cargo bench -p iw-sl --bench sl_parse`

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iw_sl::{Content, Level, parse};

const DF_RESULT: &str = "((result (action (agent-identifier :name df@WheelchairTest) (search (df-agent-description :services (set (service-description :type wheelchair-echo))) (search-constraints :max-results -1))) (sequence (df-agent-description :name (agent-identifier :name echo@WheelchairTest :addresses (sequence http://127.0.0.1:7778/acc)) :protocols (set fipa-request) :services (set (service-description :name echo-service :type wheelchair-echo :properties (set (property :name max-speed :value 1.5))))))))";

fn bench(c: &mut Criterion) {
    let content = parse(DF_RESULT, Level::Sl0).expect("bench input parses");
    let json = serde_json::to_string(&content).expect("serialises");
    let mut g = c.benchmark_group("sl");
    g.measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_secs(1));
    g.throughput(Throughput::Bytes(DF_RESULT.len() as u64));
    g.bench_function("parse_df_result_sl0", |b| {
        b.iter(|| parse(black_box(DF_RESULT), Level::Sl0))
    });
    g.bench_function("parse_df_result_full", |b| {
        b.iter(|| parse(black_box(DF_RESULT), Level::Full))
    });
    g.bench_function("print_df_result", |b| {
        b.iter(|| black_box(&content).to_string())
    });
    g.bench_function("peer_serde_json_same_tree", |b| {
        b.iter(|| serde_json::from_str::<Content>(black_box(&json)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
