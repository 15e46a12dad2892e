//! `intellwheels impair`: the seeded UDP impairment proxy as a process of its own.
//!
//! Relays datagrams between loopback endpoints `--a` and `--b` (both send to `--listen`), applying
//! the faults given as probabilities, and prints its counters as one JSON object per line every
//! `--report-ms` and once more at the end.

use std::net::SocketAddr;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Parser;
use iw_transport_net::{ImpairConfig, ImpairProxy};

/// Relay UDP datagrams between two loopback endpoints, injecting seeded faults.
#[derive(Parser, Debug)]
pub struct Args {
    /// Address the proxy listens on (loopback).
    #[arg(long, default_value = "127.0.0.1:0")]
    listen: SocketAddr,
    /// Endpoint `a` (loopback `ip:port`).
    #[arg(long)]
    a: SocketAddr,
    /// Endpoint `b` (loopback `ip:port`).
    #[arg(long)]
    b: SocketAddr,
    /// Seed of the fault stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Probability a datagram is lost.
    #[arg(long, default_value_t = 0.0)]
    drop: f64,
    /// Probability a datagram is forwarded twice.
    #[arg(long, default_value_t = 0.0)]
    duplicate: f64,
    /// Probability a datagram is held back and overtaken by the next one.
    #[arg(long, default_value_t = 0.0)]
    reorder: f64,
    /// Probability 1 to 3 bytes of a datagram are flipped.
    #[arg(long, default_value_t = 0.0)]
    corrupt: f64,
    /// Probability a datagram is delayed.
    #[arg(long, default_value_t = 0.0)]
    delay: f64,
    /// Shortest added delay, ms.
    #[arg(long, default_value_t = 5)]
    delay_min_ms: u64,
    /// Longest added delay, ms.
    #[arg(long, default_value_t = 20)]
    delay_max_ms: u64,
    /// Probability a forged datagram is inserted.
    #[arg(long, default_value_t = 0.0)]
    inject_forged: f64,
    /// Probability an earlier datagram is replayed.
    #[arg(long, default_value_t = 0.0)]
    inject_replay: f64,
    /// Stop after this many ms (0 = run until killed).
    #[arg(long, default_value_t = 0)]
    duration_ms: u64,
    /// Print the counters every this many ms, 100 to 3600000 (an hour): a shorter period floods
    /// the output, a longer one never reports.
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(REPORT_MS))]
    report_ms: u64,
}

/// The `--report-ms` accepted.
const REPORT_MS: std::ops::RangeInclusive<u64> = 100..=3_600_000;

/// Runs the proxy until `--duration-ms` passes (or until killed), printing its counters.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let config = ImpairConfig {
        seed: args.seed,
        drop: args.drop,
        duplicate: args.duplicate,
        reorder: args.reorder,
        corrupt: args.corrupt,
        delay: args.delay,
        delay_min: Duration::from_millis(args.delay_min_ms),
        delay_max: Duration::from_millis(args.delay_max_ms),
        inject_forged: args.inject_forged,
        inject_replay: args.inject_replay,
        ..ImpairConfig::default()
    };
    let proxy =
        ImpairProxy::start_on(args.listen, args.a, args.b, config).context("starting the proxy")?;
    eprintln!("intellwheels impair: listening on {}", proxy.addr());
    let started = Instant::now();
    let report = Duration::from_millis(args.report_ms);
    let mut last_report = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(10));
        if args.duration_ms > 0 && started.elapsed() >= Duration::from_millis(args.duration_ms) {
            break;
        }
        if last_report.elapsed() >= report {
            println!("{}", serde_json::to_string(&proxy.stats())?);
            last_report = Instant::now();
        }
    }
    println!("{}", serde_json::to_string(&proxy.stop())?);
    Ok(ExitCode::SUCCESS)
}
