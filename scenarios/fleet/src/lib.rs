//! Containers per wheelchair and the fleet that composes them (thesis 3.3.3): each chair's
//! micro agents in their own container, the service agents in another, all talking FIPA-ACL
//! over real bus frames, stepped in simulated time over the simulator's world.
//!
//! # Organization
//! - [`compose`]: the agents of a chair ([`compose::chair_agents`]: perception, control,
//!   cognitive, interface) and of the services ([`compose::service_agents`]: door, logger,
//!   watcher, assistant) from a configuration, independent of the network, plus the
//!   [`compose::Building`] the cognitive agents plan on and the logger tap
//!   ([`compose::log_tap`]). `intellwheels spawn` hosts the same agents in processes.
//! - [`ChairContainer`]: one [`AgentHost`] on its own [`Bus`](iw_bus::Bus) with a chair's agents over one
//!   [`iw_body::Body`]: virtual (the simulator's [`VirtualBody`](iw_sim::VirtualBody)), real (the [`SerialBody`](iw_body::SerialBody)
//!   driver talking to a [`BoardEmulator`](iw_body::BoardEmulator) on a pty, its dead-reckoned pose fed into the world)
//!   or mixed (the same, with the virtual sonars merged in), wrapped by [`FaultyBody`] so a
//!   sensor failure can be injected.
//! - [`ServiceContainer`]: the service agents and the staff [`Console`] that hands staff goals
//!   to the assistant.
//! - [`Fleet`]: the world, the containers and the [`LockstepNetwork`] between their buses, on
//!   one mock clock. [`Fleet::new`] / [`Fleet::with_options`], [`Fleet::goal`] /
//!   [`Fleet::goal_place`], [`Fleet::step`], [`Fleet::snapshot`]; faults: [`Fleet::set_link`],
//!   [`Fleet::kill_agent`], [`Fleet::set_sensor_failure`], [`Fleet::set_laser_blind`],
//!   [`Fleet::jam_door`]; what a chair believes: [`Fleet::estimate`]; the log:
//!   [`Fleet::messages_sent`] against [`Fleet::messages_logged`].
//! - [`plan`]: the map as an occupancy grid.
//!
//! One job per module: `body` (the three body kinds and the injected sensor failure),
//! `container` (a container's bus and routes), `doors` (the world's doors for the door agent),
//! `traffic` (the taps' count and routes), `snapshot`, `error`, `network` (the lockstep
//! transport); this file composes them into the [`Fleet`].
//! - [`dashboard`]: the fleet as the dashboard shows it, and the page's asks carried out.
//!
//! # Guarantees
//! - Deterministic: each step runs the containers in a fixed order at one simulated instant, then
//!   releases the frames between containers and waits until every one is in its mailbox, then
//!   steps the world; the same map, seed and calls give the same run (a real body's board
//!   emulator advances one control period per read, whatever the wall clock).
//! - Containers share nothing but frames: a chair's agents and a service agent never hold each
//!   other; a killed agent or a downed link affects only what it carries.
//! - Every message an agent sends is copied to the logger agent (a host tap), so the log can be
//!   counted against the traffic.
#![warn(missing_docs)]

mod body;
mod container;
pub mod dashboard;
mod doors;
mod error;
mod network;
mod snapshot;
mod traffic;

pub use body::{FaultyBody, SensorFaults};
pub use container::{ChairContainer, ServiceContainer};
pub use error::FleetError;
pub use snapshot::{ChairSnapshot, Snapshot};

/// The wiring of the containers, shared with `intellwheels spawn` (crate `iw-wiring`).
pub use iw_wiring as compose;
pub use iw_wiring::{BodyKind, Console, Desk, GoalEvent, SERVICES, SharedDesk, plan};

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_agent::{AgentHost, HostStats};
use iw_bus::{Clock, MockController, Time};
use iw_control::DriveStatus;
use iw_door::Refusal;
use iw_interface::{Display, InputQueue, Recognizer};
use iw_ontology::wheelchair::Pose;
use iw_sim::{ChairId, ChairKind, ChairSpec, Map, SharedWorld, World};
use nalgebra::{Isometry2, Point2};

