//! A mixed chair's ghost in a world on another bus, over real buses: the world senses the ghost
//! where it was last placed, at its next step, and the frame comes back a message later. The
//! ghost stamps the readings with the time of the read that reported the pose they were sensed
//! at, so the localizer can match them there; a frame returned again keeps its stamp, so it is
//! not taken for a new scan.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use iw_body::VirtualSensors;
use iw_bus::transport::PeerAddr;
use iw_bus::{Clock, InProcNetwork};
use iw_wiring::world_link::{WorldGhost, world_agent};
use nalgebra::{Isometry2, Vector2};

mod common;
use common::{bus, world};

/// The ghost's reads, ns apart (the caller's clock: any clock of the chair's).
const READ_NS: u64 = 50_000_000;
/// How far the ghost moves between reads, m: five times the laser's noise.
const STRIDE_M: f64 = 0.05;

#[test]
fn a_ghosts_readings_carry_the_time_of_the_pose_they_were_sensed_at() {
    let network = InProcNetwork::new();
    let clock = Clock::system();
    let chair_bus = bus(&network, &clock, "c1");
    chair_bus.add_route(&world_agent().name, PeerAddr("w1".into()));
    let mut host = world(&network, &clock, "w1");
    let mut ghost = WorldGhost::open(
        chair_bus,
        "c1",
        Isometry2::new(Vector2::new(12.0, 6.0), 0.0),
        true,
    )
    .unwrap();
    // east along the corridor: the beam straight ahead reads the end wall at x = 20, 8 m off
    let x_at = |k: u64| 12.0 + STRIDE_M * k as f64;
    let mut reported = BTreeMap::new();
    let (mut stamped, mut late, mut repeats) = (Vec::new(), 0, 0);
    let mut last: Option<(u64, Vec<f64>)> = None;
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut k = 0;
    while stamped.len() < 60 {
        assert!(
            Instant::now() < deadline,
            "too few frames: {}",
            stamped.len()
        );
        host.step(clock.now());
        let time_ns = k * READ_NS;
        reported.insert(time_ns, x_at(k));
        if let Ok(frame) = ghost.sense_at(Isometry2::new(Vector2::new(x_at(k), 6.0), 0.0), time_ns)
            && !frame.laser_m.is_empty()
        {
            assert_eq!(frame.time_ns, time_ns);
            let x = *reported
                .get(&frame.ranges_time_ns)
                .unwrap_or_else(|| panic!("{} is no read's time", frame.ranges_time_ns));
            late += usize::from(frame.ranges_time_ns < time_ns);
            if let Some((stamp, laser_m)) = &last {
                assert!(frame.ranges_time_ns >= *stamp, "a stamp went back");
                if *laser_m == frame.laser_m {
                    // the world has not stepped since: the same readings, the same stamp
                    assert_eq!(
                        frame.ranges_time_ns, *stamp,
                        "a frame returned again is restamped"
                    );
                    repeats += 1;
                }
            }
            last = Some((frame.ranges_time_ns, frame.laser_m.clone()));
            // the forward beam and the pose it was sensed at, and where the ghost is now
            stamped.push((frame.laser_m[frame.laser_m.len() / 2], x, x_at(k)));
        }
        k += 1;
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(late > 0, "no frame trailed its read: nothing shown");
    assert!(repeats > 0, "no frame was returned again: nothing shown");
    // the forward beam reads the end wall at x = 20 from the laser, mounted ahead of the axle
    let mount = iw_sim::ChairSpec::default()
        .laser
        .expect("the default chair has a laser")
        .t_body_laser
        .translation
        .x;
    let off = |range: f64, x: f64| (range + x + mount - 20.0).abs();
    let mean = |of: &dyn Fn(&(f64, f64, f64)) -> f64| {
        stamped.iter().map(of).sum::<f64>() / stamped.len() as f64
    };
    let at_stamp = mean(&|&(range, x, _)| off(range, x));
    let at_read = mean(&|&(range, _, now)| off(range, now));
    // the laser's noise is 1 cm: its mean absolute value 0.8 cm
    assert!(at_stamp < 0.015, "{at_stamp} m off at the stamped poses");
    assert!(
        at_read > at_stamp,
        "the read's own pose fits as well ({at_read} m against {at_stamp} m)"
    );
}
