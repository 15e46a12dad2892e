//! Round trip over the FIPA HTTP MTP between two of our platforms on loopback, as JADE's figure
//! in `shared/fipa/README.md` (p50 851 us, p99 6.5 ms): `wheelchair1@RustPlatform` sends a
//! QUERY-REF to `echo@WheelchairTest`, whose INFORM comes back by a POST of its own. Each
//! platform steps its agents every 50 us; the messages are those of capture 02 (~450 bytes).
//!
//! Groups: `mtp_http/query_ref_inform` is the whole round trip (two posts, two bus hops, the
//! echo agent); `mtp_http/one_post_keepalive` and `mtp_http/one_post_new_connection` are the
//! peer in the same run: one post of the same message to a bare server answering 200, over a
//! kept-alive connection and over a new one each time. After criterion, the round trip is
//! timed one by one and its p50/p99 printed.
//!
//! Run: `cargo bench -p iw-node --bench mtp_round_trip`

use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use iw_acl::codec::print;
use iw_acl::{AclMessage, AgentId, Performative};
use iw_bus::Mailbox;
use iw_mtp_http::{GatewayConfig, MtpClient, MtpServer};
use iw_node::http_platform::{Echo, HttpPlatform};
use tokio::runtime::Runtime;
use tokio::sync::mpsc;

const STEP: Duration = Duration::from_micros(50);
const PERCENTILE_SAMPLES: usize = 2000;

struct Pair {
    _jade_like: HttpPlatform,
    ours: HttpPlatform,
    inbox: Mailbox,
    query: Vec<u8>,
    me: String,
    echo: String,
}

impl Pair {
    async fn start() -> Pair {
        let echo: Box<dyn iw_agent::Agent> = Box::new(Echo);
        let jade_like = HttpPlatform::start(
            GatewayConfig::new("WheelchairTest"),
            vec![("echo".into(), echo)],
            STEP,
        )
        .await
        .expect("platform");
        let ours = HttpPlatform::start(GatewayConfig::new("RustPlatform"), Vec::new(), STEP)
            .await
            .expect("platform");
        let me = ours.gateway().aid("wheelchair1");
        let inbox = ours.bus().register(&me.name).expect("mailbox");
        let echo = jade_like.gateway().aid("echo");
        ours.gateway().add_foreign(&echo).expect("proxy");
        let query = AclMessage::new(Performative::QueryRef)
            .with_sender(me.clone())
            .with_receiver(echo.clone())
            .with_content("((iota ?x (battery-level wheelchair1 ?x)))")
            .with_language("fipa-sl")
            .with_protocol("fipa-query")
            .with_conversation_id("conv-0002")
            .with_reply_with("q-1");
        Pair {
            _jade_like: jade_like,
            ours,
            inbox,
            query: print(&query).into_bytes(),
            me: me.name,
            echo: echo.name,
        }
    }

    async fn round_trip(&mut self) {
        self.ours
            .bus()
            .send(&self.me, &self.echo, self.query.clone())
            .expect("send");
        let answer = self.inbox.recv().await.expect("INFORM");
        assert!(
            answer
                .payload_str()
                .is_some_and(|p| p.starts_with("(INFORM"))
        );
    }
}

fn bench(c: &mut Criterion) {
    let rt = Runtime::new().expect("tokio runtime");
    let mut pair = rt.block_on(Pair::start());
    let mut group = c.benchmark_group("mtp_http");
    group.measurement_time(Duration::from_secs(4));
    group.warm_up_time(Duration::from_secs(1));
    group.sample_size(30);
    group.bench_function("query_ref_inform", |b| {
        b.iter(|| rt.block_on(pair.round_trip()))
    });

    let (tx, mut rx) = mpsc::channel(1024);
    let server = rt
        .block_on(MtpServer::bind(iw_mtp_http::server::LOOPBACK, None, tx))
        .expect("server");
    rt.spawn(async move { while rx.recv().await.is_some() {} });
    let message =
        iw_acl::codec::parse(std::str::from_utf8(&pair.query).expect("text")).expect("ACL");
    let to = vec![AgentId::new("echo@WheelchairTest")];
    let kept = MtpClient::new();
    group.bench_function("one_post_keepalive", |b| {
        b.iter(|| {
            rt.block_on(kept.send(&server.url(), &message, to.clone()))
                .expect("post")
        });
    });
    group.bench_function("one_post_new_connection", |b| {
        b.iter(|| {
            rt.block_on(MtpClient::new().send(&server.url(), &message, to.clone()))
                .expect("post")
        });
    });
    group.finish();

    let mut rtts: Vec<Duration> = (0..PERCENTILE_SAMPLES)
        .map(|_| {
            let start = Instant::now();
            rt.block_on(pair.round_trip());
            start.elapsed()
        })
        .collect();
    rtts.sort();
    let at = |q: f64| rtts[((rtts.len() - 1) as f64 * q) as usize].as_micros();
    println!(
        "mtp_http/query_ref_inform over {PERCENTILE_SAMPLES} round trips: p50 {} us, p99 {} us",
        at(0.5),
        at(0.99)
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
