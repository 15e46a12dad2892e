//! Bad input and faults across processes (issue 16): a second services or world container with
//! a live container's identity is refused and the running one is not disturbed; a chair whose
//! services and world are not there keeps trying and joins when they come; a killed world's
//! chairs are taken back by the next world where they were.

mod common;

use common::{Deployment, is, stop_all};
use serde_json::Value;
use std::time::Instant;

/// The second services container peers the first, so the holder itself tells it `Duplicate`:
/// the one that has run longer keeps the id (it used to be the lower incarnation, in seconds,
/// then the lower address, so a newcomer started in the holder's second with a lower port ran
/// on beside it).
#[test]
fn a_second_services_or_world_with_a_live_identity_is_refused_and_the_first_runs_on() {
    let net = Deployment::new();
    // A lease no scheduling stall on a loaded machine outlasts: a `left` here is the duplicate's.
    let config = net.file("lease.toml", "[container]\nlease_ms = 3000\n");
    let mut services = net.services().config(&config).ready();
    let mut world = net.world().config(&config).ready();
    services.wait_for("the world joined", |e| {
        is(e, "joined", "agent", "world@world")
    });

    let second_services = net
        .services()
        .listen(&common::loopback())
        .arg("--peer", net.services_addr());
    for (role, second) in [("--services", second_services), ("--world", net.world())] {
        let (ok, stderr) = second.config(&config).run_to_exit();
        assert!(!ok, "a second {role} container ran");
        assert!(
            stderr.contains("already held by a live container") && stderr.contains("refuses"),
            "{role}: {stderr}"
        );
    }

    // The first ones run on: a chair joining now is seen by both, and nothing left meanwhile.
    let mut chair = net.chair("chair-f").config(&config).spawn();
    services.wait_new("chair-f joined the first services", |e| {
        is(e, "joined", "agent", "cognitive@chair-f")
    });
    chair.wait_for("chair-f sees the first world", |e| {
        is(e, "joined", "agent", "world@world")
    });
    world.wait_for("the world attached chair-f's body", |e| {
        is(e, "body", "chair", "chair-f")
    });
    for proc in [&services, &world] {
        let left: Vec<&Value> = proc.seen.iter().filter(|e| e["event"] == "left").collect();
        assert!(left.is_empty(), "{} saw agents leave: {left:?}", proc.label);
    }
    stop_all([&mut chair, &mut world, &mut services]);
}

#[test]
fn a_chair_alone_keeps_trying_and_joins_when_its_services_and_world_come() {
    let net = Deployment::new();
    let mut chair = net.chair("chair-l").start("15.75,6.0,-90").ready();
    // Alone for a while (its greetings go nowhere): it keeps running and lists nobody.
    std::thread::sleep(std::time::Duration::from_secs(3));
    assert!(
        chair.child.try_wait().unwrap().is_none(),
        "chair-l gave up without its services"
    );
    chair.drain();
    assert!(
        !chair.seen.iter().any(|e| e["event"] == "joined"),
        "{:?}",
        chair.seen
    );

    let mut services = net.services().goal("chair-l:therapy").spawn();
    let mut world = net.world().spawn();
    chair.wait_for("chair-l joined late", |e| {
        is(e, "joined", "agent", "assistant@services")
    });
    // Its body (which lives in the world) is taken at the start pose it kept while alone.
    world.wait_for("chair-l's body", |e| is(e, "body", "chair", "chair-l"));
    let answer = services.wait_for("chair-l's goal answered", |e| {
        is(e, "goal", "chair", "chair-l") && e["performative"] != "AGREE"
    });
    assert_eq!(answer["performative"], "INFORM", "{answer}");
    stop_all([&mut chair, &mut world, &mut services]);
}

#[test]
fn a_killed_worlds_chairs_are_taken_back_by_the_next_world_where_they_stood() {
    let net = Deployment::new();
    let mut services = net.services().goal("chair-k:dining-hall").ready();
    // The world keeps its identity across the restart, as a deployed one does (a fresh key
    // would be a different container to the chair's security layer, which pinned the first).
    let world_launch = net.world().key(&net.key("world"));
    let mut world = world_launch.ready();
    let mut chair = net.chair("chair-k").start("1.0,6.0,0").spawn();
    services.wait_for("chair-k's goal agreed", |e| {
        is(e, "goal", "chair", "chair-k") && e["performative"] == "AGREE"
    });
    // Well on its way (2 m from the start), the world dies.
    let last = world.wait_for("chair-k driving", |e| {
        is(e, "body", "chair", "chair-k") && e["distance_m"].as_f64().unwrap() > 2.0
    });
    world.kill();
    let killed = Instant::now();
    services.wait_new("the world left", |e| is(e, "left", "agent", "world@world"));

    let mut world = world_launch.ready();
    let back = world.wait_for("chair-k's body in the new world", |e| {
        is(e, "body", "chair", "chair-k")
    });
    let attached_s = killed.elapsed().as_secs_f64();
    // Taken back where it stood (it drove at most a report period past the last report, and
    // nothing while the world was gone), not at its start.
    let gap_m = (back["x_m"].as_f64().unwrap() - last["x_m"].as_f64().unwrap())
        .hypot(back["y_m"].as_f64().unwrap() - last["y_m"].as_f64().unwrap());
    assert!(gap_m < 1.5, "last seen {last}, taken back at {back}");
    assert!(back["x_m"].as_f64().unwrap() > 2.0, "{back}");
    // And the goal in flight is carried on, not failed: a virtual body's faults are outages of
    // its world link, so its control agent held the task (wheels stopped) while the world was
    // gone and drives it on from rest with the new world's frames.
    let answer = services.wait_for("chair-k's goal answered", |e| {
        is(e, "goal", "chair", "chair-k") && e["performative"] != "AGREE"
    });
    assert_eq!(answer["performative"], "INFORM", "{answer}");
    let reached_s = killed.elapsed().as_secs_f64();
    // It got there in the new world: driven there from where it was taken back.
    let there = world.wait_for("chair-k's body at the dining hall", |e| {
        is(e, "body", "chair", "chair-k")
            && (e["x_m"].as_f64().unwrap() - 15.0).hypot(e["y_m"].as_f64().unwrap() - 8.2) < 1.0
    });
    assert!(there["distance_m"].as_f64().unwrap() > 5.0, "{there}");
    eprintln!(
        "chair-k: the new world attached it {attached_s:.1} s after the kill; goal reached \
         {reached_s:.1} s after the kill"
    );
    stop_all([&mut chair, &mut world, &mut services]);
}
