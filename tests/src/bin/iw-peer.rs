//! The peer process of the EN 50159 system tests: agent `b` on a real UDP socket with all four
//! layers, echoing every accepted message back to `a`. Protocol: `iw_tests::peer`.

use std::collections::HashMap;
use std::io::{BufRead, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{Context, bail};
use hex::FromHex;
use iw_bus::transport::PeerAddr;
use iw_bus::{Bus, BusConfig, Clock};
use iw_stack::{Platform, StackConfig};
use iw_tests::peer::Report;
use iw_tests::{acl, number_of};
use iw_transport_net::UdpTransport;

fn main() -> std::process::ExitCode {
    match try_main() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("iw-peer: {e:#}");
            std::process::ExitCode::from(2)
        }
    }
}

fn try_main() -> anyhow::Result<()> {
    let platform = Platform::new();
    let node = platform.node(&["b"]).context("making b's identity")?;
    let transport = UdpTransport::bind("127.0.0.1:0").context("binding the UDP socket")?;
    let addr = transport
        .socket_addr()
        .context("reading the socket address")?;
    let stdout = std::io::stdout();
    writeln!(
        stdout.lock(),
        "READY {addr} {}",
        hex::encode(node.identity.public_key())
    )?;

    let mut lines = std::io::stdin().lock().lines();
    let peer_line = lines.next().context("stdin closed before PEER")??;
    let parts: Vec<&str> = peer_line.split_whitespace().collect();
    let [cmd, key, route] = parts.as_slice() else {
        bail!("expected `PEER <key> <addr>`, got `{peer_line}`")
    };
    if *cmd != "PEER" {
        bail!("expected PEER, got `{peer_line}`");
    }
    let key_a = <[u8; 32]>::from_hex(key).with_context(|| format!("bad key `{key}`"))?;
    platform.register("a", key_a);

    let mut cfg = StackConfig::default();
    cfg.comm.max_attempts = 40;
    cfg.comm.initial_rto = Duration::from_millis(10);
    cfg.comm.max_rto = Duration::from_millis(200);
    let stack = platform.stack(&node, &cfg);
    let bus = Arc::new(Bus::start(
        stack,
        Arc::new(transport),
        Clock::system(),
        BusConfig::default(),
    )?);
    bus.add_route("a", PeerAddr(route.to_string()));
    let mut mailbox = bus.register("b")?;

    let stop = Arc::new(AtomicBool::new(false));
    let worker = {
        let (bus, stop) = (bus.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut seen: HashMap<u64, u64> = HashMap::new();
            let mut report = Report::default();
            while !stop.load(Ordering::Acquire) {
                // Waiting here, this thread receives from the socket itself (and sends the
                // acknowledgements and retransmissions due meanwhile).
                let Some(env) = mailbox.recv_timeout(Duration::from_millis(5)) else {
                    continue;
                };
                report.delivered += 1;
                // Genuine means: from `a`, and byte for byte the message `a` sends with that number.
                let genuine = number_of(&env.payload)
                    .filter(|n| env.header.sender == "a" && env.payload == acl("a", "b", *n));
                match genuine {
                    Some(n) => {
                        *seen.entry(n).or_default() += 1;
                        if let Err(e) = bus.send("b", "a", acl("b", "a", n)) {
                            eprintln!("iw-peer: echo {n}: {e}");
                        }
                    }
                    None => report.foreign += 1,
                }
            }
            report.unique = seen.len() as u64;
            report.duplicates = seen.values().filter(|c| **c > 1).count() as u64;
            report
        })
    };
    for line in lines {
        if line?.trim() == "REPORT" {
            break;
        }
    }
    stop.store(true, Ordering::Release);
    let mut report = worker
        .join()
        .map_err(|_| anyhow::anyhow!("worker thread panicked"))?;
    report.counters = bus.counters().to_string();
    writeln!(stdout.lock(), "{}", report.to_line())?;
    Ok(())
}
