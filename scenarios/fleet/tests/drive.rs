//! Driving by hand through the whole chair: stick readings in the interface agent's queue, the
//! `drive` stream over the bus, the real control agent's shared control, the simulated body.

use std::time::Duration;

use iw_fleet::{ChairConfig, Fleet};
use iw_interface::RawInput;
use iw_sim::Map;
use nalgebra::{Isometry2, Vector2};

const SAMPLE: &str = include_str!("../../maps/sample-building.map");
const STEP: Duration = Duration::from_millis(50);

fn fleet_with(x: f64, y: f64, deg: f64) -> Fleet {
    let map = Map::parse(SAMPLE, "sample-building.map").unwrap();
    let chair = ChairConfig {
        name: "chair-0".into(),
        t_world_body: Isometry2::new(Vector2::new(x, y), deg.to_radians()),
    };
    Fleet::new(map, 3, &[chair]).unwrap()
}

/// Holds `reading` for `s` seconds (the device reports every 100 ms), or stays silent (`None`).
fn hold(fleet: &mut Fleet, reading: Option<RawInput>, s: f64) {
    let inputs = fleet.inputs("chair-0").unwrap();
    let end = fleet.time_s() + s;
    let mut k = 0u64;
    while fleet.time_s() < end - 1e-9 {
        if let Some(r) = &reading
            && k.is_multiple_of(2)
        {
            inputs.lock().unwrap().push_back((r.clone(), k * 50));
        }
        fleet.step(STEP);
        k += 1;
    }
}

fn forward() -> Option<RawInput> {
    Some(RawInput::Joystick { x: 0.0, y: 1.0 })
}

#[test]
fn straight_at_a_wall_the_chair_stops_short_and_on_release_it_stops_within_the_watchdog() {
    // At the entrance facing north: the corridor's north wall (y = 7) 1 m ahead. The user holds
    // the stick full forward; shared control turns the chair away (the potential field) and
    // holds it back (the arc guard), so it never touches the wall.
    let mut fleet = fleet_with(1.0, 6.0, 90.0);
    let mut held_back = false;
    for _ in 0..30 {
        hold(&mut fleet, forward(), 0.2);
        let chair = &fleet.snapshot().chairs[0];
        assert_eq!(chair.collisions, 0, "{chair:?}");
        assert!(chair.pose[1] < 6.6, "short of the wall: {:?}", chair.pose);
        let status = fleet.drive_status("chair-0").unwrap();
        let (user, applied) = (status.user.unwrap(), status.applied.unwrap());
        assert!((user.linear_mps - 0.6).abs() < 1e-9, "{status:?}");
        held_back |= applied.linear_mps < 0.1;
    }
    assert!(
        held_back,
        "shared control held the chair back at some point"
    );

    // Turned away (east, along the corridor) and driving: then silence.
    let mut fleet = fleet_with(1.0, 6.0, 0.0);
    hold(&mut fleet, forward(), 2.0);
    let moving = fleet.snapshot().chairs[0].twist[0];
    assert!(moving > 0.4, "drives along the corridor: {moving}");
    let display = fleet.display("chair-0").unwrap();
    assert!(display.drive.is_some(), "{display:?}");
    // The page is gone: no more readings. The interface releases after its 300 ms hold (a stop
    // in the stream); the 1.5 m/s^2 ramp stops the wheels from 0.6 m/s in 0.4 s.
    hold(&mut fleet, None, 0.5 + 0.5);
    let chair = &fleet.snapshot().chairs[0];
    assert!(chair.twist[0].abs() < 0.01, "stopped: {:?}", chair.twist);
    hold(&mut fleet, None, 0.5);
    let answer = fleet.display("chair-0").unwrap().last_answer;
    assert!(
        answer.as_deref().unwrap_or("").starts_with("INFORM"),
        "the stream ended done: {answer:?}"
    );
}

#[test]
fn through_the_office_doorway_without_contact() {
    // In the corridor in front of the open office door (2.9..4.1 at y = 5), facing south.
    let mut fleet = fleet_with(3.5, 6.0, -90.0);
    hold(&mut fleet, forward(), 5.0);
    hold(&mut fleet, Some(RawInput::Joystick { x: 0.0, y: 0.0 }), 0.6);
    let chair = &fleet.snapshot().chairs[0];
    assert_eq!(chair.collisions, 0, "{chair:?}");
    assert!(chair.pose[1] < 4.0, "in the office: {:?}", chair.pose);
    assert!(chair.twist[0].abs() < 0.01, "released: {:?}", chair.twist);
}
