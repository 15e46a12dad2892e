//! The world link's re-attach limit across processes (issue 16): a virtual chair whose world is
//! killed and not started again stops its wheels as soon as its link times out, holds its goal
//! for `body.reattach_wait_ms` (30 s by default, 3 s here), then fails it with the link's reason,
//! which the services report.

mod common;

use std::time::{Instant, SystemTime, UNIX_EPOCH};

use common::{Deployment, is, stop_all};

/// The chair's wait for its world, ms: long against the 500 ms link timeout, short for a test.
const WAIT_MS: u64 = 3000;

fn unix_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
        * 1e3
}

#[test]
fn a_world_gone_past_the_reattach_wait_fails_the_goal_with_the_links_reason_its_wheels_stopped() {
    let net = Deployment::new();
    let config = net.file(
        "chair.toml",
        &format!("[body]\nreattach_wait_ms = {WAIT_MS}\n"),
    );
    let mut services = net.services().goal("chair-w:dining-hall").ready();
    let mut world = net.world().ready();
    let mut chair = net
        .chair("chair-w")
        .start("1.0,6.0,0")
        .config(&config)
        .spawn();
    services.wait_for("chair-w's goal agreed", |e| {
        is(e, "goal", "chair", "chair-w") && e["performative"] == "AGREE"
    });
    world.wait_for("chair-w driving", |e| {
        is(e, "body", "chair", "chair-w") && e["distance_m"].as_f64().unwrap() > 1.0
    });
    chair.wait_for("chair-w's wheels turning", |e| {
        is(e, "wheels", "chair", "chair-w") && e["moving"] == true
    });

    world.kill();
    let (killed, killed_ms) = (Instant::now(), unix_ms());
    let stopped = chair.wait_new("chair-w's wheels stopped", |e| {
        is(e, "wheels", "chair", "chair-w")
            && e["moving"] == false
            && e["unix_ms"].as_f64().unwrap() > killed_ms
    });
    let answer = services.wait_for("chair-w's goal answered", |e| {
        is(e, "goal", "chair", "chair-w") && e["performative"] != "AGREE"
    });
    let (failed_s, failed_ms) = (killed.elapsed().as_secs_f64(), unix_ms());
    assert_eq!(answer["performative"], "FAILURE", "{answer}");
    let reason = answer["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("body failed") && reason.contains("no sensor frame from the world"),
        "the goal failed for another reason than the lost world link: {answer}"
    );
    // Held for the wait, not failed at the first unread frame (the link times out after 500 ms,
    // and the wait runs from there).
    assert!(
        failed_s * 1e3 >= WAIT_MS as f64,
        "the goal failed {failed_s:.1} s after the kill, within the {WAIT_MS} ms wait: {answer}"
    );
    // The wheels stopped when the link went (500 ms), while the goal was held: before the wait
    // could have run out, not with the failure (the bound is the wait, six times the link
    // timeout, for a loaded host).
    let stopped_ms = stopped["unix_ms"].as_f64().unwrap();
    assert!(
        stopped_ms < failed_ms && stopped_ms - killed_ms < WAIT_MS as f64,
        "the wheels stopped {:.0} ms after the kill, not while the goal was held: {stopped}",
        stopped_ms - killed_ms
    );
    // And they stayed stopped: no command to turn since.
    chair.drain();
    let turned: Vec<_> = chair
        .seen
        .iter()
        .filter(|e| {
            is(e, "wheels", "chair", "chair-w")
                && e["moving"] == true
                && e["unix_ms"].as_f64().unwrap() > stopped_ms
        })
        .collect();
    assert!(turned.is_empty(), "the wheels turned again: {turned:?}");
    eprintln!(
        "chair-w: wheels stopped {:.0} ms after the world was killed (link timeout 500 ms); goal \
         failed {failed_s:.1} s after (wait {WAIT_MS} ms): {reason}",
        stopped_ms - killed_ms
    );
    stop_all([&mut chair, &mut services]);
}
