//! Containers per wheelchair and the fleet that composes them (thesis 3.3.3): each chair's
//! micro agents in their own container, the service agents in another, all talking FIPA-ACL
//! over real bus frames.
//!
//! # Organization
//! - [`ChairContainer`]: one [`AgentHost`] on its own [`Bus`] with a chair's perception and
//!   control agents over one [`iw_body::Body`] (here the simulator's [`VirtualBody`], wrapped by
//!   [`FaultyBody`] so a sensor failure can be injected).
//! - [`ServiceContainer`]: the service agents; today the [`Operator`] (staff giving goals).
//! - [`Fleet`]: the world, the containers and the [`LockstepNetwork`] between their buses, on
//!   one mock clock. [`Fleet::new`], [`Fleet::goal`], [`Fleet::step`], [`Fleet::snapshot`];
//!   faults: [`Fleet::set_link`], [`Fleet::kill_agent`], [`Fleet::set_sensor_failure`],
//!   [`Fleet::jam_door`].
//! - [`plan`]: the map as an occupancy grid, A* paths as action sequences.
//!
//! # Guarantees
//! - Deterministic: each step runs the containers in a fixed order at one simulated instant, then
//!   releases the frames between containers and waits until every one is in its mailbox, then
//!   steps the world; the same map, seed and calls give the same run.
//! - Containers share nothing but frames: a chair's agents and a service agent never hold each
//!   other; a killed agent or a downed link affects only what it carries.
//!
//! Agent names are `control@CHAIR`, `perception@CHAIR` and `operator@services`; a container's
//! endpoint is named after the chair (or `services`).
#![warn(missing_docs)]

mod network;
mod operator;
pub mod plan;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{AgentHost, HostStats};
use iw_body::{Body, BodyError, SensorFrame, WheelSpeeds};
use iw_bus::{Bus, BusConfig, Clock, MockController, Stack, Time};
use iw_control_agent::{ControlAgent, ControlConfig};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::WheelchairContent;
use iw_perception_agent::{PerceptionAgent, PerceptionConfig};
use iw_sim::{ChairId, ChairKind, ChairSpec, Map, SharedWorld, VirtualBody, World};
use iw_vo::Pose2;
use nalgebra::{Isometry2, Point2};

pub use network::{Exchange, LockstepNetwork, LockstepTransport};
pub use operator::{Desk, GoalEvent, Operator, SharedDesk};

/// The service container's endpoint name.
pub const SERVICES: &str = "services";

/// What went wrong composing or driving a fleet.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FleetError {
    /// Two chairs with one name, or a name that clashes with the services.
    #[error("chair name `{name}` is used twice or reserved")]
    DuplicateChair {
        /// The name.
        name: String,
    },
    /// A chair the fleet does not have.
    #[error("no chair `{name}` in the fleet")]
    NoSuchChair {
        /// The name asked for.
        name: String,
    },
    /// A container the fleet does not have (a chair name or `services`).
    #[error("no agent `{agent}` in container `{container}`")]
    NoSuchAgent {
        /// The container.
        container: String,
        /// The agent.
        agent: String,
    },
    /// A bus, transport or agent could not be set up.
    #[error("container `{container}`: {reason}")]
    Setup {
        /// The container.
        container: String,
        /// Why.
        reason: String,
    },
    /// The simulator refused (unknown door, door blocked).
    #[error("simulator: {source}")]
    Sim {
        /// What it said.
        #[from]
        source: iw_sim::SimError,
    },
    /// No path to a goal.
    #[error("cannot plan: {reason}")]
    Plan {
        /// Why.
        reason: String,
    },
}

/// A [`Body`] whose sensors can be failed on purpose: while failed, every read is an error
/// (the control agent then stops the chair and fails its task).
pub struct FaultyBody<B> {
    inner: B,
    failed: Arc<AtomicBool>,
}

impl<B: Body> FaultyBody<B> {
    /// Wraps `inner`; `failed` switches the failure.
    pub fn new(inner: B, failed: Arc<AtomicBool>) -> Self {
        FaultyBody { inner, failed }
    }
}

impl<B: Body> Body for FaultyBody<B> {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        if self.failed.load(Ordering::Acquire) {
            return Err(BodyError::Virtual { reason: "sensor failure injected".into() });
        }
        self.inner.read()
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        self.inner.command(speeds)
    }
}

