//! The scenario parser: no input panics it (nor the check against a map), and a scenario written
//! back as TOML reads back equal.

use std::path::Path;

use iw_fleet::BodyKind;
use iw_fleet::compose::world_link::FailedSensor;
use iw_scenario::{Assertion, ChairEntry, DoorEntry, Fault, GoalEntry, RestrictedEntry, Scenario};
use iw_sim::Map;
use proptest::prelude::*;

const SAMPLE: &str = include_str!("../../maps/sample-building.map");

fn name() -> impl Strategy<Value = String> {
    // names with quotes, backslashes, unicode and newlines exercise TOML escaping
    prop_oneof![
        "[a-z][a-z0-9-]{0,8}",
        "\\PC{0,6}",
        Just("a\"b\\c\nd".to_string())
    ]
}

fn time() -> impl Strategy<Value = f64> {
    prop_oneof![0.0..100.0f64, Just(0.0), Just(1e-300)]
}

fn chair() -> impl Strategy<Value = ChairEntry> {
    (
        name(),
        proptest::option::of(name()),
        proptest::option::of(proptest::array::uniform3(-50.0..50.0f64)),
        0..3u8,
    )
        .prop_map(|(name, start, pose, body)| ChairEntry {
            name,
            start,
            pose,
            body: [BodyKind::Virtual, BodyKind::Real, BodyKind::Mixed][body as usize],
        })
}

fn fault() -> impl Strategy<Value = Fault> {
    prop_oneof![
        (time(), name(), proptest::option::of(time())).prop_map(|(at_s, container, for_s)| {
            Fault::LinkLoss {
                at_s,
                container,
                for_s,
            }
        }),
        (time(), name(), name()).prop_map(|(at_s, container, agent)| Fault::KillAgent {
            at_s,
            container,
            agent
        }),
        (
            time(),
            name(),
            prop_oneof![
                Just(FailedSensor::All),
                Just(FailedSensor::Laser),
                Just(FailedSensor::Sonars)
            ],
            proptest::option::of(time())
        )
            .prop_map(|(at_s, chair, sensor, for_s)| Fault::SensorFailure {
                at_s,
                chair,
                sensor,
                for_s
            }),
        (time(), name(), proptest::option::of(time()))
            .prop_map(|(at_s, chair, for_s)| Fault::LaserBlind { at_s, chair, for_s }),
        (time(), name()).prop_map(|(at_s, door)| Fault::JammedDoor { at_s, door }),
    ]
}

fn assertion() -> impl Strategy<Value = Assertion> {
    prop_oneof![
        proptest::option::of(name()).prop_map(|chair| Assertion::NoCollision { chair }),
        (name(), time(), 0.01..5.0f64).prop_map(|(chair, by_s, within_m)| Assertion::GoalReached {
            chair,
            by_s,
            within_m
        }),
        (name(), time()).prop_map(|(chair, by_s)| Assertion::GoalFailed { chair, by_s }),
        (name(), time(), time(), 0.01..5.0f64).prop_map(|(chair, from_s, by_s, within_m)| {
            Assertion::LandmarkVisited {
                chair,
                from_s,
                by_s,
                within_m,
            }
        }),
        (name(), time()).prop_map(|(chair, from_s)| Assertion::Stopped { chair, from_s }),
        any::<u64>().prop_map(|at_least| Assertion::MessagesDropped {
            at_least: at_least >> 1
        }),
        (name(), name()).prop_map(|(chair, door)| Assertion::DoorRefused { chair, door }),
        name().prop_map(|door| Assertion::DoorFailed { door }),
        Just(Assertion::AllMessagesLogged),
    ]
}

prop_compose! {
    fn scenario()(
        name in name(),
        description in name(),
        seed in any::<u64>().prop_map(|s| s >> 1), // TOML integers are i64
        duration_s in time(),
        step_ms in 1..1000u64,
        visual_odometry in any::<bool>(),
        chairs in proptest::collection::vec(chair(), 0..3),
        goals in proptest::collection::vec((time(), name(), proptest::option::of(name()), proptest::option::of(proptest::array::uniform2(-50.0..50.0f64))), 0..3),
        doors in proptest::collection::vec((time(), name(), any::<bool>()), 0..3),
        faults in proptest::collection::vec(fault(), 0..3),
        restricted in proptest::collection::vec((name(), proptest::collection::vec(name(), 0..3)), 0..2),
        assertions in proptest::collection::vec(assertion(), 0..4),
    ) -> Scenario {
        Scenario {
            name,
            description,
            map: "maps/sample-building.map".into(),
            seed,
            duration_s,
            step: std::time::Duration::from_millis(step_ms),
            visual_odometry,
            chairs,
            goals: goals.into_iter().map(|(at_s, chair, place, xy)| GoalEntry { at_s, chair, place, xy }).collect(),
            doors: doors.into_iter().map(|(at_s, door, open)| DoorEntry { at_s, door, open }).collect(),
            faults,
            restricted: restricted.into_iter().map(|(door, authorised)| RestrictedEntry { door, authorised }).collect(),
            assertions,
            source: "prop.toml".into(),
        }
    }
}

