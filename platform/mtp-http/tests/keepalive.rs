//! The client's HTTP keep-alive against servers that allow it (ours) and that close (JADE's).

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::{MtpClient, wire};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

/// A server that answers every post 200 and counts connections; `close` answers as JADE does.
async fn counting_server(close: bool) -> (String, Arc<AtomicUsize>, Arc<AtomicUsize>) {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("http://{}/acc", listener.local_addr().unwrap());
    let (connections, posts) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicUsize::new(0)));
    let (c, p) = (connections.clone(), posts.clone());
    tokio::spawn(async move {
        while let Ok((mut stream, _)) = listener.accept().await {
            c.fetch_add(1, Ordering::SeqCst);
            let p = p.clone();
            tokio::spawn(async move {
                let mut buf = Vec::new();
                let mut chunk = [0u8; 4096];
                loop {
                    let Some(end) = wire::find_head_end(&buf).unwrap() else {
                        match stream.read(&mut chunk).await {
                            Ok(0) | Err(_) => return,
                            Ok(n) => buf.extend_from_slice(&chunk[..n]),
                        }
                        continue;
                    };
                    let head = wire::parse_request_head(&buf[..end]).unwrap();
                    while buf.len() < end + head.content_length {
                        let n = stream.read(&mut chunk).await.unwrap();
                        assert!(n > 0, "body cut short");
                        buf.extend_from_slice(&chunk[..n]);
                    }
                    buf.drain(..end + head.content_length);
                    p.fetch_add(1, Ordering::SeqCst);
                    stream
                        .write_all(&wire::encode_response(200, "OK", close))
                        .await
                        .unwrap();
                    if close {
                        return;
                    }
                }
            });
        }
    });
    (url, connections, posts)
}

#[tokio::test]
async fn client_keeps_connections_alive_unless_told_to_close() {
    let message = AclMessage::new(Performative::Inform)
        .with_sender(AgentId::new("a@P").with_address("http://127.0.0.1:1/acc"))
        .with_receiver(AgentId::new("b@Q"))
        .with_content("hello");
    for (close, expected_connections) in [(false, 1), (true, 3)] {
        let (url, connections, posts) = counting_server(close).await;
        let client = MtpClient::new();
        for _ in 0..3 {
            client
                .send(&url, &message, vec![AgentId::new("b@Q")])
                .await
                .unwrap();
        }
        assert_eq!(posts.load(Ordering::SeqCst), 3);
        assert_eq!(
            connections.load(Ordering::SeqCst),
            expected_connections,
            "close = {close}"
        );
    }
}
