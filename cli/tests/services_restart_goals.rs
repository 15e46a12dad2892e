//! Issue 20: a goal the services do not follow is not lost when they restart. A foreign FIPA
//! platform (the in-repo HTTP peer, `intellwheels acl send`, as JADE would be) gives a chair a
//! goal through the services' assistant over the HTTP MTP: the services' own goal events never
//! see it. The services are killed with SIGKILL while the chair drives it and started again
//! (same identity, address and configuration); the new services ask the chair what it carries
//! out, and the goal ends reached or failed with a reason in their events.

mod common;

use std::process::{Child, Command, Stdio};
use std::time::Instant;

use common::{Deployment, is, stop_all};
use serde_json::Value;

/// Kills the HTTP peer at the end: its services died under it, so it waits for nothing.
struct Peer(Child);

impl Drop for Peer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_goal_the_services_did_not_follow_ends_reached_or_failed_with_a_reason_after_they_restart() {
    let net = Deployment::new();
    let (_, config) = net.http_mtp_config("chair-g");
    let services_launch = net.services().key(&net.key("services")).config(&config);
    let mut services = services_launch.spawn();
    let serving = services.wait_for("the HTTP MTP served", |e| {
        is(e, "serving", "service", "mtp-http")
    });
    let url = serving["url"].as_str().unwrap().to_string();
    let mut world = net.world().key(&net.key("world")).ready();
    let mut chair = net
        .chair("chair-g")
        .start("1.0,6.0,0")
        .key(&net.key("chair-g"))
        .spawn();
    services.wait_for("chair-g's pose", |e| is(e, "pose", "chair", "chair-g"));

    // The foreign goal: the services forward it but follow no conversation of theirs for it.
    let _peer = Peer(
        Command::new(env!("CARGO_BIN_EXE_intellwheels"))
            .args([
                "acl",
                "send",
                "--to",
                "assistant@services",
                "--address",
                &url,
            ])
            .args(["--performative", "request", "--protocol", "fipa-request"])
            .args([
                "--content",
                "((action (agent-identifier :name chair-g) (go-to :place dining-hall)))",
            ])
            .args([
                "--language",
                "fipa-sl0",
                "--ontology",
                "IntellWheels-Wheelchair",
            ])
            .args(["--timeout", "300"])
            .stdout(Stdio::null())
            .spawn()
            .unwrap(),
    );
    // Well on its way, the services die.
    world.wait_for("chair-g driving its goal", |e| {
        is(e, "body", "chair", "chair-g") && e["distance_m"].as_f64().unwrap() > 1.5
    });
    services.drain();
    assert!(
        !services
            .seen
            .iter()
            .any(|e| is(e, "goal", "chair", "chair-g")),
        "the services were to know nothing of the foreign goal: {:?}",
        services.seen
    );
    services.kill();
    let killed = Instant::now();
    let mut services = services_launch.spawn();
    services.wait_for("chair-g back at the restarted services", |e| {
        is(e, "joined", "agent", "cognitive@chair-g")
    });

    // The restarted services learn the goal from the chair, with who gave it: either it is
    // still under way (its old conversation is reported failed with the reason and the goal is
    // given again), or it ended while they could not hear it (reported with its outcome; the
    // chair's world link can drop while its lists follow the new services).
    let learned = services.wait_for("the goal in flight learned from chair-g", |e| {
        is(e, "goal", "chair", "chair-g") && e["requester"].is_string()
    });
    let learned_s = killed.elapsed().as_secs_f64();
    assert_eq!(learned["place"], "dining-hall", "{learned}");
    assert_eq!(learned["requester"], "assistant@services", "{learned}");
    let reason = |e: &Value| e["reason"].as_str().unwrap_or_default().to_string();
    let given_again = reason(&learned).contains("given again");
    if given_again {
        assert_eq!(learned["performative"], "FAILURE", "{learned}");
        assert!(
            reason(&learned).contains("chair-g was going to dining-hall"),
            "{learned}"
        );
    }
    // And it ends: reached, or failed with a reason, in the services' events.
    let end = if given_again {
        let end = services.wait_for("the goal's end", |e| {
            is(e, "goal", "chair", "chair-g")
                && e["requester"].is_null()
                && e["performative"] != "AGREE"
        });
        assert_ne!(end["conversation"], learned["conversation"], "{end}");
        end
    } else {
        learned.clone()
    };
    let end_s = killed.elapsed().as_secs_f64();
    assert!(
        end["performative"] == "INFORM"
            || (end["performative"] == "FAILURE" && !reason(&end).is_empty()),
        "a goal that did not end reached or failed with a reason: {end}"
    );
    if end["performative"] == "INFORM" {
        world.wait_for("chair-g's body at the dining hall", |e| {
            is(e, "body", "chair", "chair-g")
                && (e["x_m"].as_f64().unwrap() - 15.0).hypot(e["y_m"].as_f64().unwrap() - 8.2) < 1.0
        });
    }
    eprintln!(
        "chair-g: the restarted services learned its goal {learned_s:.1} s after the kill ({}); \
         the goal ended {} {end_s:.1} s after the kill ({})",
        if given_again {
            "given again"
        } else {
            "ended meanwhile"
        },
        end["performative"],
        reason(&end)
    );
    stop_all([&mut chair, &mut world, &mut services]);
}
