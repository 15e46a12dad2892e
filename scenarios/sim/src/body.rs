//! The simulator as an [`iw_body::Body`]: agents drive virtual chairs exactly like real ones,
//! and real chairs get virtual readings (mixed reality).

use std::sync::{Arc, Mutex, MutexGuard};

use iw_body::{Body, BodyError, SensorFrame, VirtualSensors, WheelSpeeds};
use nalgebra::Isometry2;

use crate::{ChairId, World};

/// A world shared between the loop that steps it and the bodies that read and command it.
pub type SharedWorld = Arc<Mutex<World>>;

/// Wraps a world for sharing.
pub fn shared(world: World) -> SharedWorld {
    Arc::new(Mutex::new(world))
}

pub(crate) fn lock(world: &SharedWorld) -> MutexGuard<'_, World> {
    // the world holds plain data; a panicked holder cannot leave it unusable
    world
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn virtual_err(e: crate::SimError) -> BodyError {
    BodyError::World {
        what: "the simulator",
        source: Box::new(e),
    }
}

/// A handle to one simulated chair. `read` returns the frame of the last [`crate::step`];
/// whoever owns the loop steps the world.
#[derive(Debug, Clone)]
pub struct VirtualBody {
    world: SharedWorld,
    id: ChairId,
}

impl VirtualBody {
    /// The body of chair `id` in `world`.
    pub fn new(world: SharedWorld, id: ChairId) -> Self {
        Self { world, id }
    }

    /// The chair this body drives.
    pub fn id(&self) -> ChairId {
        self.id
    }
}

impl Body for VirtualBody {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        lock(&self.world)
            .sensors(self.id)
            .cloned()
            .map_err(virtual_err)
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        lock(&self.world)
            .command(self.id, speeds)
            .map_err(virtual_err)
    }
}

/// The virtual body of a real chair: placed at the pose the real chair reports, it returns
/// what its virtual sensors see (virtual chairs, doors, obstacles).
#[derive(Debug, Clone)]
pub struct GhostSensors {
    world: SharedWorld,
    id: ChairId,
}

impl GhostSensors {
    /// Uses chair `id` (add it as [`crate::ChairKind::Tracked`]) as the real chair's ghost.
    pub fn new(world: SharedWorld, id: ChairId) -> Self {
        Self { world, id }
    }
}

impl VirtualSensors for GhostSensors {
    fn sense_at(
        &mut self,
        t_world_body: Isometry2<f64>,
        time_ns: u64,
    ) -> Result<SensorFrame, BodyError> {
        let mut world = lock(&self.world);
        world.place(self.id, t_world_body).map_err(virtual_err)?;
        // sensed at once where it was placed: in the caller's clock, now
        let frame = world.sensors(self.id).map_err(virtual_err)?;
        Ok(SensorFrame {
            time_ns,
            ranges_time_ns: time_ns,
            ..frame.clone()
        })
    }
}