/// One chair to put in the fleet.
#[derive(Debug, Clone)]
pub struct ChairConfig {
    /// The chair's name (its container's name).
    pub name: String,
    /// Where it starts in the map frame.
    pub t_world_body: Isometry2<f64>,
}

fn bus_for(network: &LockstepNetwork, clock: &Clock, container: &str) -> Result<Arc<Bus>, FleetError> {
    let setup = |reason: String| FleetError::Setup { container: container.to_string(), reason };
    let transport = network.endpoint(container).map_err(|e| setup(e.to_string()))?;
    let config = BusConfig { tick: Duration::from_millis(1), ..BusConfig::default() };
    let bus = Bus::start(Stack::new(), Arc::new(transport), clock.clone(), config).map_err(|e| setup(e.to_string()))?;
    Ok(Arc::new(bus))
}

/// A chair's container: its agents on its own bus.
pub struct ChairContainer {
    name: String,
    id: ChairId,
    host: AgentHost,
    sensor_failed: Arc<AtomicBool>,
}

impl ChairContainer {
    /// Composes the perception and control agents of chair `name` over `body`, on a bus of
    /// `network`.
    pub fn new(
        name: &str,
        network: &LockstepNetwork,
        clock: &Clock,
        body: impl Body + Clone + Send + 'static,
        id: ChairId,
        start: Pose2,
    ) -> Result<Self, FleetError> {
        let setup = |reason: String| FleetError::Setup { container: name.to_string(), reason };
        let mut host = AgentHost::new(bus_for(network, clock, name)?);
        let sensor_failed = Arc::new(AtomicBool::new(false));
        let perception_id = AgentId::new(format!("perception@{name}"));
        let perception = PerceptionAgent::new(
            PerceptionConfig::prototype(AgentId::new(name), start),
            Box::new(FaultyBody::new(body.clone(), sensor_failed.clone())),
            None,
        )
        .map_err(|e| setup(e.to_string()))?;
        let control_config = ControlConfig::prototype(Some(perception_id.clone())).map_err(|e| setup(e.to_string()))?;
        let control = ControlAgent::new(control_config, Box::new(FaultyBody::new(body, sensor_failed.clone())))
            .map_err(|e| setup(e.to_string()))?;
        host.add(perception_id, Box::new(perception)).map_err(|e| setup(e.to_string()))?;
        host.add(AgentId::new(format!("control@{name}")), Box::new(control)).map_err(|e| setup(e.to_string()))?;
        host.bus().add_route(&format!("operator@{SERVICES}"), iw_bus::transport::PeerAddr(SERVICES.into()));
        Ok(ChairContainer { name: name.to_string(), id: ChairId(id.0), host, sensor_failed })
    }

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
    host: AgentHost,
    desk: SharedDesk,
}

impl ServiceContainer {
    /// The operator agent on its own bus of `network`.
    pub fn new(network: &LockstepNetwork, clock: &Clock) -> Result<Self, FleetError> {
        let mut host = AgentHost::new(bus_for(network, clock, SERVICES)?);
        let desk = SharedDesk::default();
        host.add(AgentId::new(format!("operator@{SERVICES}")), Box::new(Operator::new(desk.clone())))
            .map_err(|e| FleetError::Setup { container: SERVICES.into(), reason: e.to_string() })?;
        Ok(ServiceContainer { host, desk })
    }
}

/// One chair as the snapshot shows it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ChairSnapshot {
    /// Its name.
    pub name: String,
    /// True pose in the world: x, y (m), heading (rad).
    pub pose: [f64; 3],
    /// Linear (m/s) and angular (rad/s) speed.
    pub twist: [f64; 2],
    /// Sonar ranges, m (`None`: no echo).
    pub sonar_m: Vec<Option<f64>>,
    /// Contacts with walls, furniture or chairs so far.
    pub collisions: u64,
    /// Distance driven, m.
    pub distance_m: f64,
    /// Its current goal, if any.
    pub goal: Option<[f64; 2]>,
    /// The waypoints it was sent.
    pub path: Vec<[f64; 2]>,
    /// The agents of its container.
    pub agents: Vec<String>,
}

/// The whole fleet at one instant.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Snapshot {
    /// Simulated time, s.
    pub time_s: f64,
    /// Every chair.
    pub chairs: Vec<ChairSnapshot>,
    /// Door id and whether it is open.
    pub doors: Vec<(String, bool)>,
    /// The service container's agents.
    pub services: Vec<String>,
    /// The last frames between containers.
    pub recent: Vec<Exchange>,
}

