//! Replays JADE's captured posts (shared `fipa/wire/`) against our server and checks that our
//! client writes what JADE accepts; then two of our platforms talk over loopback HTTP.

use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::server::LOOPBACK;
use iw_mtp_http::{Envelope, Gateway, MtpClient, wire};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::time::timeout;

const WAIT: Duration = Duration::from_secs(10);

async fn post_raw(url: &str, bytes: &[u8]) -> Vec<u8> {
    let target = wire::Url::parse(url).unwrap();
    let mut stream = TcpStream::connect((target.host.as_str(), target.port)).await.unwrap();
    stream.write_all(bytes).await.unwrap();
    let mut answer = Vec::new();
    timeout(WAIT, stream.read_to_end(&mut answer)).await.expect("server answered").unwrap();
    answer
}

/// Echo agent as JADE's in the captures: REQUEST -> AGREE + INFORM done, QUERY-REF -> INFORM.
fn spawn_echo(gateway: std::sync::Arc<Gateway>) {
    let mut inbox = gateway.register("echo");
    tokio::spawn(async move {
        while let Some(msg) = inbox.recv().await {
            let me = gateway.aid("echo");
            let reply = msg.create_reply().with_sender(me);
            let replies = match msg.performative {
                Performative::Request => vec![
                    reply.clone().with_performative(Performative::Agree),
                    reply.with_performative(Performative::Inform).with_content(format!(
                        "((done {}))",
                        msg.content_text().unwrap_or("").trim().strip_prefix('(').and_then(|c| c.strip_suffix(')')).unwrap_or("")
                    )),
                ],
                Performative::QueryRef => vec![reply.with_performative(Performative::Inform).with_content("echo")],
                _ => vec![],
            };
            for r in replies {
                gateway.send(r).await.unwrap();
            }
        }
    });
}

#[tokio::test]
async fn replays_every_captured_request() {
    let Some(dir) = iw_testdata::require("replays_every_captured_request", "fipa/wire/to-jade") else { return };
    let gateway = Gateway::start("WheelchairTest", LOOPBACK).await.unwrap();
    spawn_echo(gateway.clone());
    let mut files: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    let mut replayed = 0;
    for request in files.iter().filter(|p| p.to_string_lossy().ends_with(".request.raw")) {
        let bytes = std::fs::read(request).unwrap();
        let answer = String::from_utf8(post_raw(&gateway.url(), &bytes).await).unwrap();
        let name = request.file_name().unwrap().to_string_lossy().to_string();
        let jade_answer = std::fs::read_to_string(request.with_file_name(name.replace(".request.raw", ".jade-http-response.raw"))).unwrap();
        if jade_answer.starts_with("HTTP/1.1 200 OK") {
            assert!(answer.starts_with("HTTP/1.1 200 OK\r\n"), "{name}: {answer}");
            assert!(answer.contains("\r\nContent-Length: 0\r\n"), "{name}: {answer}");
            assert!(answer.ends_with("\r\n\r\n"), "{name}");
        } else {
            // JADE drops (08) or never answers (09); we refuse clearly.
            assert!(answer.starts_with("HTTP/1.1 400 "), "{name}: {answer}");
        }
        replayed += 1;
    }
    assert_eq!(replayed, 9);
}

#[tokio::test]
async fn decodes_every_jade_post() {
    let Some(dir) = iw_testdata::require("decodes_every_jade_post", "fipa/wire/from-jade") else { return };
    for entry in std::fs::read_dir(&dir).unwrap() {
        let bytes = std::fs::read(entry.unwrap().path()).unwrap();
        let end = wire::find_head_end(&bytes).unwrap().unwrap();
        let head = wire::parse_request_head(&bytes[..end]).unwrap();
        assert!(head.target.starts_with("http://127.0.0.1:9000/acc"));
        let delivery = iw_mtp_http::server::decode(&head, &bytes[end..]).unwrap();
        assert_eq!(delivery.envelope.receivers()[0].name, "wheelchair1@RustPlatform");
        assert!(delivery.envelope.date.is_some());
        assert_eq!(delivery.message.receivers[0].name, "wheelchair1@RustPlatform");
    }
}

