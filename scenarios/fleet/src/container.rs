//! The fleet's containers: a chair's agents or the service agents on their own bus over the
//! lockstep network, routed to the others.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use iw_agent::AgentHost;
use iw_body::BoardEmulator;
use iw_bus::{Bus, BusConfig, Clock, Stack};
use iw_control::SharedDriveStatus;
use iw_door::RefusalLog;
use iw_interface::{Display, InputQueue};
use iw_sim::ChairId;
use iw_wiring as compose;
use iw_wiring::{Cause, SharedDesk, StartError};

use crate::{BodyKind, FleetError, LockstepNetwork, SensorFaults};

pub(crate) fn bus_for(
    network: &LockstepNetwork,
    clock: &Clock,
    container: &str,
) -> Result<Arc<Bus>, FleetError> {
    let setup = |what: &str, source: Cause| {
        FleetError::Start(StartError {
            container: container.to_string(),
            what: what.into(),
            source,
        })
    };
    let transport = network
        .endpoint(container)
        .map_err(|e| setup("its network endpoint", e.into()))?;
    let config = BusConfig {
        tick: Duration::from_millis(1),
        ..BusConfig::default()
    };
    let bus = Bus::start(Stack::new(), Arc::new(transport), clock.clone(), config)
        .map_err(|e| setup("the bus", e.into()))?;
    Ok(Arc::new(bus))
}

/// Routes `host`'s bus to the agents of the other containers.
pub(crate) fn route(host: &AgentHost, container: &str, chairs: &[String]) {
    for (agent, peer) in compose::remote_agents(container, chairs) {
        host.bus()
            .add_route(&agent, iw_bus::transport::PeerAddr(peer));
    }
}

/// A chair's container: its agents on its own bus.
pub struct ChairContainer {
    pub(crate) name: String,
    pub(crate) id: ChairId,
    pub(crate) kind: BodyKind,
    pub(crate) host: AgentHost,
    pub(crate) faults: SensorFaults,
    pub(crate) inputs: InputQueue,
    pub(crate) drive_status: SharedDriveStatus,
    pub(crate) display: Arc<Mutex<Display>>,
    // dropped after the host (fields drop in order), so the driver never outlives its board
    pub(crate) _board: Option<BoardEmulator>,
}

impl ChairContainer {
    /// The chair's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The agents running in this container.
    pub fn agents(&self) -> Vec<String> {
        self.host.agent_names()
    }
}

/// The service agents' container.
pub struct ServiceContainer {
    pub(crate) host: AgentHost,
    pub(crate) desk: SharedDesk,
    pub(crate) refusals: RefusalLog,
}
