//! TLS between two of our platforms (self-signed certificate made with rcgen), and the client's
//! HTTP keep-alive against servers that allow it (ours) and that close (JADE's).

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use iw_acl::codec::print;
use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::platform::Echo;
use iw_mtp_http::tls::pki_types::{CertificateDer, PrivateKeyDer, PrivatePkcs8KeyDer};
use iw_mtp_http::{GatewayConfig, HttpPlatform, MtpClient, tls, wire};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;
use tokio::time::timeout;

const WAIT: Duration = Duration::from_secs(10);
const STEP: Duration = Duration::from_micros(200);

fn self_signed() -> (CertificateDer<'static>, PrivateKeyDer<'static>) {
    let cert = rcgen::generate_simple_self_signed(vec!["127.0.0.1".to_owned()]).unwrap();
    let key = PrivatePkcs8KeyDer::from(cert.key_pair.serialize_der());
    (cert.cert.der().clone(), key.into())
}

fn tls_config(
    platform: &str,
    cert: &CertificateDer<'static>,
    key: &PrivateKeyDer<'static>,
) -> GatewayConfig {
    let mut config = GatewayConfig::new(platform);
    config.tls = Some(tls::server_config(vec![cert.clone()], key.clone_key()).unwrap());
    config.client = MtpClient::with_tls(tls::client_config(std::slice::from_ref(cert)).unwrap());
    config
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn platforms_talk_over_tls() {
    let (cert, key) = self_signed();
    let echo: Box<dyn iw_agent::Agent> = Box::new(Echo);
    let jade_like = HttpPlatform::start(
        tls_config("WheelchairTest", &cert, &key),
        vec![("echo".into(), echo)],
        STEP,
    )
    .await
    .unwrap();
    let ours = HttpPlatform::start(tls_config("RustPlatform", &cert, &key), Vec::new(), STEP)
        .await
        .unwrap();
    assert!(jade_like.gateway().url().starts_with("https://127.0.0.1:"));
    let me = ours.gateway().aid("wheelchair1");
    let mut inbox = ours.bus().register(&me.name).unwrap();
    let echo = jade_like.gateway().aid("echo");
    ours.gateway().add_foreign(&echo).unwrap();
    let request = AclMessage::new(Performative::Request)
        .with_sender(me.clone())
        .with_receiver(echo.clone())
        .with_content("((action (agent-identifier :name echo@WheelchairTest) (stop)))")
        .with_protocol("fipa-request")
        .with_conversation_id("tls-1");
    ours.bus()
        .send(&me.name, &echo.name, print(&request).into_bytes())
        .unwrap();
    let mut answers = Vec::new();
    for _ in 0..2 {
        let envelope = timeout(WAIT, inbox.recv())
            .await
            .expect("an answer over TLS")
            .unwrap();
        answers.push(
            iw_acl::codec::parse(envelope.payload_str().unwrap())
                .unwrap()
                .performative,
        );
    }
    assert_eq!(answers, [Performative::Agree, Performative::Inform]);

    // Without trusted roots, or trusting another certificate, nothing is sent.
    let plain = MtpClient::new()
        .send(&jade_like.gateway().url(), &request, vec![echo.clone()])
        .await
        .unwrap_err();
    assert!(
        plain
            .to_string()
            .contains("https:// needs a client with trusted roots"),
        "{plain}"
    );
    let (other, _) = self_signed();
    let wrong = MtpClient::with_tls(tls::client_config(&[other]).unwrap());
    let refused = wrong
        .send(&jade_like.gateway().url(), &request, vec![echo])
        .await
        .unwrap_err();
    assert!(
        refused.to_string().starts_with("TLS: handshake"),
        "{refused}"
    );
}

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
