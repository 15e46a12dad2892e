//! The server under a hostile peer: a flood of held connections is capped per source and in
//! total while other peers are still served, and a request trickled a byte at a time is cut at
//! the request timeout, not kept alive by every byte.

use std::net::SocketAddr;
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::{MtpClient, MtpServer, ServerLimits};
use iw_net_probe::{closed_within, connect_from, loopback};
use tokio::io::AsyncWriteExt;
use tokio::sync::mpsc;

/// Generous bound for what must happen on a loaded machine; never the expected time.
const PATIENCE: Duration = Duration::from_secs(20);

async fn server(limits: ServerLimits) -> (MtpServer, mpsc::Receiver<iw_mtp_http::Delivery>) {
    let (tx, rx) = mpsc::channel(16);
    let addr = SocketAddr::new(loopback(1), 0);
    let server = MtpServer::bind_with_limits(addr, None, tx, limits)
        .await
        .unwrap();
    (server, rx)
}

fn message() -> AclMessage {
    AclMessage::new(Performative::Inform)
        .with_sender(AgentId::new("a@P").with_address("http://127.0.0.1:1/acc"))
        .with_receiver(AgentId::new("b@Q"))
        .with_content("still served")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn held_connections_are_capped_per_source_and_in_total_and_others_are_served() {
    let limits = ServerLimits {
        max_connections: 3,
        max_per_source: 2,
        request_timeout: Duration::from_secs(60),
    };
    let (server, mut rx) = server(limits).await;
    let to = server.local_addr();
    // One source holds its two connections, silent.
    let mut held = vec![
        connect_from(loopback(2), to).await.unwrap(),
        connect_from(loopback(2), to).await.unwrap(),
    ];
    let mut third = connect_from(loopback(2), to).await.unwrap();
    assert!(
        closed_within(&mut third, PATIENCE).await,
        "a source's third connection is closed at accept"
    );
    for stream in &mut held {
        assert!(
            !closed_within(stream, Duration::from_millis(200)).await,
            "connections within the cap stay open"
        );
    }
    // Another source takes the last slot; a fourth source then finds the cap reached.
    held.push(connect_from(loopback(3), to).await.unwrap());
    let mut over = connect_from(loopback(4), to).await.unwrap();
    assert!(
        closed_within(&mut over, PATIENCE).await,
        "a connection over the total cap is closed at accept"
    );
    // A slot given back is taken again: a client from a quiet source is served.
    drop(held.pop());
    let client = MtpClient::new();
    let mut sent = Err(None);
    let started = std::time::Instant::now();
    while started.elapsed() < PATIENCE {
        match client
            .send(&server.url(), &message(), vec![AgentId::new("b@Q")])
            .await
        {
            Ok(()) => {
                sent = Ok(());
                break;
            }
            Err(e) => sent = Err(Some(e.to_string())),
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert_eq!(sent, Ok(()), "a peer within the caps is served");
    let delivered = rx.recv().await.unwrap();
    assert_eq!(delivered.message.content_text(), Some("still served"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_trickled_a_byte_at_a_time_is_cut_at_the_request_timeout() {
    let limits = ServerLimits {
        request_timeout: Duration::from_secs(1),
        ..ServerLimits::default()
    };
    let (server, _rx) = server(limits).await;
    let mut stream = connect_from(loopback(5), server.local_addr())
        .await
        .unwrap();
    let head = b"POST /acc HTTP/1.1\r\nHost: x\r\nX-Slow: ".repeat(100);
    let started = std::time::Instant::now();
    let mut cut = false;
    for byte in head.iter().cycle() {
        // One byte every 100 ms: far inside any silence timer, far outside the request timeout.
        if stream.write_all(&[*byte]).await.is_err()
            || closed_within(&mut stream, Duration::from_millis(100)).await
        {
            cut = true;
            break;
        }
        if started.elapsed() > PATIENCE {
            break;
        }
    }
    assert!(
        cut,
        "a trickled request still held its connection after {:?}",
        started.elapsed()
    );
}
