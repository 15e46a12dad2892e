//! ACL string codec speed: parse, check and print of JADE's timing message
//! (`bench-message-470B.acl`), of a typical ~380-byte INFORM reply and of a 300-byte REQUEST as
//! the bus benches send. `check` is `codec::check_with`, the parser layer's well-formedness and
//! sender/receiver check, which reads the same grammar without building the message. JADE 4.6.5 on the same 470 bytes: 55 k decodes/s,
//! 405 k encodes/s (shared/fipa/README.md). Peer measured in the same run: serde_json reading
//! the same message as JSON (`json-peer`), a well-tuned parser on the same data.
//!
//! Two groups over the same cases: `acl` in wall time, `acl-cpu` in the bench thread's CPU time
//! (`CLOCK_THREAD_CPUTIME_ID`), which leaves out the time other processes hold the core: on a
//! shared, loaded machine it is the figure that says what one core does.
//!
//! `cargo bench -p iw-acl --bench codec`

use std::hint::black_box;
use std::time::Duration;

use criterion::measurement::{Measurement, ValueFormatter, WallTime};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use iw_acl::codec::{self, ParseOptions, PrintOptions};

/// An INFORM answering a wheelchair's pose query: the common case on the platform's bus.
const TYPICAL: &str = r#"(INFORM
 :sender (agent-identifier :name localization@IntellWheels :addresses (sequence http://10.0.0.2:7778/acc))
 :receiver (set (agent-identifier :name planner@IntellWheels))
 :content "((= (iota ?p (pose wheelchair1 ?p)) (pose :x 3.25 :y -1.5 :theta 0.785)))"
 :language fipa-sl :ontology wheelchair-ontology :protocol fipa-query
 :conversation-id conv-4711 :in-reply-to q-4711)"#;

/// The bus benches' message: a REQUEST from `ping` to `echo` with its content padded to 300 bytes.
fn bus_message() -> String {
    let head = "(request :sender (agent-identifier :name ping) :receiver (set (agent-identifier :name echo)) \
                :language fipa-sl :ontology wheelchair :conversation-id bench :content \"";
    let text = format!("{head}{}\")", "x".repeat(300 - head.len() - 2));
    assert_eq!(text.len(), 300);
    text
}

/// The calling thread's CPU time in nanoseconds.
struct ThreadCpuTime;

fn thread_cpu_ns() -> u64 {
    u64::try_from(iw_bench_clock::thread_cpu().as_nanos()).unwrap_or(u64::MAX)
}

impl Measurement for ThreadCpuTime {
    type Intermediate = u64;
    type Value = u64;

    fn start(&self) -> u64 {
        thread_cpu_ns()
    }
    fn end(&self, start: u64) -> u64 {
        thread_cpu_ns().saturating_sub(start)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, value: &u64) -> f64 {
        *value as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        self
    }
}

impl ValueFormatter for ThreadCpuTime {
    fn scale_values(&self, _typical_ns: f64, _values: &mut [f64]) -> &'static str {
        "ns (cpu)"
    }
    fn scale_throughputs(
        &self,
        _typical_ns: f64,
        throughput: &Throughput,
        values: &mut [f64],
    ) -> &'static str {
        let (per, unit) = match throughput {
            Throughput::Bytes(n) | Throughput::BytesDecimal(n) => (*n as f64, "B/s (cpu)"),
            Throughput::Elements(n) => (*n as f64, "elem/s (cpu)"),
            Throughput::Bits(n) => (*n as f64, "bit/s (cpu)"),
        };
        values.iter_mut().for_each(|v| *v = per * 1e9 / *v);
        unit
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns"
    }
}

fn bench_wall(c: &mut Criterion<WallTime>) {
    bench(c, "acl");
}

fn bench_cpu(c: &mut Criterion<ThreadCpuTime>) {
    bench(c, "acl-cpu");
}

fn bench<M: Measurement>(c: &mut Criterion<M>, group_name: &str) {
    let mut inputs = vec![
        ("typical-380B", TYPICAL.to_owned()),
        ("bus-300B", bus_message()),
    ];
    if let Some(path) =
        iw_testdata::require("acl codec bench", "fipa/vectors/bench-message-470B.acl")
    {
        inputs.insert(
            0,
            (
                "jade-470B",
                std::fs::read_to_string(path).expect("readable bench message"),
            ),
        );
    }
    let mut group = c.benchmark_group(group_name);
    group
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1));
    for (name, text) in &inputs {
        group.throughput(Throughput::Elements(1));
        let message = codec::parse(text).expect("bench message parses");
        group.bench_function(format!("parse/{name}/{}B", text.len()), |b| {
            b.iter(|| codec::parse(black_box(text)))
        });
        let jade = ParseOptions::jade();
        group.bench_function(format!("parse-jade/{name}"), |b| {
            b.iter(|| codec::parse_with(black_box(text), &jade))
        });
        let standard = ParseOptions::default();
        group.bench_function(format!("check/{name}"), |b| {
            b.iter(|| codec::check_with(black_box(text), &standard))
        });
        group.bench_function(format!("check-jade/{name}"), |b| {
            b.iter(|| codec::check_with(black_box(text), &jade))
        });
        let json = serde_json::to_string(&message).expect("serializable");
        group.bench_function(format!("json-peer-parse/{name}/{}B", json.len()), |b| {
            b.iter(|| serde_json::from_str::<iw_acl::AclMessage>(black_box(&json)))
        });
        group.bench_function(format!("print/{name}"), |b| {
            b.iter(|| codec::print(black_box(&message)))
        });
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

criterion_group!(wall, bench_wall);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = bench_cpu
}
criterion_main!(wall, cpu);
