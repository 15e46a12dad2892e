//! The world's doors as the door agent moves them; a door can be jammed on purpose.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex, PoisonError};

use iw_door::{ActuatorFault, DoorActuator};
use iw_sim::SharedWorld;
use iw_wiring as compose;

/// Moves the world's doors for the door agent; a jammed door faults.
pub(crate) struct WorldDoors {
    pub(crate) world: SharedWorld,
    /// The door agent's door names to map door ids.
    pub(crate) ids: BTreeMap<String, String>,
    pub(crate) jammed: Arc<Mutex<BTreeSet<String>>>,
}

impl DoorActuator for WorldDoors {
    fn set(&mut self, door: &str, open: bool) -> Result<(), ActuatorFault> {
        let id = compose::map_door(&self.ids, door)?;
        if self
            .jammed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .contains(id)
        {
            return Err(ActuatorFault::new(door, "jammed"));
        }
        self.world
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .set_door(id, open)
            .map_err(|e| ActuatorFault::caused(door, "the simulator refused", e))
    }
}
