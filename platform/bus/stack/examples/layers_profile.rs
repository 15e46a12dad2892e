//! The per-message loop of `benches/layers.rs`, without criterion, for profilers:
//! `cargo build --release -p iw-stack --example layers_profile` then
//! `valgrind --tool=callgrind target/release/examples/layers_profile all 20000`.
//! Arguments: layer set (default `all`), messages (default 100000).

#[path = "../benches/common/mod.rs"]
mod common;

fn main() {
    let mut args = std::env::args().skip(1);
    let set = args.next().unwrap_or_else(|| "all".into());
    let n: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let mut exchange = common::Exchange::new(&set);
    let delivered: usize = (0..n).map(|_| exchange.one()).sum();
    assert_eq!(exchange.rejected().total(), 0, "{}", exchange.rejected());
    println!("{set}: {n} messages, {delivered} bytes delivered");
}