struct Goal {
    target: Point2<f64>,
    path: Vec<Point2<f64>>,
}

/// The world, its chairs' containers and the service container, stepped together.
pub struct Fleet {
    world: SharedWorld,
    clock: MockController,
    network: LockstepNetwork,
    chairs: Vec<ChairContainer>,
    goals: Vec<Option<Goal>>,
    services: ServiceContainer,
    jammed: Vec<String>,
    conversations: u64,
}

impl Fleet {
    /// A fleet of `chairs` on `map`; `seed` drives the simulator's noise.
    pub fn new(map: Map, seed: u64, chairs: &[ChairConfig]) -> Result<Self, FleetError> {
        let (clock, controller) = Clock::mock(Time::from_ns(0));
        let network = LockstepNetwork::new();
        let mut world = World::new(map, seed);
        let ids: Vec<ChairId> = chairs
            .iter()
            .map(|c| world.add_chair(ChairSpec::default(), c.t_world_body, ChairKind::Simulated))
            .collect();
        let world = iw_sim::shared(world);
        let services = ServiceContainer::new(&network, &clock)?;
        let mut containers: Vec<ChairContainer> = Vec::new();
        for (config, id) in chairs.iter().zip(ids) {
            if config.name == SERVICES || containers.iter().any(|c| c.name == config.name) {
                return Err(FleetError::DuplicateChair { name: config.name.clone() });
            }
            let t = config.t_world_body;
            let start = Pose2 { x: t.translation.x, y: t.translation.y, theta: t.rotation.angle() };
            let body = VirtualBody::new(world.clone(), id);
            containers.push(ChairContainer::new(&config.name, &network, &clock, body, id, start)?);
            let peer = iw_bus::transport::PeerAddr(config.name.clone());
            for agent in ["control", "perception"] {
                services.host.bus().add_route(&format!("{agent}@{}", config.name), peer.clone());
            }
        }
        let goals = containers.iter().map(|_| None).collect();
        Ok(Fleet { world, clock: controller, network, chairs: containers, goals, services, jammed: Vec::new(), conversations: 0 })
    }

    fn index(&self, chair: &str) -> Result<usize, FleetError> {
        self.chairs.iter().position(|c| c.name == chair).ok_or_else(|| FleetError::NoSuchChair { name: chair.into() })
    }