proptest! {
    #[test]
    fn any_text_parses_or_is_an_error_naming_the_file(text in "\\PC{0,300}") {
        let map = Map::parse(SAMPLE, "sample-building.map").unwrap();
        match Scenario::parse(&text, Path::new("any.toml")) {
            Ok(s) => {
                if let Err(e) = s.validate(&map) {
                    prop_assert!(e.to_string().starts_with("any.toml:"), "{}", e);
                }
            }
            Err(e) => prop_assert!(e.to_string().starts_with("any.toml:"), "{}", e),
        }
    }

    #[test]
    fn scenarios_round_trip_through_toml(scenario in scenario()) {
        let text = toml::to_string(&scenario).unwrap();
        let back = Scenario::parse(&text, Path::new("prop.toml")).unwrap();
        prop_assert_eq!(back, scenario, "{}", text);
        // and checking it against a map never panics, whatever it names
        let _ = Scenario::parse(&text, Path::new("prop.toml")).unwrap().validate(&Map::parse(SAMPLE, "s.map").unwrap());
    }
}

/// The two-chair scenario with `chairs` and `goal_at_s` put in; validated against the sample map.
fn check(chairs: &str, goal_at_s: &str) -> Result<(), String> {
    let text = format!(
        "name = \"hostile\"\nmap = \"maps/sample-building.map\"\nduration_s = 20\n{chairs}\n\
         [[goal]]\nat_s = {goal_at_s}\nchair = \"a\"\nxy = [5.5, 6.0]\n"
    );
    let scenario = Scenario::parse(&text, Path::new("hostile.toml")).map_err(|e| e.to_string())?;
    let map = Map::parse(SAMPLE, "sample-building.map").unwrap();
    scenario.validate(&map).map_err(|e| e.to_string())
}

#[test]
fn bad_start_poses_and_times_are_refused_naming_the_entry() {
    let chair = |name: &str, pose: &str| format!("[[chair]]\nname = \"{name}\"\npose = {pose}\n");
    let fine = chair("a", "[1.0, 6.0, 0.0]");
    assert_eq!(check(&fine, "0.5"), Ok(()));
    // On the closed door `bedroom1` (1.4, 7)-(2.6, 7).
    let on_door = check(&chair("a", "[2.0, 7.0, 90.0]"), "0.5").unwrap_err();
    assert!(
        on_door.contains("chair[0]") && on_door.contains("the closed door `bedroom1`"),
        "{on_door}"
    );
    // In a wall.
    let in_wall = check(&chair("a", "[0.7, 7.0, 0.0]"), "0.5").unwrap_err();
    assert!(
        in_wall.contains("chair[0]") && in_wall.contains("a wall"),
        "{in_wall}"
    );
    // Two chairs on one pose.
    let twice = format!("{fine}{}", chair("b", "[1.0, 6.0, 0.0]"));
    let twice = check(&twice, "0.5").unwrap_err();
    assert!(
        twice.contains("chair[1]") && twice.contains("chair[0] `a`"),
        "{twice}"
    );
    // A goal that would never come.
    let never = check(&fine, "1e308").unwrap_err();
    assert!(
        never.contains("goal[0]") && never.contains("within the run"),
        "{never}"
    );
}

#[test]
fn a_route_through_a_wall_is_refused_with_its_line() {
    let map = "wall 0 0 10 0\nwall 5 -5 5 5\nroute across 1 1 9 1\n";
    let err = Map::parse(map, "walls.map").unwrap_err().to_string();
    assert!(
        err.contains("walls.map:3") && err.contains("route `across`") && err.contains("wall"),
        "{err}"
    );
    let around = "wall 0 0 10 0\nwall 5 -5 5 5\nroute around 1 1 4 1 4 6 6 6 6 1\n";
    assert!(Map::parse(around, "walls.map").is_ok());
    let table = "wall 0 -1 10 -1\nbox 5 1 1 1 name=table\nroute lap closed 1 1 9 1 9 3\n";
    let err = Map::parse(table, "table.map").unwrap_err().to_string();
    assert!(err.contains("furniture `table`"), "{err}");
}
