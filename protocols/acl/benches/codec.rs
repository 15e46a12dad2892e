//! ACL string codec speed: parse and print of JADE's timing message (`bench-message-470B.acl`)
//! and of a typical ~380-byte INFORM reply. JADE 4.6.5 on the same 470 bytes: 55 k decodes/s,
//! 405 k encodes/s (shared/fipa/README.md). Peer measured in the same run: serde_json reading
//! the same message as JSON (`json-peer`), a well-tuned parser on the same data.
//!
//! `cargo bench -p iw-acl --bench codec`

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iw_acl::codec::{self, ParseOptions, PrintOptions};

/// An INFORM answering a wheelchair's pose query: the common case on the platform's bus.
const TYPICAL: &str = r#"(INFORM
 :sender (agent-identifier :name localization@IntellWheels :addresses (sequence http://10.0.0.2:7778/acc))
 :receiver (set (agent-identifier :name planner@IntellWheels))
 :content "((= (iota ?p (pose wheelchair1 ?p)) (pose :x 3.25 :y -1.5 :theta 0.785)))"
 :language fipa-sl :ontology wheelchair-ontology :protocol fipa-query
 :conversation-id conv-4711 :in-reply-to q-4711)"#;

fn bench(c: &mut Criterion) {
    let mut inputs = vec![("typical-380B", TYPICAL.to_owned())];
    if let Some(path) = iw_testdata::require("acl codec bench", "fipa/vectors/bench-message-470B.acl") {
        inputs.insert(0, ("jade-470B", std::fs::read_to_string(path).expect("readable bench message")));
    }
    let mut group = c.benchmark_group("acl");
    group.measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    for (name, text) in &inputs {
        group.throughput(Throughput::Elements(1));
        let message = codec::parse(text).expect("bench message parses");
        group.bench_function(format!("parse/{name}/{}B", text.len()), |b| b.iter(|| codec::parse(black_box(text))));
        let jade = ParseOptions::jade();
        group.bench_function(format!("parse-jade/{name}"), |b| b.iter(|| codec::parse_with(black_box(text), &jade)));
        let json = serde_json::to_string(&message).expect("serializable");
        group.bench_function(format!("json-peer-parse/{name}/{}B", json.len()), |b| {
            b.iter(|| serde_json::from_str::<iw_acl::AclMessage>(black_box(&json)))
        });
        group.bench_function(format!("print/{name}"), |b| b.iter(|| codec::print(black_box(&message))));
        let mut buffer = String::with_capacity(1024);
        let options = PrintOptions::default();
        group.bench_function(format!("print-into-reused-buffer/{name}"), |b| {
            b.iter(|| {
                buffer.clear();
                codec::print_into(black_box(&message), &mut buffer, &options)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