    fn world(&self) -> std::sync::MutexGuard<'_, World> {
        self.world.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.clock.now().0 as f64 * 1e-9
    }

    /// Plans a path for `chair` to `target` around walls, furniture and closed doors, and has the
    /// operator request it from the chair's control agent. Returns the goal's conversation id.
    pub fn goal(&mut self, chair: &str, target: Point2<f64>) -> Result<String, FleetError> {
        let i = self.index(chair)?;
        let (grid, here) = {
            let world = self.world();
            let grid = plan::occupancy(world.map(), |door| !world.door_is_open(door).unwrap_or(false))?;
            (grid, world.pose(self.chairs[i].id)?.translation.vector)
        };
        let path = grid
            .astar(Point2::from(here), target)
            .map_err(|e| FleetError::Plan { reason: format!("{chair} to ({:.2}, {:.2}): {e}", target.x, target.y) })?;
        let points = plan::waypoints(&path, 1.0);
        self.conversations += 1;
        let conversation = format!("goal-{}-{}", chair, self.conversations);
        let actor = AgentId::new(format!("control@{chair}"));
        let request = WheelchairContent::Request { actor: actor.clone(), action: plan::drive_along(&points) }.fill(
            AclMessage::new(Performative::Request)
                .with_receiver(actor)
                .with_protocol("fipa-request")
                .with_conversation_id(conversation.clone()),
        );
        operator::desk(&self.services.desk).outbox.push_back(request);
        self.goals[i] = Some(Goal { target, path: points });
        Ok(conversation)
    }

    /// Advances everything by `dt`: the containers at this instant, the frames between them,
    /// then the world.
    pub fn step(&mut self, dt: Duration) {
        let now = self.clock.now();
        for chair in &mut self.chairs {
            chair.host.step(now);
        }
        self.services.host.step(now);
        self.network.settle();
        {
            let mut world = self.world();
            for door in &self.jammed {
                // a jammed door stays as it is whatever anyone asks
                let _ = world.set_door(door, false);
            }
            iw_sim::step(&mut world, dt.as_secs_f64());
        }
        self.clock.advance(dt);
    }

    /// Takes a container's link to the others down (`up == false`) or restores it.
    pub fn set_link(&mut self, container: &str, up: bool) -> Result<(), FleetError> {
        if container != SERVICES {
            self.index(container)?;
        }
        self.network.set_link(container, up);
        Ok(())
    }

    /// Removes agent `agent` (e.g. `control`) from `container` as if it crashed after its
    /// take-down.
    pub fn kill_agent(&mut self, container: &str, agent: &str) -> Result<(), FleetError> {
        let now = self.clock.now();
        let name = format!("{agent}@{container}");
        let removed = if container == SERVICES {
            self.services.host.remove(&name, now)
        } else {
            let i = self.index(container)?;
            self.chairs[i].host.remove(&name, now)
        };
        if removed { Ok(()) } else { Err(FleetError::NoSuchAgent { container: container.into(), agent: agent.into() }) }
    }

    /// Fails (or restores) every sensor read of `chair`.
    pub fn set_sensor_failure(&mut self, chair: &str, failed: bool) -> Result<(), FleetError> {
        let i = self.index(chair)?;
        self.chairs[i].sensor_failed.store(failed, Ordering::Release);
        Ok(())
    }

    /// Closes `door` and keeps it closed from now on.
    pub fn jam_door(&mut self, door: &str) -> Result<(), FleetError> {
        self.world().set_door(door, false)?;
        self.jammed.push(door.to_string());
        Ok(())
    }

    /// Opens or closes `door` (refused if jammed open is asked: it stays closed).
    pub fn set_door(&mut self, door: &str, open: bool) -> Result<(), FleetError> {
        if open && self.jammed.iter().any(|d| d == door) {
            return Ok(());
        }
        self.world().set_door(door, open)?;
        Ok(())
    }

    /// The answers the operator got, in order.
    pub fn goal_events(&self) -> Vec<GoalEvent> {
        operator::desk(&self.services.desk).events.clone()
    }

    /// Every frame between containers so far.
    pub fn exchanges(&self) -> Vec<Exchange> {
        self.network.exchanges()
    }

    /// Per-container agent host statistics, chairs first then `services`.
    pub fn host_stats(&self) -> Vec<(String, HostStats)> {
        let mut out: Vec<(String, HostStats)> = self.chairs.iter().map(|c| (c.name.clone(), c.host.stats())).collect();
        out.push((SERVICES.to_string(), self.services.host.stats()));
        out
    }

    /// Whether `chair`'s footprint currently overlaps anything.
    pub fn overlapping(&self, chair: &str) -> Result<bool, FleetError> {
        let i = self.index(chair)?;
        Ok(self.world().overlapping(self.chairs[i].id)?)
    }

    /// The fleet now.
    pub fn snapshot(&self) -> Snapshot {
        let world = self.world();
        let chairs = self
            .chairs
            .iter()
            .zip(&self.goals)
            .map(|(c, goal)| {
                let pose = world.pose(c.id).unwrap_or_else(|_| Isometry2::identity());
                ChairSnapshot {
                    name: c.name.clone(),
                    pose: [pose.translation.x, pose.translation.y, pose.rotation.angle()],
                    twist: world.twist(c.id).map(|(v, w)| [v, w]).unwrap_or([0.0, 0.0]),
                    sonar_m: world.sensors(c.id).map(|s| s.sonar_m.to_vec()).unwrap_or_default(),
                    collisions: world.collisions(c.id).unwrap_or(0),
                    distance_m: world.distance_m(c.id).unwrap_or(0.0),
                    goal: goal.as_ref().map(|g| [g.target.x, g.target.y]),
                    path: goal.as_ref().map(|g| g.path.iter().map(|p| [p.x, p.y]).collect()).unwrap_or_default(),
                    agents: c.agents(),
                }
            })
            .collect();
        let doors = world.map().doors.iter().map(|d| (d.id.clone(), world.door_is_open(&d.id).unwrap_or(d.open))).collect();
        Snapshot {
            time_s: self.clock.now().0 as f64 * 1e-9,
            chairs,
            doors,
            services: self.services.host.agent_names(),
            recent: self.network.recent(20),
        }
    }
}

impl Drop for Fleet {
    fn drop(&mut self) {
        let now = self.clock.now();
        for chair in &mut self.chairs {
            chair.host.shutdown(now);
        }
        self.services.host.shutdown(now);
    }
}
