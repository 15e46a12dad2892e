//! A virtual chair's body through a world outage, over real buses: while its world is gone it
//! fails its reads with how long the world has been silent, takes a stop (the world's watchdog
//! stops a body it does not hear; a new world attaches it at rest) but refuses a drive, and a
//! restarted world takes it back where it stood with its wheel ticks continued.

use std::sync::Arc;
use std::time::{Duration, Instant};

use iw_agent::AgentHost;
use iw_body::{Body, SensorFrame, WheelSpeeds};
use iw_bus::transport::PeerAddr;
use iw_bus::{Bus, Clock, InProcNetwork};
use iw_wiring::world_link::{LINK_TIMEOUT, WorldBody, world_agent};
use nalgebra::{Isometry2, Vector2};

mod common;
use common::{bus, world};

/// Chair `c1`'s bus on `network` with the world routed at `w1`, and its body at (7.5, 6).
fn chair_c1(network: &InProcNetwork, clock: &Clock) -> (Arc<Bus>, WorldBody) {
    let chair_bus = bus(network, clock, "c1");
    chair_bus.add_route(&world_agent().name, PeerAddr("w1".into()));
    let start = Isometry2::new(Vector2::new(7.5, 6.0), 0.0);
    let body = WorldBody::open(chair_bus.clone(), "c1", start).unwrap();
    (chair_bus, body)
}

/// Both wheels at `mps`.
fn ahead(mps: f64) -> WheelSpeeds {
    WheelSpeeds {
        left_mps: mps,
        right_mps: mps,
    }
}

/// Steps `host` and commands `speeds` until the body reads a frame that `done` accepts.
fn drive_until(
    host: &mut AgentHost,
    body: &mut WorldBody,
    clock: &Clock,
    speeds: WheelSpeeds,
    done: impl Fn(&SensorFrame) -> bool,
) -> SensorFrame {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        assert!(Instant::now() < deadline, "the body never got there");
        host.step(clock.now());
        if let Ok(frame) = body.read() {
            if done(&frame) {
                return frame;
            }
            body.command(speeds).unwrap();
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn a_body_rides_out_its_worlds_restart() {
    let network = InProcNetwork::new();
    let clock = Clock::system();
    let (chair_bus, mut body) = chair_c1(&network, &clock);
    let forward = ahead(0.3);

    let mut first = world(&network, &clock, "w1");
    let before = drive_until(&mut first, &mut body, &clock, forward, |f| {
        f.left_ticks > 2000
    });

    // The world dies: it steps no more, and its route goes (its lease ran out).
    drop(first);
    chair_bus.remove_route(&world_agent().name);
    std::thread::sleep(LINK_TIMEOUT + Duration::from_millis(200));
    let err = body.read().unwrap_err().to_string();
    assert!(
        err.contains("no sensor frame from the world for") && err.contains("attaching again"),
        "{err}"
    );
    let silent_ms: u64 = err
        .split("for ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no silence in {err}"));
    assert!(silent_ms >= LINK_TIMEOUT.as_millis() as u64, "{err}");
    body.stop().expect("a stop with no world to take it holds");
    let drive = body.command(forward);
    assert!(drive.is_err(), "a drive with no world: {drive:?}");

    // A new world at another endpoint: the body attaches to it where it stood, and its ticks go
    // on from where they were instead of starting again from zero.
    chair_bus.add_route(&world_agent().name, PeerAddr("w2".into()));
    let mut second = world(&network, &clock, "w2");
    let after = drive_until(&mut second, &mut body, &clock, forward, |_| true);
    assert!(
        after.left_ticks >= before.left_ticks,
        "ticks went back: {} then {}",
        before.left_ticks,
        after.left_ticks
    );
    assert!(
        after.left_ticks - before.left_ticks < 2000,
        "ticks jumped: {} then {}",
        before.left_ticks,
        after.left_ticks
    );
    let on = drive_until(&mut second, &mut body, &clock, forward, |f| {
        f.left_ticks > after.left_ticks + 500
    });
    assert!(on.left_ticks > after.left_ticks);
}

/// A world that stalls (its process late) past the link timeout and goes on: its first step
/// after the stall moves the body by up to a fifth of a second of driving, which its scans
/// show; the body's ticks keep that motion instead of being rebased as for a new world.
#[test]
fn a_body_keeps_the_motion_of_its_worlds_first_step_after_a_stall() {
    let network = InProcNetwork::new();
    let clock = Clock::system();
    let (_chair_bus, mut body) = chair_c1(&network, &clock);
    let forward = ahead(0.5);
    let mut host = world(&network, &clock, "w1");
    let before = drive_until(&mut host, &mut body, &clock, forward, |f| {
        f.left_ticks > 2000
    });
    let at = |body: &WorldBody| {
        let truth = body.true_pose();
        let guard = truth.lock().unwrap();
        guard.expect("a frame came").1.translation.vector
    };
    let true_before = at(&body);
    // the world steps no more for longer than the link timeout; the chair drives on
    let stalled = Instant::now();
    while stalled.elapsed() < LINK_TIMEOUT + Duration::from_millis(200) {
        let _ = body.read();
        body.command(forward).unwrap();
        std::thread::sleep(Duration::from_millis(50));
    }
    let after = drive_until(&mut host, &mut body, &clock, forward, |_| true);
    let moved_m = (at(&body) - true_before).norm();
    let ticked_m = (after.left_ticks - before.left_ticks) as f64
        * iw_body::WheelGeometry::default().m_per_tick();
    assert!(
        moved_m > 0.05,
        "the world's step after the stall moved {moved_m} m"
    );
    assert!(
        (ticked_m - moved_m).abs() < 0.2 * moved_m,
        "moved {moved_m} m, the ticks say {ticked_m} m"
    );
}
