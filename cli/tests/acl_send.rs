//! `intellwheels acl send` against our platform (echo agent, AMS and DF behind the HTTP MTP on
//! loopback), through the real binary: a fipa-request, a DF search, an unknown receiver, and an
//! address where no platform listens.

use std::process::{Command, Output};
use std::time::Duration;

use iw_mtp_http::GatewayConfig;
use iw_node::http_platform::{Echo, HttpPlatform};

fn platform(rt: &tokio::runtime::Runtime) -> HttpPlatform {
    let echo: Box<dyn iw_agent::Agent> = Box::new(Echo);
    rt.block_on(HttpPlatform::start(
        GatewayConfig::new("WheelchairTest"),
        vec![("echo".into(), echo)],
        Duration::from_millis(1),
    ))
    .expect("platform starts")
}

fn send(args: &[&str]) -> (Output, Vec<String>) {
    let output = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
        .args(["acl", "send", "--timeout", "20"])
        .args(args)
        .output()
        .unwrap();
    let lines = String::from_utf8(output.stdout.clone())
        .unwrap()
        .lines()
        .map(str::to_owned)
        .collect();
    (output, lines)
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

#[test]
fn request_search_and_unknown_receiver() {
    let rt = runtime();
    let platform = platform(&rt);
    let url = platform.gateway().url();

    let (output, lines) = send(&[
        "--to",
        "echo@WheelchairTest",
        "--address",
        &url,
        "--performative",
        "request",
        "--protocol",
        "fipa-request",
        "--content",
        "((action (agent-identifier :name echo@WheelchairTest) (move-to :room kitchen)))",
        "--language",
        "fipa-sl",
        "--ontology",
        "wheelchair-ontology",
    ]);
    assert!(output.status.success(), "{output:?}");
    assert_eq!(
        lines,
        [
            "AGREE",
            "INFORM ((done (action (agent-identifier :name echo@WheelchairTest) (move-to :room kitchen))))"
        ]
    );

    let (output, lines) = send(&[
        "--to",
        "df@WheelchairTest",
        "--address",
        &url,
        "--performative",
        "REQUEST",
        "--protocol",
        "fipa-request",
        "--content",
        "((action (agent-identifier :name df@WheelchairTest) (search (df-agent-description :services (set (service-description :type wheelchair-echo))) (search-constraints :max-results -1))))",
        "--language",
        "fipa-sl0",
        "--ontology",
        "FIPA-Agent-Management",
    ]);
    assert!(output.status.success(), "{output:?}");
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(
        lines[0].starts_with(
            "INFORM ((result (action (agent-identifier :name df@WheelchairTest) (search "
        ),
        "{lines:?}"
    );
    assert!(lines[0].contains(&format!("(df-agent-description :name (agent-identifier :name echo@WheelchairTest :addresses (sequence {url})) :services (set (service-description :name echo-service :type wheelchair-echo)))")), "{lines:?}");

    let (output, lines) = send(&[
        "--to",
        "nobody@WheelchairTest",
        "--address",
        &url,
        "--performative",
        "inform",
        "--content",
        "hello",
    ]);
    assert!(output.status.success(), "{output:?}");
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(
        lines[0].starts_with("FAILURE ((action (agent-identifier :name acl-send@intellwheels-cli"),
        "{lines:?}"
    );
    assert!(
        lines[0].contains("(MTS-error (agent-identifier :name nobody@WheelchairTest"),
        "{lines:?}"
    );
    assert!(
        lines[0].contains("Agent not found: nobody@WheelchairTest"),
        "{lines:?}"
    );
}

#[test]
fn no_platform_at_the_address_is_an_error() {
    // A port that was just free: bind, note it, close.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let address = format!("http://127.0.0.1:{port}/acc");
    let (output, lines) = send(&[
        "--to",
        "echo@Nowhere",
        "--address",
        &address,
        "--performative",
        "request",
    ]);
    assert_eq!(output.status.code(), Some(2), "{output:?}");
    assert!(lines.is_empty());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("could not be delivered to echo@Nowhere")
            && stderr.contains("Foreign agent unreachable"),
        "{stderr}"
    );
    let (output, _) = send(&[
        "--to",
        "echo",
        "--address",
        &address,
        "--performative",
        "shout",
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("--performative \"shout\""),
        "{output:?}"
    );
}
