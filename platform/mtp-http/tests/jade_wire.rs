//! Replays JADE's captured posts (shared `fipa/wire/`) against our server and checks that our
//! client writes what JADE accepts; then two of our platforms talk over loopback HTTP.

use std::time::Duration;

use iw_acl::codec::{ParseOptions, parse_with, print};
use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::platform::Echo;
use iw_mtp_http::{Envelope, GatewayConfig, HttpPlatform, MtpClient, wire};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::time::timeout;

const WAIT: Duration = Duration::from_secs(10);
const STEP: Duration = Duration::from_micros(200);

async fn post_raw(url: &str, bytes: &[u8]) -> Vec<u8> {
    let target = wire::Url::parse(url).unwrap();
    let mut stream = TcpStream::connect((target.host.as_str(), target.port))
        .await
        .unwrap();
    stream.write_all(bytes).await.unwrap();
    let mut answer = Vec::new();
    timeout(WAIT, stream.read_to_end(&mut answer))
        .await
        .expect("server answered")
        .unwrap();
    answer
}

/// JADE's platform of the captures, as ours: AMS, DF and the echo agent.
async fn wheelchair_test() -> HttpPlatform {
    let echo: Box<dyn iw_agent::Agent> = Box::new(Echo);
    HttpPlatform::start(
        GatewayConfig::new("WheelchairTest"),
        vec![("echo".into(), echo)],
        STEP,
    )
    .await
    .unwrap()
}

