//! `intellwheels spawn` as real processes on loopback UDP: the world, the services and two chairs
//! (one on a serial board emulated on a pty, one virtual in the world). Killing the serial chair with SIGKILL leaves the
//! others working, the board's watchdog stops its wheels, and the services see its agents leave;
//! SIGTERM shuts a container down cleanly and deregisters it.

mod common;

use serde_json::Value;
use std::process::Command;
use std::time::{Duration, Instant};

use common::{Deployment, LIMIT, Proc, is, stop_all};

use iw_body::{BoardEmulator, WheelGeometry, WheelSpeeds};

/// Polls the board until `f` holds; panics after LIMIT with the board state and what the
/// services saw (a goal failure there names the reason).
fn board_until(
    board: &BoardEmulator,
    services: &mut Proc,
    what: &str,
    f: impl Fn(&iw_body::BoardState) -> bool,
) {
    let deadline = Instant::now() + LIMIT;
    while !f(&board.handle().state()) {
        if Instant::now() >= deadline {
            services.drain();
            panic!(
                "board never {what}: {:?}\nservices saw {:#?}",
                board.handle().state(),
                services.seen
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn killing_a_chair_leaves_the_others_running_and_its_board_stops() {
    let net = Deployment::new();
    // in real time, as the scenario runner's boards: the chair's I/O thread reads as fast as
    // the board answers, so a board that advanced a period per request raced ahead of real
    // time, and the chair's odometry with it
    let board = BoardEmulator::spawn_real_time(
        WheelGeometry::default(),
        Duration::from_millis(50),
        Some(Duration::from_millis(300)),
    )
    .expect("pty");
    let mut services = net
        .services()
        .key(&net.key("services"))
        .goal("chair-a:office")
        .goal("chair-b:bathroom")
        .goal("chair-c:therapy")
        .ready();
    let mut world = net.world().ready();
    let serial = format!("serial:{}", board.port_name());
    let chair = |name: &str, body: &str, start: &str| {
        net.chair(name).body(body).start(start).key(&net.key(name))
    };
    let mut chair_a = chair("chair-a", &serial, "1.0,6.0,0").ready();
    let mut chair_b = chair("chair-b", "virtual", "7.5,8.5,-90").ready();

    for agent in [
        "control@chair-a",
        "perception@chair-a",
        "control@chair-b",
        "perception@chair-b",
    ] {
        services.wait_for(&format!("{agent} joined"), |e| {
            is(e, "joined", "agent", agent)
        });
    }
    chair_a.wait_for("the services seen by chair-a", |e| {
        is(e, "joined", "agent", "assistant@services")
    });
    services.wait_for("chair-a's goal agreed", |e| {
        is(e, "goal", "chair", "chair-a") && e["performative"] == "AGREE"
    });
    board_until(&board, &mut services, "drove", |s| {
        s.speeds != WheelSpeeds::STOP
    });

    chair_a.kill(); // SIGKILL: no take-down, no last stop
    board_until(&board, &mut services, "stopped by its watchdog", |s| {
        s.speeds == WheelSpeeds::STOP && s.watchdog_stops >= 1
    });
    services.wait_for("chair-a's control agent leaving", |e| {
        is(e, "left", "agent", "control@chair-a")
    });

    // The rest carries on: chair-b keeps exchanging messages and gets its goal done, and a chair
    // joining after the kill gets its goal done too.
    services.wait_new("a chair-b pose after the kill", |e| {
        is(e, "pose", "chair", "chair-b")
    });
    let _chair_c = net
        .chair("chair-c")
        .start("15.0,8.2,180")
        .key(&net.key("chair-c"))
        .ready();
    for chair in ["chair-b", "chair-c"] {
        services.wait_for(&format!("{chair}'s goal done"), |e| {
            is(e, "goal", "chair", chair) && e["performative"] == "INFORM"
        });
    }
    assert!(
        !services.seen.iter().any(|e| e["event"] == "goal"
            && e["performative"] == "FAILURE"
            && e["chair"] != "chair-a"),
        "{:#?}",
        services.seen
    );

    // SIGTERM: chair-b stops cleanly and the services see it deregister.
    chair_b.stop();
    services.wait_for("chair-b's control agent leaving", |e| {
        is(e, "left", "agent", "control@chair-b")
    });
    stop_all([&mut services, &mut world]);
}

#[test]
fn bad_flags_and_files_are_clear_errors() {
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_intellwheels"))
            .arg("spawn")
            .args(args)
            .output()
            .unwrap()
    };
    let out = run(&["--chair", "c", "--body", "wooden"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--body `wooden`"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(&["--chair", "c", "--listen", "127.0.0.1:7"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("security.control_key"),
        "no control key and no --insecure-dev: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(&["--chair", "c", "--listen", "127.0.0.1:0", "--insecure-dev"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("port 0"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("bad.toml");
    std::fs::write(&config, "[container]\nlease_ms = \"long\"\n").unwrap();
    let out = run(&["--services", "--config", config.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("bad.toml"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let key = dir.path().join("not-a-key");
    std::fs::write(&key, "hello").unwrap();
    let out = run(&[
        "--services",
        "--listen",
        "127.0.0.1:7",
        "--insecure-dev",
        "--key",
        key.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("identity key"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Services, the world and one virtual chair over `transport`, listening at the given addresses:
/// the chair joins, its goal is done, and it leaves cleanly.
fn goal_done_over(transport: &str, services_addr: &str, world_addr: &str, chair_addr: &str) {
    let net = Deployment::insecure(transport, services_addr);
    let mut services = net.services().goal("chair-s:therapy").ready();
    let mut world = net.world().listen(world_addr).ready();
    let mut chair = net
        .chair("chair-s")
        .start("15.0,8.2,180")
        .listen(chair_addr)
        .spawn();
    services.wait_for("chair-s's goal done", |e| {
        is(e, "goal", "chair", "chair-s") && e["performative"] == "INFORM"
    });
    chair.stop();
    services.wait_for("chair-s's control agent leaving", |e| {
        is(e, "left", "agent", "control@chair-s")
    });
    stop_all([&mut services, &mut world]);
}

#[test]
fn containers_over_iceoryx2_join_and_a_goal_is_done() {
    let tag = format!("iwt-{}", std::process::id());
    goal_done_over(
        "iceoryx2",
        &format!("{tag}-services"),
        &format!("{tag}-world"),
        &format!("{tag}-chair"),
    );
}

/// Two consecutive free TCP ports on loopback (bus and control channel).
fn free_tcp_port_pair() -> u16 {
    loop {
        let a = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = a.local_addr().unwrap().port();
        if port < u16::MAX && std::net::TcpListener::bind(("127.0.0.1", port + 1)).is_ok() {
            return port;
        }
    }
}

#[test]
fn containers_over_tcp_join_and_a_goal_is_done() {
    goal_done_over(
        "tcp",
        &format!("127.0.0.1:{}", free_tcp_port_pair()),
        &format!("127.0.0.1:{}", free_tcp_port_pair()),
        &format!("127.0.0.1:{}", free_tcp_port_pair()),
    );
}

/// Issue 20 item 3: a chair killed with SIGKILL mid-goal and started again (same identity key,
/// same address) gets its goal again: the services report the goal in flight failed, with the
/// reason, then give it again once the chair is back. `after_lease`: the restart waits until
/// the services saw the chair leave; otherwise it is at once, and the chair's higher
/// incarnation tells the services it is a new life.
fn chair_restarted_after_sigkill(after_lease: bool) {
    let net = Deployment::new();
    let mut services = net
        .services()
        .key(&net.key("services"))
        .goal("chair-r:dining-hall")
        .ready();
    let chair_launch = net
        .chair("chair-r")
        .start("1.0,6.0,0")
        .key(&net.key("chair-r"));
    let agreed = |e: &Value| is(e, "goal", "chair", "chair-r") && e["performative"] == "AGREE";
    let mut chair = chair_launch.spawn();
    services.wait_for("the first goal agreed", agreed);
    chair.kill(); // SIGKILL: no deregistration, sessions lost
    if !after_lease {
        // incarnations count seconds: make sure the new life has a higher one
        std::thread::sleep(Duration::from_millis(1100));
        chair = chair_launch.spawn();
    }
    services.wait_new("the chair leaving", |e| {
        is(e, "left", "agent", "control@chair-r")
    });
    let failed = services.wait_new("the goal in flight reported failed", |e| {
        is(e, "goal", "chair", "chair-r") && e["performative"] == "FAILURE"
    });
    let reason = failed["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("chair-r left before the goal was done"),
        "{failed}"
    );
    if after_lease {
        chair = chair_launch.spawn();
    }
    let again = services.wait_new("the goal agreed again after the restart", agreed);
    assert_ne!(
        again["conversation"], failed["conversation"],
        "a new conversation"
    );
    assert_eq!(again["place"], "dining-hall");
    stop_all([&mut chair, &mut services]);
}

#[test]
fn a_chair_restarted_after_sigkill_gets_its_goal_again() {
    chair_restarted_after_sigkill(true);
}

#[test]
fn a_chair_restarted_at_once_after_sigkill_gets_its_goal_again() {
    chair_restarted_after_sigkill(false);
}

/// Issue 20: a services container killed with SIGKILL mid-run and started again gets its chair
/// back (the chair's agents join the new one) and the goal that was in flight is given again
/// and agreed: not silently lost.
#[test]
fn a_services_container_restarted_after_sigkill_gets_its_chair_back() {
    let net = Deployment::new();
    let services_launch = net
        .services()
        .key(&net.key("services"))
        .goal("chair-q:dining-hall");
    let mut services = services_launch.ready();
    let mut chair = net
        .chair("chair-q")
        .start("1.0,6.0,0")
        .key(&net.key("chair-q"))
        .spawn();
    let agreed = |e: &Value| is(e, "goal", "chair", "chair-q") && e["performative"] == "AGREE";
    services.wait_for("the first goal agreed", agreed);
    services.kill(); // SIGKILL: sessions, lists and goals in memory lost
    let mut services = services_launch.spawn();
    services.wait_for("the restarted services ready", |e| e["event"] == "ready");
    services.wait_for("chair-q's cognitive agent back", |e| {
        is(e, "joined", "agent", "cognitive@chair-q")
    });
    services.wait_for("the goal given again and agreed", agreed);
    stop_all([&mut chair, &mut services]);
}
