//! The scenario parser: no input panics it (nor the check against a map), and a scenario written
//! back as TOML reads back equal.

use std::path::Path;

use iw_fleet::BodyKind;
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
        (time(), name(), proptest::option::of(time()))
            .prop_map(|(at_s, chair, for_s)| Fault::SensorFailure { at_s, chair, for_s }),
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
            step_ms,
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