#[tokio::test]
async fn replays_every_captured_request() {
    let Some(dir) = iw_testdata::require("replays_every_captured_request", "fipa/wire/to-jade")
    else {
        return;
    };
    let platform = wheelchair_test().await;
    let gateway = platform.gateway();
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let mut replayed = 0;
    for request in files
        .iter()
        .filter(|p| p.to_string_lossy().ends_with(".request.raw"))
    {
        let bytes = std::fs::read(request).unwrap();
        let answer = String::from_utf8(post_raw(&gateway.url(), &bytes).await).unwrap();
        let name = request.file_name().unwrap().to_string_lossy().to_string();
        let jade_answer = std::fs::read_to_string(
            request.with_file_name(name.replace(".request.raw", ".jade-http-response.raw")),
        )
        .unwrap();
        if jade_answer.starts_with("HTTP/1.1 200 OK") {
            assert!(
                answer.starts_with("HTTP/1.1 200 OK\r\n"),
                "{name}: {answer}"
            );
            assert!(
                answer.contains("\r\nContent-Length: 0\r\n"),
                "{name}: {answer}"
            );
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
    let Some(dir) = iw_testdata::require("decodes_every_jade_post", "fipa/wire/from-jade") else {
        return;
    };
    for entry in std::fs::read_dir(&dir).unwrap() {
        let bytes = std::fs::read(entry.unwrap().path()).unwrap();
        let end = wire::find_head_end(&bytes).unwrap().unwrap();
        let head = wire::parse_request_head(&bytes[..end]).unwrap();
        assert!(head.target.starts_with("http://127.0.0.1:9000/acc"));
        let delivery = iw_mtp_http::server::decode(&head, &bytes[end..]).unwrap();
        assert_eq!(
            delivery.envelope.receivers()[0].name,
            "wheelchair1@RustPlatform"
        );
        assert!(delivery.envelope.date.is_some());
        assert_eq!(
            delivery.message.receivers[0].name,
            "wheelchair1@RustPlatform"
        );
    }
}

#[test]
fn client_writes_what_jade_accepts() {
    let Some(path) = iw_testdata::require(
        "client_writes_what_jade_accepts",
        "fipa/wire/to-jade/01-request.request.raw",
    ) else {
        return;
    };
    let jade = std::fs::read(path).unwrap();
    let echo = AgentId::new("echo@WheelchairTest").with_address("http://127.0.0.1:7778/acc");
    let msg = AclMessage::new(Performative::Request)
        .with_sender(
            AgentId::new("wheelchair1@RustPlatform").with_address("http://127.0.0.1:9000/acc"),
        )
        .with_receiver(echo.clone())
        .with_content(
            "((action (agent-identifier :name echo@WheelchairTest) (move-to :room kitchen)))",
        )
        .with_protocol("fipa-request");
    let ours = MtpClient::encode("http://127.0.0.1:7778/acc", &msg, vec![echo]).unwrap();
    let header_names = |b: &[u8]| -> Vec<String> {
        let end = wire::find_head_end(b).unwrap().unwrap();
        String::from_utf8_lossy(&b[..end])
            .split("\r\n")
            .map(|l| l.split([':', ' ']).next().unwrap().to_owned())
            .collect()
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

/// The next message in `inbox`, within [`WAIT`].
async fn recv(inbox: &mut iw_bus::Mailbox) -> AclMessage {
    let envelope = timeout(WAIT, inbox.recv())
        .await
        .expect("an answer within the wait")
        .unwrap();
    iw_acl::codec::parse(envelope.payload_str().unwrap()).unwrap()
}

/// The ACL payload of a capture from JADE.
fn jade_says(relative: &str) -> AclMessage {
    let path = iw_testdata::require("jade_says", relative).unwrap();
    let bytes = std::fs::read(path).unwrap();
    let end = wire::find_head_end(&bytes).unwrap().unwrap();
    let head = wire::parse_request_head(&bytes[..end]).unwrap();
    iw_mtp_http::server::decode(&head, &bytes[end..])
        .unwrap()
        .message
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_captured_conversation_answers_like_jade() {
    if iw_testdata::require(
        "every_captured_conversation_answers_like_jade",
        "fipa/wire/acl",
    )
    .is_none()
    {
        return;
    }
    let jade_like = wheelchair_test().await;
    let rust = HttpPlatform::start(GatewayConfig::new("RustPlatform"), Vec::new(), STEP)
        .await
        .unwrap();
    let ours = rust.gateway().clone();
    // wheelchair1 is a bare mailbox on RustPlatform's bus, so the test reads what it receives.
    let me = ours.aid("wheelchair1");
    let mut inbox = rust.bus().register(&me.name).unwrap();
    let (jade_url, our_url) = (jade_like.gateway().url(), ours.url());
    let localise = |text: &str| {
        text.replace("http://127.0.0.1:7778/acc", &jade_url)
            .replace("http://127.0.0.1:9000/acc", &our_url)
    };
    let send = |case: &str| {
        let path = iw_testdata::require("captured", &format!("fipa/wire/acl/{case}.acl")).unwrap();
        let text = localise(&std::fs::read_to_string(path).unwrap());
        let mut message = parse_with(&text, &ParseOptions::jade()).unwrap();
        for receiver in &mut message.receivers {
            receiver.addresses = vec![jade_url.clone()];
            ours.add_foreign(receiver).unwrap();
        }
        rust.bus()
            .send(
                &me.name,
                &message.receivers[0].name,
                print(&message).into_bytes(),
            )
            .unwrap();
    };
    let same_as_jade = |ours: &AclMessage, capture: &str| {
        let jade = jade_says(&format!("fipa/wire/from-jade/{capture}.raw"));
        assert_eq!(ours.performative, jade.performative, "{capture}");
        assert_eq!(
            ours.content_text().map(|c| c.to_owned()),
            jade.content_text().map(localise),
            "{capture}"
        );
        assert_eq!(
            (
                &ours.language,
                &ours.ontology,
                &ours.protocol,
                &ours.in_reply_to,
                &ours.conversation_id
            ),
            (
                &jade.language,
                &jade.ontology,
                &jade.protocol,
                &jade.in_reply_to,
                &jade.conversation_id
            ),
            "{capture}"
        );
        assert_eq!(
            ours.sender.as_ref().unwrap().name,
            jade.sender.as_ref().unwrap().name
        );
        assert_eq!(
            ours.sender.as_ref().unwrap().addresses,
            std::slice::from_ref(&jade_url),
            "replies carry the sender's address"
        );
    };

    send("01-request");
    same_as_jade(&recv(&mut inbox).await, "01a-agree-to-request");
    same_as_jade(&recv(&mut inbox).await, "01b-inform-done-to-request");
    send("02-query-ref");
    same_as_jade(&recv(&mut inbox).await, "02-inform-to-query-ref");
    send("07-df-subscribe"); // Nothing matches yet: the DF says nothing until 06.
    send("03-df-search");
    same_as_jade(&recv(&mut inbox).await, "03-df-search-result-inform");
    send("04-ams-search");
    let ams = recv(&mut inbox).await;
    assert_eq!(
        (ams.performative, ams.sender.as_ref().unwrap().name.as_str()),
        (Performative::Inform, "ams@WheelchairTest")
    );
    for agent in [
        "ams@WheelchairTest",
        "df@WheelchairTest",
        "echo@WheelchairTest",
    ] {
        assert!(
            ams.content_text()
                .unwrap()
                .contains(&format!(":name {agent} ")),
            "{agent} listed: {ams:?}"
        );
    }
    send("05-unknown-receiver");
    let failure = recv(&mut inbox).await;
    let jade_failure = jade_says("fipa/wire/from-jade/05-ams-failure-unknown-receiver.raw");
    assert_eq!(
        (failure.performative, &failure.sender.as_ref().unwrap().name),
        (
            jade_failure.performative,
            &jade_failure.sender.as_ref().unwrap().name
        )
    );
    assert_eq!(
        (&failure.language, &failure.conversation_id),
        (&jade_failure.language, &jade_failure.conversation_id)
    );
    assert!(
        failure
            .content_text()
            .unwrap()
            .contains("(MTS-error (agent-identifier :name nobody@WheelchairTest"),
        "{failure:?}"
    );
    assert!(
        failure
            .content_text()
            .unwrap()
            .contains("(internal-error \"Agent not found: nobody@WheelchairTest\")"),
        "{failure:?}"
    );
    send("06-df-register");
    same_as_jade(&recv(&mut inbox).await, "06-df-register-inform-done");
    same_as_jade(
        &recv(&mut inbox).await,
        "07-df-subscribe-notification-inform",
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn foreign_names_and_addresses_are_checked() {
    let platform = wheelchair_test().await;
    let gateway = platform.gateway();
    let err = gateway
        .add_foreign(&AgentId::new("echo@WheelchairTest").with_address("http://127.0.0.1:1/acc"))
        .unwrap_err();
    assert!(err.to_string().contains("local agent"), "{err}");
    // A local agent writing to a foreign agent without an address hears from its own AMS.
    let mut inbox = platform.bus().register("tester@WheelchairTest").unwrap();
    let lost = AgentId::new("x@Elsewhere");
    gateway.add_foreign(&lost).unwrap();
    let hello = AclMessage::new(Performative::Inform)
        .with_sender(AgentId::new("tester@WheelchairTest"))
        .with_receiver(lost)
        .with_content("hello");
    platform
        .bus()
        .send(
            "tester@WheelchairTest",
            "x@Elsewhere",
            print(&hello).into_bytes(),
        )
        .unwrap();
    let envelope = timeout(WAIT, inbox.recv()).await.unwrap().unwrap();
    let failure = iw_acl::codec::parse(envelope.payload_str().unwrap()).unwrap();
    assert_eq!(
        (
            failure.performative,
            failure.sender.as_ref().unwrap().name.as_str()
        ),
        (Performative::Failure, "ams@WheelchairTest")
    );
    assert!(
        failure
            .content_text()
            .unwrap()
            .contains("Foreign agent unreachable"),
        "{:?}",
        failure.content_text()
    );
}