use compose::world_link::FailedSensor;
use compose::{Building, ServiceConfig, StartError, desk};
/// The interface agent's raw device readings, for [`Fleet::inputs`].
pub use iw_interface::RawInput;
pub use network::{Exchange, LockstepNetwork, LockstepTransport};

use body::{body_for, sim_camera};
use container::{bus_for, route};
use doors::WorldDoors;
use traffic::{Traffic, tap_into};

/// One chair to put in the fleet.
#[derive(Debug, Clone)]
pub struct ChairConfig {
    /// The chair's name (its container's name).
    pub name: String,
    /// Where it starts in the map frame.
    pub t_world_body: Isometry2<f64>,
}

/// What a fleet is built with besides its map and chairs.
#[derive(Debug, Clone, Default)]
pub struct FleetOptions {
    /// Chairs whose body is not virtual.
    pub bodies: BTreeMap<String, BodyKind>,
    /// Restricted doors (map door id) and the chairs allowed through each.
    pub restricted: BTreeMap<String, BTreeSet<String>>,
    /// The logger agent's log file; a fresh file in the temporary directory (removed with the
    /// fleet) when absent.
    pub log_path: Option<PathBuf>,
    /// Virtual chairs' perception agents also run LSAC-SURF RGB-D visual odometry on the
    /// simulator's rendered camera and fuse it with the wheels (costs a render and a detection
    /// per chair and control period).
    pub visual_odometry: bool,
    /// The variance of a chair's position in its worst direction, m², above which its
    /// cognitive agent detours past a landmark; `None`: [`compose::LANDMARK_UNCERTAINTY_M2`].
    pub landmark_uncertainty_m2: Option<f64>,
}

struct Goal {
    target: Point2<f64>,
}

/// The log file of a fleet; a temporary one is removed with the fleet.
struct LogFile {
    path: PathBuf,
    temporary: bool,
}

