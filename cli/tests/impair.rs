//! `intellwheels impair`: the seeded impairment proxy as a process, on real loopback sockets.

use std::process::{Command, Stdio};
use std::time::Duration;

use iw_bus::transport::FrameTransport;
use iw_transport_net::UdpTransport;

/// Receives until the link has been quiet for `quiet`.
fn drain(t: &UdpTransport, quiet: Duration) -> Vec<Vec<u8>> {
    let mut got = Vec::new();
    while let Some((_, frame)) = t.recv_timeout(quiet).unwrap() {
        got.push(frame);
    }
    got
}

#[test]
fn the_impair_process_relays_and_reports_its_counters() {
    let a = UdpTransport::bind("127.0.0.1:0").unwrap();
    let b = UdpTransport::bind("127.0.0.1:0").unwrap();
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let listen = format!("127.0.0.1:{port}");
    let child = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
        .args([
            "impair",
            "--listen",
            &listen,
            "--seed",
            "5",
            "--drop",
            "0.5",
            "--duration-ms",
            "1500",
            "--report-ms",
            "10000",
        ])
        .args(["--a", &a.local_addr().0, "--b", &b.local_addr().0])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let proxy = iw_bus::transport::PeerAddr(listen);
    for i in 0..100u32 {
        a.send(&proxy, &i.to_be_bytes()).unwrap();
    }
    let got = drain(&b, Duration::from_millis(300));
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    let last = String::from_utf8(out.stdout).unwrap();
    let stats: serde_json::Value = serde_json::from_str(last.lines().last().unwrap()).unwrap();
    assert_eq!(stats["received"], 100);
    assert_eq!(stats["forwarded"].as_u64().unwrap(), got.len() as u64);
    assert!(
        (20..80).contains(&got.len()),
        "about half dropped, got {}",
        got.len()
    );
}

#[test]
fn the_impair_process_refuses_bad_settings() {
    let out = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
        .args([
            "impair",
            "--a",
            "127.0.0.1:1",
            "--b",
            "127.0.0.1:2",
            "--drop",
            "2",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("`drop` = 2"));
}
