//! FIPA HTTP MTP in a running deployment: the world, the services (with `[mtp.http] listen`) and
//! a chair as `intellwheels spawn` processes on loopback UDP; the in-repo HTTP peer
//! (`intellwheels acl send`, a FIPA platform of its own, as JADE would be) searches our DF for
//! the assistant and REQUESTs a goal from it, and gets AGREE and then the chair's INFORM done,
//! over HTTP. A receiver the services do not host gets the AMS's FAILURE.

mod common;

use std::process::Command;

use common::{Deployment, is, stop_all};

/// `intellwheels acl send ARGS`: its exit success and the replies it printed.
fn send(args: &[&str]) -> (bool, Vec<String>) {
    let output = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
        .args(["acl", "send"])
        .args(args)
        .output()
        .unwrap();
    eprintln!("{}", String::from_utf8_lossy(&output.stderr));
    let lines = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(str::to_owned)
        .collect();
    (output.status.success(), lines)
}

#[test]
fn a_foreign_http_agent_finds_the_assistant_in_the_df_and_gets_a_goal_done() {
    let net = Deployment::new();
    let (port, config) = net.http_mtp_config("chair-b");
    let mut services = net.services().config(&config).spawn();
    let serving = services.wait_for("the HTTP MTP served", |e| {
        is(e, "serving", "service", "mtp-http")
    });
    let url = serving["url"].as_str().unwrap().to_string();
    assert!(
        url.starts_with(&format!("http://127.0.0.1:{port}")),
        "{url}"
    );
    let mut world = net.world().ready();
    let mut chair = net.chair("chair-b").start("15.75,6.0,-90").ready();
    // the chair is there for the services once its perception agent publishes its pose
    services.wait_for("chair-b's pose", |e| is(e, "pose", "chair", "chair-b"));

    // DF search, as a JADE agent's DFService.search does.
    let (ok, lines) = send(&[
        "--to",
        "df@services",
        "--address",
        &url,
        "--performative",
        "request",
        "--protocol",
        "fipa-request",
        "--content",
        "((action (agent-identifier :name df@services) (search (df-agent-description :services (set (service-description :type wheelchair-goals))) (search-constraints :max-results -1))))",
        "--language",
        "fipa-sl0",
        "--ontology",
        "FIPA-Agent-Management",
        "--timeout",
        "30",
    ]);
    println!("DF search: {lines:?}");
    assert!(ok, "{lines:?}");
    let found = lines.last().unwrap();
    assert!(
        found.starts_with("INFORM ((result (action (agent-identifier :name df@services")
            && found.contains("(agent-identifier :name assistant@services")
            && found.contains(":name wheelchair-assistant :type wheelchair-goals"),
        "{lines:?}"
    );

    // A goal through the assistant: AGREE, then the chair's INFORM done, relayed over HTTP.
    let (ok, lines) = send(&[
        "--to",
        "assistant@services",
        "--address",
        &url,
        "--performative",
        "request",
        "--protocol",
        "fipa-request",
        "--content",
        "((action (agent-identifier :name chair-b) (go-to :place therapy)))",
        "--language",
        "fipa-sl0",
        "--ontology",
        "IntellWheels-Wheelchair",
        "--timeout",
        "100",
    ]);
    println!("goal: {lines:?}");
    assert!(ok, "{lines:?}");
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(lines[0].starts_with("AGREE"), "{lines:?}");
    assert!(
        lines[1].starts_with("INFORM ((done") && lines[1].contains("therapy"),
        "{lines:?}"
    );

    // An agent the services do not host: the AMS's FAILURE, as JADE's.
    let (ok, lines) = send(&[
        "--to",
        "nobody@services",
        "--address",
        &url,
        "--performative",
        "inform",
        "--content",
        "hello",
    ]);
    assert!(ok, "{lines:?}");
    assert!(
        lines.len() == 1 && lines[0].contains("Agent not found: nobody@services"),
        "{lines:?}"
    );

    stop_all([&mut chair, &mut services, &mut world]);
}
