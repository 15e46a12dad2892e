//! `intellwheels spawn --lockstep` as real processes on loopback UDP (issue 16): a lockstep
//! world, the services and two virtual chairs. Both goals are reached, and the world is seen to
//! wait for its bodies: while one chair's process is frozen (SIGSTOP, shorter than the link
//! timeout), the world's simulated clock stands still, and the other chair, whose process runs
//! on, does not move either.

mod common;

use std::process::Command;
use std::time::{Duration, Instant};

use common::{Deployment, Proc, is, stop_all};
use serde_json::Value;

fn signal(proc: &Proc, signal: &str) {
    let status = Command::new("kill")
        .args([signal, &proc.child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success(), "kill {signal}");
}

fn num(event: &Value, key: &str) -> f64 {
    event[key]
        .as_f64()
        .unwrap_or_else(|| panic!("no {key}: {event}"))
}

#[test]
fn a_lockstep_world_waits_for_a_frozen_chair_and_both_goals_are_reached() {
    let net = Deployment::new();
    // The world reports its bodies every 100 ms, so a wait of a few hundred is seen.
    let config = net.file("reports.toml", "[services]\npose_report_ms = 100\n");
    let mut services = net
        .services()
        .goal("chair-s:office")
        .goal("chair-t:therapy")
        .ready();
    let mut world = net.world().lockstep().config(&config).ready();
    let world_started = Instant::now();
    let chair = |name: &str, start: &str| net.chair(name).lockstep().start(start).spawn();
    let mut chair_s = chair("chair-s", "1.0,6.0,0");
    let mut chair_t = chair("chair-t", "15.75,6.0,-90");
    for name in ["chair-s", "chair-t"] {
        services.wait_for("the goal agreed", |e| {
            is(e, "goal", "chair", name) && e["performative"] == "AGREE"
        });
    }
    world.wait_for("chair-t's body", |e| is(e, "body", "chair", "chair-t"));
    world.wait_for("chair-s driving", |e| {
        is(e, "body", "chair", "chair-s") && num(e, "distance_m") > 0.3
    });

    // Freeze chair-t for less than the link timeout (500 ms): the world holds its step for it.
    let queued: Vec<Value> = world.events.try_iter().collect();
    world.seen.extend(queued);
    signal(&chair_t, "-STOP");
    let frozen = Instant::now();
    let mut during = Vec::new();
    while frozen.elapsed() < Duration::from_millis(450) {
        let left = Duration::from_millis(450).saturating_sub(frozen.elapsed());
        if let Ok(event) = world.events.recv_timeout(left) {
            if is(&event, "body", "chair", "chair-s") {
                during.push((frozen.elapsed(), event.clone()));
            }
            world.seen.push(event);
        }
    }
    signal(&chair_t, "-CONT");
    // Two reports of chair-s at least 150 ms apart with the same simulated time and the same
    // distance: no step between them, though chair-s ran. (A real-time world steps every 50 ms
    // by the time that passed, so its clock moves between any two reports.)
    let held = during.iter().enumerate().any(|(i, (at, a))| {
        during[i + 1..].iter().any(|(later, b)| {
            *later - *at >= Duration::from_millis(150)
                && num(a, "world_s") == num(b, "world_s")
                && num(a, "distance_m") == num(b, "distance_m")
        })
    });
    assert!(
        held,
        "the world's clock moved while chair-t was frozen: {during:#?}"
    );

    for name in ["chair-s", "chair-t"] {
        let answer = services.wait_for("the goal answered", |e| {
            is(e, "goal", "chair", name) && e["performative"] != "AGREE"
        });
        assert_eq!(answer["performative"], "INFORM", "{answer}");
    }
    // The reports queued so far are old: the figures below are from one made after the goals.
    let queued: Vec<Value> = world.events.try_iter().collect();
    world.seen.extend(queued);
    let last = world.wait_new("a body report after the goals", |e| e["event"] == "body");
    let wall_s = world_started.elapsed().as_secs_f64();
    let world_s = num(&last, "world_s");
    eprintln!(
        "lockstep: {} reports of chair-s during the 450 ms freeze, simulated times {:?}; \
         {world_s:.1} s of world time in {wall_s:.1} s of wall time",
        during.len(),
        during
            .iter()
            .map(|(_, e)| num(e, "world_s"))
            .collect::<Vec<_>>()
    );
    stop_all([&mut chair_s, &mut chair_t, &mut world, &mut services]);
}
