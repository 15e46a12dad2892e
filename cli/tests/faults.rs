//! Bad input and faults across processes (issue 16): a second services or world container with
//! a live container's identity is refused and the running one is not disturbed; a chair whose
//! services and world are not there keeps trying and joins when they come; a killed world's
//! chairs are taken back by the next world where they were.

mod common;

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::Instant;

use common::{LIMIT, Proc, free_port_pair, is, keygen, keygen_control};
use serde_json::Value;

fn addr() -> String {
    format!("127.0.0.1:{}", free_port_pair())
}

/// Runs `intellwheels spawn ARGS` to its exit (killed after LIMIT); its success and stderr.
fn run_to_exit(args: &[&str]) -> (bool, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
        .arg("spawn")
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("spawn {args:?} still running after {LIMIT:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    (status.success(), reader.join().unwrap())
}

/// The second services container peers the first, so the holder itself tells it `Duplicate`:
/// the one that has run longer keeps the id (it used to be the lower incarnation, in seconds,
/// then the lower address, so a newcomer started in the holder's second with a lower port ran
/// on beside it).
#[test]
fn a_second_services_or_world_with_a_live_identity_is_refused_and_the_first_runs_on() {
    let dir = tempfile::tempdir().unwrap();
    let control = keygen_control(dir.path());
    // A lease no scheduling stall on a loaded machine outlasts: a `left` here is the duplicate's.
    let config = dir.path().join("lease.toml");
    std::fs::write(&config, "[container]\nlease_ms = 3000\n").unwrap();
    let config = config.to_str().unwrap();
    let services_addr = addr();
    let mut services = Proc::spawn(&[
        "--services",
        "--listen",
        &services_addr,
        "--control-key",
        &control,
        "--config",
        config,
    ]);
    services.wait_for("services ready", |e| e["event"] == "ready");
    let mut world = Proc::spawn(&[
        "--world",
        "--listen",
        &addr(),
        "--peer",
        &services_addr,
        "--control-key",
        &control,
        "--config",
        config,
    ]);
    world.wait_for("world ready", |e| e["event"] == "ready");
    services.wait_for("the world joined", |e| {
        is(e, "joined", "agent", "world@world")
    });

    for role in ["--services", "--world"] {
        let second = addr();
        let (ok, stderr) = run_to_exit(&[
            role,
            "--listen",
            &second,
            "--peer",
            &services_addr,
            "--control-key",
            &control,
            "--config",
            config,
        ]);
        assert!(!ok, "a second {role} container ran");
        assert!(
            stderr.contains("already held by a live container") && stderr.contains("refuses"),
            "{role}: {stderr}"
        );
    }

    // The first ones run on: a chair joining now is seen by both, and nothing left meanwhile.
    let mut chair = Proc::spawn(&[
        "--chair",
        "chair-f",
        "--listen",
        &addr(),
        "--peer",
        &services_addr,
        "--control-key",
        &control,
        "--config",
        config,
    ]);
    services.wait_new("chair-f joined the first services", |e| {
        is(e, "joined", "agent", "cognitive@chair-f")
    });
    chair.wait_for("chair-f sees the first world", |e| {
        is(e, "joined", "agent", "world@world")
    });
    world.wait_for("the world attached chair-f's body", |e| {
        is(e, "body", "chair", "chair-f")
    });
    for (name, proc) in [("services", &services), ("world", &world)] {
        let left: Vec<&Value> = proc.seen.iter().filter(|e| e["event"] == "left").collect();
        assert!(left.is_empty(), "{name} saw agents leave: {left:?}");
    }
    assert!(chair.terminate().success());
    assert!(world.terminate().success());
    assert!(services.terminate().success());
}

#[test]
fn a_chair_alone_keeps_trying_and_joins_when_its_services_and_world_come() {
    let dir = tempfile::tempdir().unwrap();
    let control = keygen_control(dir.path());
    let services_addr = addr();
    let mut chair = Proc::spawn(&[
        "--chair",
        "chair-l",
        "--start",
        "15.75,6.0,-90",
        "--listen",
        &addr(),
        "--peer",
        &services_addr,
        "--control-key",
        &control,
    ]);
    chair.wait_for("chair-l ready", |e| e["event"] == "ready");
    // Alone for a while (its greetings go nowhere): it keeps running and lists nobody.
    std::thread::sleep(std::time::Duration::from_secs(3));
    assert!(
        chair.child.try_wait().unwrap().is_none(),
        "chair-l gave up without its services"
    );
    while let Ok(event) = chair.events.try_recv() {
        chair.seen.push(event);
    }
    assert!(
        !chair.seen.iter().any(|e| e["event"] == "joined"),
        "{:?}",
        chair.seen
    );

    let mut services = Proc::spawn(&[
        "--services",
        "--listen",
        &services_addr,
        "--goal",
        "chair-l:therapy",
        "--control-key",
        &control,
    ]);
    let mut world = Proc::spawn(&[
        "--world",
        "--listen",
        &addr(),
        "--peer",
        &services_addr,
        "--control-key",
        &control,
    ]);
    chair.wait_for("chair-l joined late", |e| {
        is(e, "joined", "agent", "assistant@services")
    });
    // Its body (which lives in the world) is taken at the start pose it kept while alone.
    world.wait_for("chair-l's body", |e| is(e, "body", "chair", "chair-l"));
    let answer = services.wait_for("chair-l's goal answered", |e| {
        is(e, "goal", "chair", "chair-l") && e["performative"] != "AGREE"
    });
    assert_eq!(answer["performative"], "INFORM", "{answer}");
    assert!(chair.terminate().success());
    assert!(world.terminate().success());
    assert!(services.terminate().success());
}

#[test]
fn a_killed_worlds_chairs_are_taken_back_by_the_next_world_where_they_stood() {
    let dir = tempfile::tempdir().unwrap();
    let control = keygen_control(dir.path());
    let services_addr = addr();
    let world_addr = addr();
    let mut services = Proc::spawn(&[
        "--services",
        "--listen",
        &services_addr,
        "--goal",
        "chair-k:dining-hall",
        "--control-key",
        &control,
    ]);
    services.wait_for("services ready", |e| e["event"] == "ready");
    // The world keeps its identity across the restart, as a deployed one does (a fresh key
    // would be a different container to the chair's security layer, which pinned the first).
    let world_key = keygen(dir.path(), "world");
    let world_args = [
        "--world",
        "--listen",
        &world_addr,
        "--peer",
        &services_addr,
        "--key",
        &world_key,
        "--control-key",
        &control,
    ];
    let mut world = Proc::spawn(&world_args);
    world.wait_for("world ready", |e| e["event"] == "ready");
    let mut chair = Proc::spawn(&[
        "--chair",
        "chair-k",
        "--start",
        "1.0,6.0,0",
        "--listen",
        &addr(),
        "--peer",
        &services_addr,
        "--control-key",
        &control,
    ]);
    services.wait_for("chair-k's goal agreed", |e| {
        is(e, "goal", "chair", "chair-k") && e["performative"] == "AGREE"
    });
    // Well on its way (2 m from the start), the world dies.
    let last = world.wait_for("chair-k driving", |e| {
        is(e, "body", "chair", "chair-k") && e["distance_m"].as_f64().unwrap() > 2.0
    });
    world.child.kill().unwrap();
    world.child.wait().unwrap();
    let killed = Instant::now();
    services.wait_new("the world left", |e| is(e, "left", "agent", "world@world"));

    let mut world = Proc::spawn(&world_args);
    world.wait_for("the new world ready", |e| e["event"] == "ready");
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
    assert!(chair.terminate().success());
    assert!(world.terminate().success());
    assert!(services.terminate().success());
}