#[test]
fn client_writes_what_jade_accepts() {
    let Some(path) = iw_testdata::require("client_writes_what_jade_accepts", "fipa/wire/to-jade/01-request.request.raw") else { return };
    let jade = std::fs::read(path).unwrap();
    let echo = AgentId::new("echo@WheelchairTest").with_address("http://127.0.0.1:7778/acc");
    let msg = AclMessage::new(Performative::Request)
        .with_sender(AgentId::new("wheelchair1@RustPlatform").with_address("http://127.0.0.1:9000/acc"))
        .with_receiver(echo.clone())
        .with_content("((action (agent-identifier :name echo@WheelchairTest) (move-to :room kitchen)))")
        .with_protocol("fipa-request");
    let ours = MtpClient::encode("http://127.0.0.1:7778/acc", &msg, vec![echo]).unwrap();
    let header_names = |b: &[u8]| -> Vec<String> {
        let end = wire::find_head_end(b).unwrap().unwrap();
        String::from_utf8_lossy(&b[..end]).split("\r\n").map(|l| l.split([':', ' ']).next().unwrap().to_owned()).collect()
    };
    assert_eq!(header_names(&ours), header_names(&jade));
    let text = String::from_utf8(ours.clone()).unwrap();
    assert!(text.starts_with("POST http://127.0.0.1:7778/acc HTTP/1.1\r\n"));
    assert!(text.contains("Content-Type: multipart/mixed ; boundary=\""));
    assert!(!text.replace("\r\n", "").contains('\r'));
    let end = wire::find_head_end(&ours).unwrap().unwrap();
    let head = wire::parse_request_head(&ours[..end]).unwrap();
    assert_eq!(head.content_length, ours.len() - end);
    let boundary = wire::boundary_of(head.content_type.as_deref().unwrap()).unwrap();
    let (env, payload) = wire::split_multipart(&ours[end..], boundary).unwrap();
    let env = Envelope::from_xml(std::str::from_utf8(env).unwrap()).unwrap();
    assert_eq!(env.payload_length, Some(payload.len()));
    assert_eq!(env.payload_encoding, None);
    assert!(text.ends_with(&format!("\r\n--{boundary}--\r\n")));
}

#[tokio::test]
async fn two_platforms_request_and_unknown_receiver() {
    let jade_like = Gateway::start("WheelchairTest", LOOPBACK).await.unwrap();
    spawn_echo(jade_like.clone());
    let ours = Gateway::start("RustPlatform", LOOPBACK).await.unwrap();
    let mut inbox = ours.register("wheelchair1");
    let echo = AgentId::new("echo@WheelchairTest").with_address(jade_like.url());
    let request = AclMessage::new(Performative::Request)
        .with_sender(ours.aid("wheelchair1"))
        .with_receiver(echo)
        .with_content("((action (agent-identifier :name echo@WheelchairTest) (move-to :room kitchen)))")
        .with_protocol("fipa-request")
        .with_conversation_id("conv-0001")
        .with_reply_with("req-0001");
    ours.send(request).await.unwrap();
    let agree = timeout(WAIT, inbox.recv()).await.unwrap().unwrap();
    let inform = timeout(WAIT, inbox.recv()).await.unwrap().unwrap();
    assert_eq!((agree.performative, inform.performative), (Performative::Agree, Performative::Inform));
    assert_eq!(inform.conversation_id.as_deref(), Some("conv-0001"));
    assert!(inform.content_text().unwrap().starts_with("((done (action"));

    let nobody = AgentId::new("nobody@WheelchairTest").with_address(jade_like.url());
    let hello = AclMessage::new(Performative::Inform).with_sender(ours.aid("wheelchair1")).with_receiver(nobody).with_content("hello");
    ours.send(hello).await.unwrap();
    let failure = timeout(WAIT, inbox.recv()).await.unwrap().unwrap();
    assert_eq!(failure.performative, Performative::Failure);
    assert_eq!(failure.sender.as_ref().unwrap().name, "ams@WheelchairTest");
    assert!(failure.content_text().unwrap().contains("MTS-error"));
    assert!(failure.content_text().unwrap().contains("Agent not found: nobody@WheelchairTest"));

    // A foreign receiver without an address cannot be reached.
    let lost = AclMessage::new(Performative::Inform).with_sender(ours.aid("wheelchair1")).with_receiver(AgentId::new("x@Elsewhere"));
    assert!(ours.send(lost).await.unwrap_err().to_string().contains("Foreign agent unreachable"));
}
