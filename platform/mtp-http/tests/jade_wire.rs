//! Replays JADE's captured posts (shared `fipa/wire/`) through our decoder, checks that our
//! client writes what JADE accepts and that the AMS's report of an undeliverable message reads
//! like JADE's. The whole platform against JADE's captures is tested where it is assembled
//! (`iw-node`, `tests/http_platform.rs`).

use iw_acl::codec::{ParseOptions, parse_with};
use iw_acl::{AclMessage, AgentId, Performative};
use iw_mtp_http::{Envelope, MtpClient, delivery_failure, wire};

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

/// The message of a captured post, read by our own decoder.
fn posted(test: &str, relative: &str) -> Option<AclMessage> {
    let bytes = std::fs::read(iw_testdata::require(test, relative)?).unwrap();
    let end = wire::find_head_end(&bytes).unwrap().unwrap();
    let head = wire::parse_request_head(&bytes[..end]).unwrap();
    Some(
        iw_mtp_http::server::decode(&head, &bytes[end..])
            .unwrap()
            .message,
    )
}

#[test]
fn delivery_failure_reads_like_jades_ams() {
    let Some(jade) = posted(
        "delivery_failure",
        "fipa/wire/from-jade/05-ams-failure-unknown-receiver.raw",
    ) else {
        return;
    };
    let Some(sent) =
        iw_testdata::require("delivery_failure", "fipa/wire/acl/05-unknown-receiver.acl")
    else {
        return;
    };
    let sent = parse_with(
        &std::fs::read_to_string(sent).unwrap(),
        &ParseOptions::jade(),
    )
    .unwrap();
    let nobody = AgentId::new("nobody@WheelchairTest").with_address("http://127.0.0.1:7778/acc");
    let reason = "Agent not found: getContainerID() failed to find agent nobody@WheelchairTest";
    let ours = delivery_failure(&sent, &nobody, AgentId::new("ams@WheelchairTest"), reason);
    assert_eq!(ours.performative, jade.performative);
    assert_eq!(
        (&ours.language, &ours.ontology, &ours.protocol),
        (&jade.language, &jade.ontology, &jade.protocol)
    );
    assert_eq!(ours.conversation_id, jade.conversation_id);
    assert_eq!(ours.receivers[0].name, "wheelchair1@RustPlatform");
    // JADE spaces its terms irregularly: compare the SL trees.
    let tree =
        |m: &AclMessage| iw_sl::parse(m.content_text().unwrap(), iw_sl::Level::Full).unwrap();
    assert_eq!(tree(&ours), tree(&jade));
}
