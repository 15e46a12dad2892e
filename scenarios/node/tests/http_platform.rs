//! A whole platform over the FIPA HTTP MTP (`HttpPlatform`: AMS, DF and the echo agent behind a
//! gateway) against JADE's captures (shared `fipa/wire/`): replayed posts, the captured
//! conversations answered as JADE answers them, foreign names checked; and two of our platforms
//! talking over TLS (self-signed certificate made with rcgen).

use std::time::Duration;

use iw_acl::codec::{ParseOptions, parse_with, print};
use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::tls::pki_types::{CertificateDer, PrivateKeyDer, PrivatePkcs8KeyDer};
use iw_mtp_http::{GatewayConfig, MtpClient, tls, wire};
use iw_node::http_platform::{Echo, HttpPlatform};
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
        // JADE's echo wraps the request's whole content tuple, `((done ((action …))))`, which
        // is not SL (done takes an action); ours says `((done (action …)))` of the same action.
        let as_sl = |jade: String| match jade
            .strip_prefix("((done (")
            .and_then(|rest| rest.strip_suffix(")))"))
        {
            Some(action) if capture == "01b-inform-done-to-request" => {
                format!("((done {action}))")
            }
            _ => jade,
        };
        assert_eq!(
            ours.content_text().map(|c| c.to_owned()),
            jade.content_text().map(localise).map(as_sl),
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

/// An agent that cannot be put on the platform's bus (its name is the AMS's) stops the start
/// with `Error::Attach`, whose source is the host's own error (the bus refusing the name).
#[tokio::test]
async fn an_agent_that_cannot_be_hosted_keeps_the_hosts_error() {
    let echo: Box<dyn iw_agent::Agent> = Box::new(Echo);
    let err = HttpPlatform::start(
        GatewayConfig::new("Clash"),
        vec![("ams".into(), echo)],
        STEP,
    )
    .await
    .unwrap_err();
    assert!(
        matches!(&err, iw_mtp_http::Error::Attach { agent, what: "hosting it on the bus", .. } if agent == "ams"),
        "{err}"
    );
    let host = std::error::Error::source(&err)
        .and_then(|s| s.downcast_ref::<iw_agent::AgentError>())
        .unwrap_or_else(|| panic!("no host error under `{err}`"));
    assert!(
        matches!(
            host,
            iw_agent::AgentError::Bus {
                source: iw_bus::BusError::AgentExists { .. },
                ..
            }
        ),
        "{host}"
    );
}