impl Drop for LogFile {
    fn drop(&mut self) {
        if self.temporary {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// The world, its chairs' containers and the service container, stepped together.
pub struct Fleet {
    world: SharedWorld,
    clock: MockController,
    network: LockstepNetwork,
    building: Building,
    chairs: Vec<ChairContainer>,
    goals: Vec<Option<Goal>>,
    services: ServiceContainer,
    jammed: Arc<Mutex<BTreeSet<String>>>,
    traffic: Arc<Traffic>,
    conversations: u64,
    log: LogFile,
}

impl Fleet {
    /// A fleet of virtual `chairs` on `map`; `seed` drives the simulator's noise.
    pub fn new(map: Map, seed: u64, chairs: &[ChairConfig]) -> Result<Self, FleetError> {
        Self::with_options(map, seed, chairs, FleetOptions::default())
    }

    /// A fleet of `chairs` on `map` with real or mixed bodies, restricted doors and a log path
    /// as `options` say.
    pub fn with_options(
        map: Map,
        seed: u64,
        chairs: &[ChairConfig],
        options: FleetOptions,
    ) -> Result<Self, FleetError> {
        let mut names: Vec<String> = Vec::new();
        for c in chairs {
            if c.name == SERVICES
                || names.contains(&c.name)
                || c.name.contains('@')
                || c.name.is_empty()
            {
                return Err(FleetError::DuplicateChair {
                    name: c.name.clone(),
                });
            }
            names.push(c.name.clone());
        }
        if let Some(unknown) = options.bodies.keys().find(|n| !names.contains(n)) {
            return Err(FleetError::NoSuchChair {
                name: unknown.clone(),
            });
        }
        let (clock, controller) = Clock::mock(Time::from_ns(0));
        let network = LockstepNetwork::new();
        let mut building = Building::from_map(map.clone())?;
        if let Some(m2) = options.landmark_uncertainty_m2 {
            if !(m2.is_finite() && m2 > 0.0) {
                return Err(FleetError::Plan {
                    reason: format!(
                        "the landmark detour's uncertainty threshold must be a positive number of m², got {m2}"
                    ),
                });
            }
            building.landmark_uncertainty_m2 = m2;
        }
        let mut world = World::new(map, seed);
        let ids: Vec<ChairId> = chairs
            .iter()
            .map(|c| {
                let kind = options.bodies.get(&c.name).copied().unwrap_or_default();
                let sim_kind = if kind == BodyKind::Virtual {
                    ChairKind::Simulated
                } else {
                    ChairKind::Tracked
                };
                world.add_chair(ChairSpec::default(), c.t_world_body, sim_kind)
            })
            .collect();
        let world = iw_sim::shared(world);
        let traffic = Arc::new(Traffic::default());
        let log = match options.log_path {
            Some(path) => LogFile {
                path,
                temporary: false,
            },
            None => {
                static FLEETS: AtomicU64 = AtomicU64::new(0);
                let n = FLEETS.fetch_add(1, Ordering::AcqRel);
                let path =
                    std::env::temp_dir().join(format!("iw-fleet-{}-{n}.log", std::process::id()));
                let _ = std::fs::remove_file(&path); // a stale file of a dead process with our pid
                LogFile {
                    path,
                    temporary: true,
                }
            }
        };
        let jammed = Arc::new(Mutex::new(BTreeSet::new()));

        let mut host = AgentHost::new(bus_for(&network, &clock, SERVICES)?);
        let service_config = ServiceConfig {
            restricted: options.restricted,
            ..ServiceConfig::new(names.clone(), log.path.clone())
        };
        let ids_by_name = compose::door_ids(&building.map);
        let doors = WorldDoors {
            world: world.clone(),
            ids: ids_by_name,
            jammed: jammed.clone(),
        };
        let service_agents = compose::service_agents(&service_config, &building, Box::new(doors))?;
        let add_err = |container: &str| {
            let container = container.to_string();
            move |e: iw_agent::AgentError| {
                FleetError::Start(StartError {
                    container: container.clone(),
                    what: "an agent".into(),
                    source: e.into(),
                })
            }
        };
        for (aid, agent) in service_agents.agents {
            host.add(aid, agent).map_err(add_err(SERVICES))?;
        }
        let desk = service_agents.desk;
        route(&host, SERVICES, &names);
        tap_into(&mut host, &traffic);
        let services = ServiceContainer {
            host,
            desk,
            refusals: service_agents.refusals,
        };

        let mut containers = Vec::new();
        for (config, id) in chairs.iter().zip(ids) {
            let name = &config.name;
            let kind = options.bodies.get(name).copied().unwrap_or_default();
            let faults = SensorFaults::default();
            let (body, board) =
                body_for(kind, name, &world, id, config.t_world_body, faults.clone())?;
            let visual = if options.visual_odometry && kind == BodyKind::Virtual {
                Some(sim_camera(&world, id, name)?)
            } else {
                None
            };
            let agents = compose::chair_agents(
                name,
                &config.t_world_body,
                &building,
                body,
                visual,
                Recognizer::new(iw_interface::sequence::DEFAULT_MAX_GAP),
            )?;
            let mut host = AgentHost::new(bus_for(&network, &clock, name)?);
            for (aid, agent) in agents.agents {
                host.add(aid, agent).map_err(add_err(name))?;
            }
            route(&host, name, &names);
            tap_into(&mut host, &traffic);
            containers.push(ChairContainer {
                name: name.clone(),
                id,
                kind,
                host,
                faults,
                inputs: agents.inputs,
                display: agents.display,
                drive_status: agents.drive_status,
                _board: board,
            });
        }
        let goals = containers.iter().map(|_| None).collect();
        Ok(Fleet {
            world,
            clock: controller,
            network,
            building,
            chairs: containers,
            goals,
            services,
            jammed,
            traffic,
            conversations: 0,
            log,
        })
    }

    fn index(&self, chair: &str) -> Result<usize, FleetError> {
        self.chairs
            .iter()
            .position(|c| c.name == chair)
            .ok_or_else(|| FleetError::NoSuchChair { name: chair.into() })
    }

    fn world(&self) -> std::sync::MutexGuard<'_, World> {
        self.world.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.clock.now().0 as f64 * 1e-9
    }

    /// The building the cognitive agents plan on (places, doors, connections).
    pub fn building(&self) -> &Building {
        &self.building
    }

    /// Sends `chair` to the place at `target` (within 0.5 m of a place of the map; see
    /// [`Fleet::goal_place`]). Errors when `target` is not a place.
    pub fn goal(&mut self, chair: &str, target: Point2<f64>) -> Result<String, FleetError> {
        let place = self.building.place_at(target)?;
        self.goal_place(chair, &place)
    }

    /// Staff send `chair` to `place`: the console asks the assistant, which asks the chair's
    /// cognitive agent; it plans (PDDL, then A*), has doors opened and the control agent drive.
    /// Returns the goal's conversation id; its answers arrive in [`Fleet::goal_events`].
    pub fn goal_place(&mut self, chair: &str, place: &str) -> Result<String, FleetError> {
        let i = self.index(chair)?;
        let target = self
            .building
            .destinations()
            .find(|(n, _)| *n == place)
            .map(|(_, p)| *p)
            .ok_or_else(|| FleetError::Plan {
                reason: format!(
                    "no place `{place}` (places: {})",
                    self.building
                        .destinations()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            })?;
        self.conversations += 1;
        let conversation = format!("goal-{}-{}", chair, self.conversations);
        desk(&self.services.desk).outbox.push_back((
            conversation.clone(),
            chair.to_string(),
            place.to_string(),
        ));
        self.goals[i] = Some(Goal { target });
        Ok(conversation)
    }

    fn step_hosts(&mut self, now: Time) -> u64 {
        let mut delivered = 0;
        for chair in &mut self.chairs {
            delivered += chair.host.step(now);
        }
        delivered += self.services.host.step(now);
        self.network.settle();
        delivered
    }

    /// Advances everything by `dt`: the containers at this instant, the frames between them,
    /// then the world.
    pub fn step(&mut self, dt: Duration) {
        let now = self.clock.now();
        self.step_hosts(now);
        iw_sim::step(&mut self.world(), dt.as_secs_f64());
        self.clock.advance(dt);
    }

    /// Lets the agents answer what is in flight without time passing (at most `rounds` rounds,
    /// fewer once nothing is delivered), e.g. so the logger has the last messages of a run.
    pub fn quiesce(&mut self, rounds: usize) {
        let now = self.clock.now();
        for _ in 0..rounds {
            if self.step_hosts(now) == 0 {
                break;
            }
        }
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
        if removed {
            Ok(())
        } else {
            Err(FleetError::NoSuchAgent {
                container: container.into(),
                agent: agent.into(),
            })
        }
    }

    /// Fails (or restores) `sensor` of `chair`: every read (`All`), or the laser's or the
    /// sonars' readings (garbage).
    pub fn set_sensor_failure(
        &mut self,
        chair: &str,
        sensor: FailedSensor,
        failed: bool,
    ) -> Result<(), FleetError> {
        match sensor {
            FailedSensor::All => self.set_fault(chair, |f| &f.failed, failed),
            FailedSensor::Laser => self.set_fault(chair, |f| &f.laser_garbage, failed),
            FailedSensor::Sonars => self.set_fault(chair, |f| &f.sonar_garbage, failed),
        }
    }

    /// Blinds (or restores) `chair`'s laser: it returns no ranges while the wheels, sonars and
    /// camera read on.
    pub fn set_laser_blind(&mut self, chair: &str, blind: bool) -> Result<(), FleetError> {
        self.set_fault(chair, |f| &f.laser_blind, blind)
    }

    /// Sets (or clears) the fault `which` picks of `chair`'s sensors.
    fn set_fault(
        &self,
        chair: &str,
        which: impl FnOnce(&SensorFaults) -> &AtomicBool,
        on: bool,
    ) -> Result<(), FleetError> {
        let i = self.index(chair)?;
        which(&self.chairs[i].faults).store(on, Ordering::Release);
        Ok(())
    }

    /// The pose `chair`'s perception agent last published, with its covariance (what the
    /// chair's other agents steer by); `None` before the first.
    pub fn estimate(&self, chair: &str) -> Result<Option<Pose>, FleetError> {
        self.index(chair)?;
        Ok(self
            .traffic
            .estimates
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(chair)
            .cloned())
    }

    /// Closes `door` (a map door id) and keeps it closed from now on: the door agent's
    /// actuator faults on it.
    pub fn jam_door(&mut self, door: &str) -> Result<(), FleetError> {
        self.world().set_door(door, false)?;
        self.jammed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(door.to_string());
        Ok(())
    }

    /// Opens or closes `door` by hand (a jammed door stays closed).
    pub fn set_door(&mut self, door: &str, open: bool) -> Result<(), FleetError> {
        if open
            && self
                .jammed
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .contains(door)
        {
            self.world().door_is_open(door)?;
            return Ok(());
        }
        self.world().set_door(door, open)?;
        Ok(())
    }

    /// The answers the staff console got, in order.
    pub fn goal_events(&self) -> Vec<GoalEvent> {
        desk(&self.services.desk).events.clone()
    }

    /// The door agent's refusals so far.
    pub fn door_refusals(&self) -> Vec<Refusal> {
        self.services
            .refusals
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Where raw inputs for `chair`'s interface agent go (joystick, voice, ...).
    pub fn inputs(&self, chair: &str) -> Result<InputQueue, FleetError> {
        Ok(self.chairs[self.index(chair)?].inputs.clone())
    }

    /// What `chair`'s interface agent shows.
    pub fn display(&self, chair: &str) -> Result<Display, FleetError> {
        Ok(self.chairs[self.index(chair)?]
            .display
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone())
    }

    /// What `chair`'s user asks by hand and what shared control applies, at the last control
    /// tick.
    pub fn drive_status(&self, chair: &str) -> Result<DriveStatus, FleetError> {
        Ok(*self.chairs[self.index(chair)?]
            .drive_status
            .lock()
            .unwrap_or_else(PoisonError::into_inner))
    }

    /// `chair`'s body kind.
    pub fn body_kind(&self, chair: &str) -> Result<BodyKind, FleetError> {
        Ok(self.chairs[self.index(chair)?].kind)
    }

    /// Every frame between containers so far.
    pub fn exchanges(&self) -> Vec<Exchange> {
        self.network.exchanges()
    }

    /// Messages the agents sent so far (each once, whatever its receivers; the logger's own
    /// copies and queries not counted).
    pub fn messages_sent(&self) -> u64 {
        self.traffic.sent.load(Ordering::Acquire)
    }

    /// Records in the logger agent's log, read back from its file.
    pub fn messages_logged(&self) -> Result<u64, FleetError> {
        let records = iw_logger::read_records(&self.log.path, iw_logger::DEFAULT_MAX_RECORD_LEN)
            .map_err(|e| {
                FleetError::Start(StartError {
                    container: SERVICES.into(),
                    what: "reading the log".into(),
                    source: e.into(),
                })
            })?;
        Ok(records.len() as u64)
    }

    /// The logger agent's log file.
    pub fn log_path(&self) -> &std::path::Path {
        &self.log.path
    }

    /// Per-container agent host statistics, chairs first then `services`.
    pub fn host_stats(&self) -> Vec<(String, HostStats)> {
        let mut out: Vec<(String, HostStats)> = self
            .chairs
            .iter()
            .map(|c| (c.name.clone(), c.host.stats()))
            .collect();
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
        let paths = self
            .traffic
            .paths
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone();
        let world = self.world();
        let chairs = self
            .chairs
            .iter()
            .zip(&self.goals)
            .map(|(c, goal)| {
                let pose = world.pose(c.id).unwrap_or_else(|_| Isometry2::identity());
                ChairSnapshot {
                    name: c.name.clone(),
                    pose: [
                        pose.translation.x,
                        pose.translation.y,
                        pose.rotation.angle(),
                    ],
                    twist: world.twist(c.id).map(|(v, w)| [v, w]).unwrap_or([0.0, 0.0]),
                    sonar_m: world
                        .sensors(c.id)
                        .map(|s| s.sonar_m.to_vec())
                        .unwrap_or_default(),
                    collisions: world.collisions(c.id).unwrap_or(0),
                    distance_m: world.distance_m(c.id).unwrap_or(0.0),
                    goal: goal.as_ref().map(|g| [g.target.x, g.target.y]),
                    path: paths.get(&c.name).cloned().unwrap_or_default(),
                    agents: c.agents(),
                }
            })
            .collect();
        let doors = world
            .map()
            .doors
            .iter()
            .map(|d| (d.id.clone(), world.door_is_open(&d.id).unwrap_or(d.open)))
            .collect();
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
