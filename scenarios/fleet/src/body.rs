//! A chair's body in the fleet: virtual (the simulator drives it), real (the serial driver and
//! an emulated board, its pose fed into the world) or mixed, each wrapped so a sensor failure can
//! be injected; and a virtual chair's camera.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use iw_body::{
    BoardEmulator, Body, BodyError, MixedBody, Odometry, SensorFrame, SerialBody, VirtualSensors,
    WheelGeometry, WheelSpeeds,
};
use iw_perception::VisualConfig;
use iw_sim::{ChairId, GhostSensors, SharedWorld, VirtualBody};
use iw_wiring as compose;
use iw_wiring::world_link::FrameFaults;
use iw_wiring::{Cause, SharedBody, StartError};
use nalgebra::Isometry2;

use crate::{BodyKind, FleetError};

/// The sensor faults that can be injected into a chair's body.
#[derive(Debug, Clone, Default)]
pub struct SensorFaults {
    /// Every read fails (the control agent then stops the chair and fails its task).
    pub failed: Arc<AtomicBool>,
    /// The laser returns no ranges (covered or broken) while the rest reads on: the localizer
    /// can no longer match the map and dead-reckons.
    pub laser_blind: Arc<AtomicBool>,
    /// The laser returns garbage while the rest reads on
    /// ([`iw_wiring::world_link::FrameFaults`], as a world container sends it).
    pub laser_garbage: Arc<AtomicBool>,
    /// The sonars return garbage while the rest reads on.
    pub sonar_garbage: Arc<AtomicBool>,
}

impl SensorFaults {
    /// The faults of the readings now, as a world container applies them to its frames.
    fn frame(&self) -> FrameFaults {
        FrameFaults {
            laser_blind: self.laser_blind.load(Ordering::Acquire),
            laser_garbage: self.laser_garbage.load(Ordering::Acquire),
            sonar_garbage: self.sonar_garbage.load(Ordering::Acquire),
        }
    }
}

/// A [`Body`] whose sensors can be failed on purpose ([`SensorFaults`]).
pub struct FaultyBody<B> {
    inner: B,
    faults: SensorFaults,
}

impl<B: Body> FaultyBody<B> {
    /// Wraps `inner`; `faults` switch the failures.
    pub fn new(inner: B, faults: SensorFaults) -> Self {
        FaultyBody { inner, faults }
    }
}

impl<B: Body> Body for FaultyBody<B> {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        if self.faults.failed.load(Ordering::Acquire) {
            return Err(BodyError::Virtual {
                reason: "sensor failure injected".into(),
            });
        }
        let mut frame = self.inner.read()?;
        self.faults
            .frame()
            .apply(&mut frame.laser_m, &mut frame.sonar_m);
        Ok(frame)
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        self.inner.command(speeds)
    }
}

/// The perception agent's camera for virtual chair `id`: the simulator's renderer
/// ([`compose::camera::visual_config`]).
pub(crate) fn sim_camera(
    world: &SharedWorld,
    id: ChairId,
    name: &str,
) -> Result<VisualConfig, FleetError> {
    let camera = iw_sim::vo::SimCamera::new(world.clone(), id).map_err(|e| {
        FleetError::Start(StartError {
            container: name.to_string(),
            what: "its camera".into(),
            source: e.into(),
        })
    })?;
    Ok(compose::camera::visual_config(camera))
}

/// The real chair's virtual side when it senses nothing virtual: its ghost is placed at the
/// pose the real chair reports (virtual chairs see it, collisions are counted), no readings.
pub(crate) struct PoseFeed(GhostSensors);

impl VirtualSensors for PoseFeed {
    fn sense_at(
        &mut self,
        t_world_body: Isometry2<f64>,
        time_ns: u64,
    ) -> Result<SensorFrame, BodyError> {
        self.0.sense_at(t_world_body, time_ns)?;
        Ok(SensorFrame::empty(time_ns))
    }
}

/// The body of a chair and, for a real or mixed one, the board emulator it talks to.
pub(crate) fn body_for(
    kind: BodyKind,
    name: &str,
    world: &SharedWorld,
    id: ChairId,
    t_world_body: Isometry2<f64>,
    faults: SensorFaults,
) -> Result<(SharedBody, Option<BoardEmulator>), FleetError> {
    let setup = |what: &str, source: Cause| {
        FleetError::Start(StartError {
            container: name.to_string(),
            what: what.into(),
            source,
        })
    };
    if kind == BodyKind::Virtual {
        return Ok((
            SharedBody::new(FaultyBody::new(VirtualBody::new(world.clone(), id), faults)),
            None,
        ));
    }
    let geometry = WheelGeometry::default();
    let board = BoardEmulator::spawn(geometry, compose::CONTROL_PERIOD.as_nanos() as u64)
        .map_err(|e| setup("its board emulator", e.into()))?;
    let serial = SerialBody::open(board.port_name(), 115_200, Duration::from_secs(2))
        .map_err(|e| setup("its serial body", e.into()))?;
    let odometry = Odometry::new(geometry, t_world_body);
    let ghost = GhostSensors::new(world.clone(), id);
    let body = if kind == BodyKind::Mixed {
        SharedBody::new(FaultyBody::new(
            MixedBody::new(serial, ghost, odometry),
            faults,
        ))
    } else {
        SharedBody::new(FaultyBody::new(
            MixedBody::new(serial, PoseFeed(ghost), odometry),
            faults,
        ))
    };
    Ok((body, Some(board)))
}
