//! A world container's agent for the link tests.

use std::sync::Arc;

use iw_agent::AgentHost;
use iw_bus::transport::PeerAddr;
use iw_bus::{Bus, BusConfig, Clock, InProcNetwork, Stack};
use iw_wiring::agent_id;
use iw_wiring::world_link::{WorldAgent, body_endpoint, world_agent};

/// A bus at `endpoint` of `network`.
pub fn bus(network: &InProcNetwork, clock: &Clock, endpoint: &str) -> Arc<Bus> {
    Arc::new(
        Bus::start(
            Stack::new(),
            Arc::new(network.endpoint(endpoint).unwrap()),
            clock.clone(),
            BusConfig::default(),
        )
        .unwrap(),
    )
}

/// A world on its own bus (endpoint `endpoint`) with chair `c1`'s body routed to it.
pub fn world(network: &InProcNetwork, clock: &Clock, endpoint: &str) -> AgentHost {
    let bus = bus(network, clock, endpoint);
    bus.add_route(&body_endpoint("c1").name, PeerAddr("c1".into()));
    let map = iw_sim::Map::parse(
        include_str!("../../../maps/sample-building.map"),
        "sample-building.map",
    )
    .unwrap();
    let agent = WorldAgent::new(
        iw_sim::shared(iw_sim::World::new(map, 1)),
        agent_id("door", "services"),
    );
    let mut host = AgentHost::new(bus);
    host.add(world_agent(), Box::new(agent)).unwrap();
    host
}
