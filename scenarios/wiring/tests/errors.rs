//! A virtual body's and the door actuator's failures to reach the world keep the bus's error:
//! `source()` is the `BusError` itself, and the message (which the door agent sends as an SL
//! `error-message`) still ends with what the bus said.

use std::collections::BTreeMap;
use std::error::Error;
use std::sync::Arc;

use iw_body::{Body, BodyError, WheelSpeeds};
use iw_bus::{Bus, BusConfig, BusError, Clock, InProcNetwork, Stack};
use iw_door::DoorActuator;
use iw_wiring::agent_id;
use iw_wiring::world_link::{WorldBody, WorldDoors, world_agent};
use nalgebra::Isometry2;

/// A chair's bus with no route to the world.
fn isolated_bus() -> Arc<Bus> {
    let network = InProcNetwork::new();
    Arc::new(
        Bus::start(
            Stack::new(),
            Arc::new(network.endpoint("c1").unwrap()),
            Clock::system(),
            BusConfig::default(),
        )
        .unwrap(),
    )
}

/// The `BusError` under `err`: no route to the world, and said at the end of the message.
fn no_route(err: &(dyn Error + 'static)) {
    let cause = err
        .source()
        .and_then(|s| s.downcast_ref::<BusError>())
        .unwrap_or_else(|| panic!("no BusError under `{err}`"));
    assert!(
        matches!(cause, BusError::NoRoute { receiver } if *receiver == world_agent().name),
        "{cause}"
    );
    assert!(err.to_string().ends_with(&cause.to_string()), "{err}");
}

#[test]
fn a_drive_the_world_cannot_hear_keeps_the_bus_error() {
    let mut body = WorldBody::open(isolated_bus(), "c1", Isometry2::identity()).unwrap();
    let err = body
        .command(WheelSpeeds {
            left_mps: 0.2,
            right_mps: 0.2,
        })
        .unwrap_err();
    assert!(
        matches!(
            err,
            BodyError::World {
                what: "world unreachable",
                ..
            }
        ),
        "{err}"
    );
    no_route(&err);
}

#[test]
fn a_door_the_world_cannot_hear_keeps_the_bus_error() {
    let bus = isolated_bus();
    let door_agent = agent_id("door", "services");
    let _mailbox = bus.register(&door_agent.name).unwrap();
    let ids = BTreeMap::from([("door-d1".to_string(), "d1".to_string())]);
    let mut doors = WorldDoors::new(bus, door_agent, ids);
    let fault = doors.set("door-d1", true).unwrap_err();
    assert_eq!(fault.door, "door-d1");
    assert_eq!(fault.reason, "world unreachable");
    no_route(&fault);
    // a door the map lacks has nothing underneath
    let fault = doors.set("door-nowhere", true).unwrap_err();
    assert!(fault.source().is_none(), "{fault}");
}
