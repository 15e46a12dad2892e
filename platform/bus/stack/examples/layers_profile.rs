//! The per-message loop of `benches/layers.rs`, without criterion, for profilers:
//! `cargo build --release -p iw-stack --example layers_profile` then
//! `valgrind --tool=callgrind target/release/examples/layers_profile all 20000`.
//! Arguments: layer set (default `all`), messages (default 100000).

use std::hint::black_box;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_bus::{Envelope, Layer, MsgId, Time, Verdict};
use iw_stack::{Platform, StackConfig};

fn message() -> Vec<u8> {
    let base = AclMessage::new(Performative::Inform)
        .with_sender(AgentId::new("a"))
        .with_receiver(AgentId::new("b"))
        .with_ontology("intellwheels")
        .with_conversation_id("c-1");
    let empty = iw_acl::codec::print(&base.clone().with_content("")).len();
    iw_acl::codec::print(&base.with_content("x".repeat(300 - empty))).into_bytes()
}

fn main() {
    let mut args = std::env::args().skip(1);
    let set = args.next().unwrap_or_else(|| "all".into());
    let n: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let payload = message();
    let platform = Platform::new();
    let na = platform.node(&["a"]).expect("identity");
    let nb = platform.node(&["b"]).expect("identity");
    let cfg = StackConfig::with_layers(set.parse().expect("layer set"));
    let (mut a, mut b) = (platform.stack(&na, &cfg), platform.stack(&nb, &cfg));
    let now = Time::from_ns(1_700_000_000_000_000_000);
    let mut delivered = 0usize;
    let mut wire = Vec::new();
    for id in 1..=n {
        let env = Envelope::new(MsgId(id), "a", "b", payload.clone());
        if let Verdict::Pass(e) = a.outbound(env, now) {
            wire.push(e);
        }
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
    }
    assert_eq!(b.counters().total(), 0, "{}", b.counters());
    println!("{set}: {n} messages, {delivered} bytes delivered");
}
