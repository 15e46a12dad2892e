//! The simulator's refusals reach the agents' error types whole: a virtual body's read or
//! command that the world refuses is a `BodyError` whose `source()` is the `SimError` itself,
//! and its message still ends with what the simulator said.

use std::error::Error;

use iw_body::{Body, BodyError, VirtualSensors, WheelSpeeds};
use iw_sim::{ChairId, GhostSensors, Map, SimError, VirtualBody, World, shared};
use nalgebra::Isometry2;

fn chairless_world() -> iw_sim::SharedWorld {
    let map = Map::parse("wall closed 0 0 4 0 4 4 0 4\n", "room.map").unwrap();
    shared(World::new(map, 1))
}

/// The `SimError` under `err`, checking the message ends with it.
fn sim_cause(err: &BodyError) -> &SimError {
    assert!(matches!(err, BodyError::World { .. }), "{err:?}");
    let cause = err
        .source()
        .and_then(|s| s.downcast_ref::<SimError>())
        .unwrap_or_else(|| panic!("no SimError under `{err}`"));
    assert!(err.to_string().ends_with(&cause.to_string()), "{err}");
    cause
}

#[test]
fn a_body_of_a_chair_the_world_lacks_keeps_the_simulators_error() {
    let mut body = VirtualBody::new(chairless_world(), ChairId(3));
    let err = body.read().unwrap_err();
    assert!(
        matches!(sim_cause(&err), SimError::NoSuchChair { id: 3, count: 0 }),
        "{err}"
    );
    let err = body.command(WheelSpeeds::STOP).unwrap_err();
    assert!(matches!(sim_cause(&err), SimError::NoSuchChair { .. }));
}

#[test]
fn a_ghost_the_world_cannot_place_keeps_the_simulators_error() {
    let mut ghost = GhostSensors::new(chairless_world(), ChairId(0));
    let err = ghost.sense_at(Isometry2::identity(), 0).unwrap_err();
    assert!(matches!(
        sim_cause(&err),
        SimError::NoSuchChair { id: 0, .. }
    ));
}
