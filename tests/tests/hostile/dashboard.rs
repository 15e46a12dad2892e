//! A connection flood and a slowloris on the dashboard (loopback only, a few hundred connections,
//! over in seconds): the attacker's connections are refused or closed within the header timeout,
//! the server's descriptors stay bounded, and a client with the token from another address is
//! still served.

use std::net::{IpAddr, SocketAddr};
use std::time::{Duration, Instant};

use iw_dashboard::{ConnectionLimits, Dashboard, DashboardConfig, MapView};
use iw_net_probe::{closed_within, connect_from, loopback};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

const TOKEN: &str = "hostile-suite-token";

/// Tight limits so the suite is fast; the defaults differ only in scale.
fn limits() -> ConnectionLimits {
    ConnectionLimits {
        max_connections: 64,
        header_timeout: Duration::from_secs(1),
        http_timeout: Duration::from_secs(5),
        per_source_burst: 16,
        per_source_per_s: 4.0,
    }
}

fn start() -> Dashboard {
    let config = DashboardConfig {
        token: Some(TOKEN.into()),
        ..DashboardConfig::default()
    };
    Dashboard::start_with_limits(config, &MapView::default(), limits()).expect("start dashboard")
}

/// One complete GET from `source`; the reply, or what went wrong.
async fn get_from(source: IpAddr, to: SocketAddr, target: &str) -> String {
    let attempt = async {
        let mut stream = connect_from(source, to).await?;
        let request = format!("GET {target} HTTP/1.1\r\nHost: {to}\r\nConnection: close\r\n\r\n");
        stream.write_all(request.as_bytes()).await?;
        let mut reply = Vec::new();
        stream.read_to_end(&mut reply).await?;
        Ok::<_, std::io::Error>(String::from_utf8_lossy(&reply).into_owned())
    };
    match tokio::time::timeout(Duration::from_secs(5), attempt).await {
        Ok(Ok(reply)) => reply,
        Ok(Err(e)) => format!("error: {e}"),
        Err(_) => "error: timed out".into(),
    }
}

/// Asks until served or `within` passes: the first reply that is not a refusal.
async fn served_within(source: IpAddr, to: SocketAddr, within: Duration) -> String {
    let started = Instant::now();
    loop {
        let reply = get_from(source, to, &format!("/map.json?token={TOKEN}")).await;
        if reply.starts_with("HTTP/1.1 200") || started.elapsed() > within {
            return reply;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Sockets this process holds whose local end is the server's `port` (the accepted side; the
/// suite's other tests open descriptors too, so the process's total says nothing).
fn server_side_sockets(port: u16) -> usize {
    let inodes: std::collections::HashSet<String> = std::fs::read_dir("/proc/self/fd")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|fd| std::fs::read_link(fd.path()).ok())
        .filter_map(|link| {
            let link = link.to_string_lossy().into_owned();
            Some(
                link.strip_prefix("socket:[")?
                    .strip_suffix(']')?
                    .to_string(),
            )
        })
        .collect();
    let table = std::fs::read_to_string("/proc/net/tcp").unwrap_or_default();
    table
        .lines()
        .skip(1)
        .filter(|line| {
            let fields: Vec<&str> = line.split_whitespace().collect();
            let local_port = fields
                .get(1)
                .and_then(|a| a.rsplit(':').next())
                .and_then(|p| u16::from_str_radix(p, 16).ok());
            // State 0A is the listening socket itself.
            local_port == Some(port)
                && fields.get(3) != Some(&"0A")
                && fields.get(9).is_some_and(|inode| inodes.contains(*inode))
        })
        .count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_half_open_connections_is_bounded_and_others_are_served() {
    let dashboard = start();
    let addr = dashboard.addr();
    let limits = limits();

    // 300 connections from one source, each sending half a request and then nothing.
    let mut flood = Vec::new();
    for _ in 0..300 {
        if let Ok(mut stream) = connect_from(loopback(1), addr).await {
            let _ = stream
                .write_all(b"GET /map.json HTTP/1.1\r\nHost: x\r\n")
                .await;
            flood.push(stream);
        }
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let held_by_server = server_side_sockets(addr.port());
    println!(
        "flood: {} connections made, {held_by_server} descriptors held by the server",
        flood.len()
    );
    assert!(
        held_by_server <= limits.per_source_burst as usize + 8,
        "the server holds {held_by_server} descriptors for one source's flood"
    );

    // Another address with the token is served during the flood.
    let reply = served_within(loopback(2), addr, Duration::from_secs(3)).await;
    assert!(reply.starts_with("HTTP/1.1 200"), "{reply}");

    // Every flood connection is closed by the header timeout at the latest; none was served.
    let wait = limits.header_timeout + Duration::from_secs(2);
    for stream in &mut flood {
        assert!(
            closed_within(stream, wait).await,
            "a half-open connection outlived the timeout"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slowloris_from_many_addresses_is_cut_at_the_header_timeout() {
    let dashboard = start();
    let addr = dashboard.addr();
    let limits = limits();

    // 128 connections (twice the cap) from 64 addresses, each dribbling a header byte every
    // 100 ms for as long as the server lets it.
    let started = Instant::now();
    let mut dribblers = Vec::new();
    for i in 0..128u8 {
        let source = loopback(10 + i / 2);
        dribblers.push(tokio::spawn(async move {
            let Ok(mut stream) = connect_from(source, addr).await else {
                return Some(Duration::ZERO);
            };
            let opened = Instant::now();
            let header = b"GET / HTTP/1.1\r\nHost: x\r\nX-Slow: ";
            if stream.write_all(header).await.is_err() {
                return Some(opened.elapsed());
            }
            let mut buf = [0u8; 512];
            while opened.elapsed() < Duration::from_secs(8) {
                tokio::select! {
                    read = stream.read(&mut buf) => {
                        if matches!(read, Ok(0) | Err(_)) {
                            return Some(opened.elapsed());
                        }
                    }
                    _ = tokio::time::sleep(Duration::from_millis(100)) => {
                        if stream.write_all(b"a").await.is_err() {
                            return Some(opened.elapsed());
                        }
                    }
                }
            }
            None
        }));
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    // A client with the token gets in once the timeout has freed a slot.
    let reply = served_within(loopback(2), addr, limits.header_timeout * 4).await;
    assert!(reply.starts_with("HTTP/1.1 200"), "{reply}");

    let mut longest = Duration::ZERO;
    for dribbler in dribblers {
        let held = dribbler
            .await
            .expect("dribbler")
            .expect("a slowloris connection was never closed");
        longest = longest.max(held);
    }
    println!(
        "slowloris: longest connection held {longest:?} (header timeout {:?}); run took {:?}",
        limits.header_timeout,
        started.elapsed()
    );
    assert!(longest <= limits.header_timeout + Duration::from_secs(2));
}
