//! The composed fleet on the sample building: goals go staff console -> assistant -> cognitive
//! -> door and control agents, every message reaches the logger.

use std::time::Duration;

use iw_fleet::{ChairConfig, Fleet};
use iw_sim::Map;
use nalgebra::{Isometry2, Vector2};

const SAMPLE: &str = include_str!("../../maps/sample-building.map");

fn chair(name: &str, x: f64, y: f64, deg: f64) -> ChairConfig {
    ChairConfig {
        name: name.into(),
        t_world_body: Isometry2::new(Vector2::new(x, y), deg.to_radians()),
    }
}

fn run_until_answered(fleet: &mut Fleet, conversation: &str, max_s: f64) -> Option<String> {
    while fleet.time_s() < max_s {
        fleet.step(Duration::from_millis(50));
        let done = fleet
            .goal_events()
            .into_iter()
            .find(|e| e.conversation == conversation && e.performative != "AGREE");
        if let Some(e) = done {
            return Some(e.performative);
        }
    }
    None
}

#[test]
fn a_goal_through_a_door_is_planned_opened_and_driven() {
    let map = Map::parse(SAMPLE, "sample-building.map").unwrap();
    let mut fleet = Fleet::new(map, 1, &[chair("chair1", 1.0, 6.0, 0.0)]).unwrap();
    let conversation = fleet.goal_place("chair1", "office").unwrap();
    let answer = run_until_answered(&mut fleet, &conversation, 60.0);
    let snapshot = fleet.snapshot();
    assert_eq!(
        answer.as_deref(),
        Some("INFORM"),
        "at {:.1} s: {:?}",
        snapshot.time_s,
        snapshot.chairs[0]
    );
    let chair = &snapshot.chairs[0];
    assert_eq!(chair.collisions, 0);
    // The chair steers by dead reckoning with the simulated encoder errors (tyre compression up
    // to 3 %, slip) over about 7 m: its true pose may sit a few decimetres from the place.
    assert!(
        (chair.pose[0] - 4.5).hypot(chair.pose[1] - 2.5) < 0.45,
        "in the office: {:?}",
        chair.pose
    );
    fleet.quiesce(8);
    let log = iw_logger::read_records(fleet.log_path(), iw_logger::DEFAULT_MAX_RECORD_LEN).unwrap();
    let logged: Vec<iw_logger::LoggedMessage> = log
        .iter()
        .map(|r| iw_logger::LoggedMessage::from_record(r).unwrap())
        .collect();
    let door_opened = logged.iter().any(|m| {
        m.sender == "door@services" && m.performative == "inform" && m.acl.contains("office-door")
    });
    let drove = logged.iter().any(|m| {
        m.sender == "cognitive@chair1"
            && m.receivers == ["control@chair1"]
            && m.acl.contains("goto-xy")
    });
    assert!(
        door_opened && drove,
        "the door agent opened the door and the cognitive agent sent the control agent a route"
    );
    assert_eq!(
        fleet.messages_logged().unwrap(),
        fleet.messages_sent(),
        "every message sent is in the log"
    );
}
