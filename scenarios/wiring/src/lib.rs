//! One wiring: what a chair container and the services container host, with each agent's
//! configuration, free of any network. The in-process fleet (`iw-fleet`: demo and scenario
//! runner) and the container processes of `intellwheels spawn` (`iw-node`) host exactly these
//! agents, each container on its own bus and transport.
//!
//! # Organization
//! - [`chair_agents`]: `perception@CHAIR`, `control@CHAIR`, `cognitive@CHAIR`,
//!   `interface@CHAIR` over one [`SharedBody`] ([`CHAIR_ROLES`]).
//! - [`service_agents`]: `ams@services`, `df@services`, `door@services` (every door of the map),
//!   `logger@services`, `watcher@services`, `assistant@services` and the staff console
//!   `staff@services` ([`SERVICE_ROLES`], [`Console`]).
//! - [`BodyKind`]: virtual, real or mixed, for both.
//! - [`Building`]: the map as the cognitive agents plan on it; [`plan`]: the map as a grid.
//! - [`log_tap`]: a host tap copying every message to the logger.
//! - [`remote_agents`]: which agents a container routes to which other container.
//! - [`world_link`]: the world container's agent and a chair's body in it, over the platform.
//! - [`view`]: what the dashboard is given (the map as drawn, drive panel inputs as readings).
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId};
use iw_agent::{Agent, Tap};
use iw_ams_df::{Ams, Df, WhitePages};
use iw_assistant::{AssistantAgent, AssistantConfig};
use iw_body::{Body, BodyError, SensorFrame, WheelSpeeds};
use iw_bus::Bus;
use iw_cognitive::agent::{
    BUILDING_DOMAIN, BuildingMap, CognitiveAgent, CognitiveConfig, DoorPassage, LandmarkStop,
};
use iw_cognitive::{Domain, GridError, NarrowPassage, OccupancyGrid};
pub use iw_control::SharedDriveStatus;
use iw_control::{ControlAgent, ControlConfig, LaserMount};
use iw_door::{ActuatorFault, DoorActuator, DoorAgent, DoorConfig, DoorPolicy, RefusalLog};
use iw_interface::{Display, InputQueue, InterfaceAgent, InterfaceConfig, Recognizer};
use iw_localization::{LocalizationMap, Localizer};
use iw_logger::SyncPolicy;
use iw_logger::agent::{LOG_ONTOLOGY, LoggerAgent, LoggerConfig, copy_for_logger};
use iw_ontology::fipa::{AgentState, AmsAgentDescription};
use iw_perception::{PerceptionAgent, PerceptionConfig, VisualConfig};
use iw_sim::{ChairSpec, Map};
use iw_vo::Pose2;
use iw_watcher::{WatcherAgent, WatcherConfig};
use nalgebra::{Isometry2, Point2, Vector2};

pub mod camera;
mod console;
pub mod plan;
pub mod view;
pub mod world_link;

pub use console::{Console, Desk, GOAL_QUERY_WAIT, GoalAnswer, GoalEvent, SharedDesk, desk};

/// The service container's name.
pub const SERVICES: &str = "services";

/// What a chair's body is (thesis 3.5), the same for the in-process fleet (a scenario's
/// `body`) and for a chair process (`[body] kind`, `spawn --body`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BodyKind {
    /// Simulated: the world drives it (in the fleet's simulator or the world container).
    #[default]
    Virtual,
    /// The serial driver talking to the interface board (emulated on a pty in the fleet); its
    /// dead-reckoned pose is fed into the world, which it does not sense. Spelled `real` in a
    /// scenario and `serial` in a spawn configuration; both are read.
    #[serde(alias = "serial")]
    Real,
    /// Real, with the virtual sonars of its ghost in the world merged in (nearest wins).
    Mixed,
}

/// The error underneath a [`WiringError`] (an agent's, the bus's, the simulator's), kept whole.
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// A part of a container that could not start: which container, which part, and why. The
/// wiring, the fleet and a container process all say it so.
#[derive(Debug, thiserror::Error)]
#[error("container `{container}`: {what}: {source}")]
pub struct StartError {
    /// The container.
    pub container: String,
    /// The part, e.g. `the bus` or `the control agent`.
    pub what: String,
    /// What it said.
    #[source]
    pub source: Cause,
}

/// What went wrong composing a container's agents.
///
/// A variant with a `source` says it in its message too (`… : <source>`): a caller printing only
/// the message loses nothing.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WiringError {
    /// An agent could not be set up.
    #[error("container `{container}`: {reason}")]
    Setup {
        /// The container.
        container: String,
        /// Why.
        reason: String,
    },
    /// A part of a container (an agent, its link to the world) could not be set up.
    #[error(transparent)]
    Start(#[from] StartError),
    /// The building cannot be planned on, or a place is unknown.
    #[error("cannot plan: {reason}")]
    Plan {
        /// Why.
        reason: String,
    },
    /// The building cannot be derived from the map (`what`: the part, e.g. its domain).
    #[error("cannot plan: {what}: {source}")]
    Building {
        /// The part that failed.
        what: &'static str,
        /// What it said.
        #[source]
        source: Cause,
    },
    /// The building's occupancy grid cannot be built from the map.
    #[error("cannot plan: {source}")]
    Grid {
        /// What the grid said.
        #[from]
        source: GridError,
    },
}

/// How far in front of a landmark's marker the chair may stop to read it, in order of
/// preference, m: the camera sits 0.6 m ahead of the base and measures depth up to 3.5 m.
const LANDMARK_VIEW_M: [f64; 3] = [1.8, 1.5, 2.2];

/// How much farther out on a marker's axis the chair's landmark detour comes in from, m: it
/// drives the last metre towards the marker, so the camera reads it on the way in.
const LANDMARK_RUN_IN_M: f64 = 1.0;

/// The deployment's landmark detour threshold unless [`Building::landmark_uncertainty_m2`] sets
/// one. It works because the covariance is honest when the chair dead-reckons (the wheels' bias
/// in the filter, visual odometry's noise growing with the motion, [`camera::VISUAL_NOISE`]).
pub use iw_cognitive::agent::LANDMARK_UNCERTAINTY_M2;

/// The clearance a doorway must leave the chair's centre, m: the chair's half width less a few
/// centimetres (the grid rounds it up a cell), so a 1 m doorway stays passable.
pub const CHAIR_RADIUS_M: f64 = 0.3;

/// The clearance the cognitive agent keeps from walls and furniture elsewhere, m: room for the
/// chair's long front to turn on the spot.
pub const WALL_CLEARANCE_M: f64 = 0.5;

/// Paths keep this far from the inflated walls and furniture where there is room, m: down the
/// middle of corridors, and round corners wide enough for the chair's front.
pub const PATH_COMFORT_M: f64 = 1.0;

/// How long a watcher grant of a passage lasts before it is taken back: a chair crosses a
/// 15 m corridor in about 40 s.
pub const PASS_LEASE: Duration = Duration::from_secs(60);

/// Longest a chair waits for a passage before it goes on under its own guard: a full lease of
/// the chair inside, and its way out.
pub const PASS_WAIT: Duration = Duration::from_secs(75);

/// Heading error above which a chair turns on the spot before driving to a point, rad.
pub const TURN_IN_PLACE_RAD: f64 = 0.3;

/// The control and sensing period of a chair's agents (a real board advances this per read).
pub const CONTROL_PERIOD: Duration = Duration::from_millis(50);

/// An agent's name in a container: `ROLE@CONTAINER`.
pub fn agent_id(role: &str, container: &str) -> AgentId {
    AgentId::new(format!("{role}@{container}"))
}

/// The roles of a chair's container, in the order they are hosted.
pub const CHAIR_ROLES: [&str; 4] = ["perception", "control", "cognitive", "interface"];

/// The roles of the service container, in the order they are hosted (the staff console last).
pub const SERVICE_ROLES: [&str; 7] = [
    "ams",
    "df",
    "door",
    "logger",
    "watcher",
    "assistant",
    "staff",
];

/// The name the door agent and the planner give a map door: the map's door ids may equal place
/// names (`office`), and the planner keeps one namespace.
pub fn door_name(map_door: &str) -> String {
    format!("{map_door}-door")
}

/// The door agent's door names ([`door_name`]) to the map's door ids.
pub fn door_ids(map: &Map) -> BTreeMap<String, String> {
    map.doors
        .iter()
        .map(|d| (door_name(&d.id), d.id.clone()))
        .collect()
}

/// The map door id of the door agent's door `door` in `ids` (from [`door_ids`]), or the
/// actuator fault saying it is not a door of the map.
pub fn map_door<'a>(
    ids: &'a BTreeMap<String, String>,
    door: &str,
) -> Result<&'a String, ActuatorFault> {
    ids.get(door)
        .ok_or_else(|| ActuatorFault::new(door, "not a door of the map"))
}

/// Which agents of other containers `container` must route to, as (agent, its container):
/// a chair reaches the service agents, the services reach every chair's agents.
pub fn remote_agents(container: &str, chairs: &[String]) -> Vec<(String, String)> {
    if container == SERVICES {
        chairs
            .iter()
            .flat_map(|c| {
                CHAIR_ROLES
                    .iter()
                    .map(move |r| (agent_id(r, c).name, c.clone()))
            })
            .collect()
    } else {
        SERVICE_ROLES
            .iter()
            .map(|r| (agent_id(r, SERVICES).name, SERVICES.to_string()))
            .collect()
    }
}

/// The building as the agents know it, derived once from the map: the strategic layer's places,
/// connections and doors, and the grid it paths on.
#[derive(Debug, Clone)]
pub struct Building {
    /// The map it was derived from.
    pub map: Map,
    /// Places, connections (same room, no door between), door passages, landmarks (the places
    /// named `landmark...`, and a point in front of each marker of the map).
    pub plan: BuildingMap,
    /// The places of `plan` that are not the map's but a door's sides (`DOOR-side-1`,
    /// `DOOR-side-2`), where the chair lines up with the doorway.
    pub approaches: BTreeSet<String>,
    /// Where the chair's centre may go: walls and furniture inflated by [`WALL_CLEARANCE_M`],
    /// with a straight lane carved through each usable doorway from one of its sides to the
    /// other; doors left out (the planner decides about doors).
    pub grid: OccupancyGrid,
    /// The planning domain.
    pub domain: Domain,
    /// The map as every chair's localizer matches its laser and sonars against it (walls,
    /// furniture, the doors drawn closed, landmarks), indexed once and shared.
    pub localization: Arc<LocalizationMap>,
    /// The variance of a chair's position in its worst direction, m², above which its
    /// cognitive agent detours past a landmark ([`LANDMARK_UNCERTAINTY_M2`] unless set).
    pub landmark_uncertainty_m2: f64,
}

impl Building {
    /// Derives the building from `map`: two places are connected when one can drive between them
    /// with every door closed; a door joins two places of its own in front of it, one on each
    /// side. Places named `landmark...` are landmarks (relocalisation points), not destinations.
    pub fn from_map(map: Map) -> Result<Self, WiringError> {
        let domain = Domain::parse(BUILDING_DOMAIN).map_err(|e| WiringError::Building {
            what: "building domain",
            source: e.into(),
        })?;
        let grid = plan::raster(&map, |_| false)?;
        let localization = Arc::new(iw_sim::localization::localization_map(&map).map_err(|e| {
            WiringError::Building {
                what: "cannot localize on the map",
                source: e.into(),
            }
        })?);
        let rooms = Rooms::of(&map)?;
        let mut places = BTreeMap::new();
        let mut landmarks = Vec::new();
        for place in &map.places {
            if place.name.starts_with("landmark") {
                landmarks.push(LandmarkStop {
                    at: place.position,
                    from: None,
                });
            } else {
                places.insert(place.name.clone(), place.position);
            }
        }
        let passable = grid.inflated(CHAIR_RADIUS_M);
        // in front of each marker, within the camera's depth range, where the chair may stand,
        // come to along the marker's axis where there is room for the run-in
        for marker in &map.landmarks {
            let normal = Vector2::new(marker.facing_rad.cos(), marker.facing_rad.sin());
            let free = |d: f64| {
                let p = marker.position + normal * d;
                let (c, r) = passable.cell_of(&p)?;
                (!passable.is_occupied(c, r)).then_some(p)
            };
            let stops: Vec<_> = LANDMARK_VIEW_M
                .iter()
                .filter_map(|d| Some((free(*d)?, free(d + LANDMARK_RUN_IN_M))))
                .collect();
            let best = stops.iter().find(|(_, from)| from.is_some());
            match best.or(stops.first()).copied() {
                Some((at, from)) => landmarks.push(LandmarkStop { at, from }),
                None => {
                    tracing::warn!(
                        landmark = marker.id,
                        "no room in front of the landmark; the cognitive agent will not detour to it"
                    )
                }
            }
        }
        let mut doors = Vec::new();
        let mut approaches = BTreeSet::new();
        for door in &map.doors {
            let name = door_name(&door.id);
            let mid = nalgebra::center(&door.a, &door.b);
            let along = door.b - door.a;
            let normal = Vector2::new(-along.y, along.x).normalize();
            // A point in front of the doorway on each side, so the chair lines up before it
            // drives through (and out of the way again after).
            let approach = |sign: f64| {
                [0.9, 0.8, 0.7, 0.6, 0.5].iter().find_map(|d| {
                    let p = mid + normal * sign * *d;
                    let (c, r) = passable.cell_of(&p)?;
                    (!passable.is_occupied(c, r)).then_some(p)
                })
            };
            match (approach(1.0), approach(-1.0)) {
                (Some(p), Some(q))
                    if rooms.at(&p) != rooms.at(&q) && free_near(&passable, mid).is_some() =>
                {
                    // on the straight line between the two sides, so the chair drives through
                    // without turning in the doorway
                    let at = nalgebra::center(&p, &q);
                    let (a, b) = (format!("{name}-side-1"), format!("{name}-side-2"));
                    for (side, point) in [(&a, p), (&b, q)] {
                        if places.insert(side.clone(), point).is_some() {
                            return Err(WiringError::Plan {
                                reason: format!(
                                    "place `{side}` clashes with the planner's name for a side of door `{}`",
                                    door.id
                                ),
                            });
                        }
                        approaches.insert(side.clone());
                    }
                    doors.push(DoorPassage { name, a, b, at });
                }
                _ => {
                    tracing::warn!(door = %door.id, "door too narrow or with one room on both sides; the planner will not use it")
                }
            }
        }
        let room_of: BTreeMap<&String, Option<usize>> =
            places.iter().map(|(n, p)| (n, rooms.at(p))).collect();
        let mut connections = Vec::new();
        for (a, ra) in &room_of {
            for (b, rb) in &room_of {
                if a < b && ra.is_some() && ra == rb {
                    connections.push(((*a).clone(), (*b).clone()));
                }
            }
        }
        let lanes: Vec<(Point2<f64>, Point2<f64>)> =
            doors.iter().map(|d| (places[&d.a], places[&d.b])).collect();
        let grid =
            carve_lanes(&grid.inflated(WALL_CLEARANCE_M), &lanes)?.with_comfort(PATH_COMFORT_M);
        let passages = map
            .passages
            .iter()
            .map(|p| NarrowPassage {
                name: p.name.clone(),
                a: p.a,
                b: p.b,
                width_m: p.width_m,
            })
            .collect();
        Ok(Building {
            map,
            plan: BuildingMap {
                places,
                connections,
                doors,
                landmarks,
                passages,
            },
            approaches,
            grid,
            domain,
            localization,
            landmark_uncertainty_m2: LANDMARK_UNCERTAINTY_M2,
        })
    }

    /// The building as chair `chair` starting at `t_world_body` plans on: with a place of its
    /// own there (`CHAIR-start`, returned too), connected to the places of its room (to the
    /// nearest place if it starts outside every room), so its first goal is always driven to.
    pub fn with_start(
        &self,
        chair: &str,
        t_world_body: &Isometry2<f64>,
    ) -> Result<(BuildingMap, String), WiringError> {
        let p = Point2::from(t_world_body.translation.vector);
        let start = format!("{chair}-start");
        if self.plan.places.contains_key(&start) {
            return Err(WiringError::Plan {
                reason: format!("place `{start}` clashes with the start place of chair `{chair}`"),
            });
        }
        let rooms = Rooms::of(&self.map)?;
        let room = rooms.at(&p);
        let mut neighbours: Vec<String> = self
            .plan
            .places
            .iter()
            .filter(|(_, q)| room.is_some() && rooms.at(q) == room)
            .map(|(n, _)| n.clone())
            .collect();
        if neighbours.is_empty() {
            let nearest = self
                .plan
                .places
                .iter()
                .min_by(|a, b| (a.1 - p).norm().total_cmp(&(b.1 - p).norm()));
            neighbours.extend(nearest.map(|(n, _)| n.clone()));
        }
        let mut plan = self.plan.clone();
        plan.places.insert(start.clone(), p);
        plan.connections
            .extend(neighbours.into_iter().map(|n| (start.clone(), n)));
        Ok((plan, start))
    }

    /// The map's places (destinations), without the doors' sides.
    pub fn destinations(&self) -> impl Iterator<Item = (&String, &Point2<f64>)> {
        self.plan
            .places
            .iter()
            .filter(|(n, _)| !self.approaches.contains(*n))
    }

    /// The place at `target` (within 0.5 m), for goals given as points.
    pub fn place_at(&self, target: Point2<f64>) -> Result<String, WiringError> {
        self.destinations()
            .filter(|(_, p)| (**p - target).norm() <= 0.5)
            .min_by(|a, b| (a.1 - target).norm().total_cmp(&(b.1 - target).norm()))
            .map(|(n, _)| n.clone())
            .ok_or_else(|| WiringError::Plan {
                reason: format!(
                    "({:.2}, {:.2}) is not a place of the map (places: {})",
                    target.x,
                    target.y,
                    self.destinations()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            })
    }
}

/// `grid` with every cell within half a cell of a lane's segment freed.
fn carve_lanes(
    grid: &OccupancyGrid,
    lanes: &[(Point2<f64>, Point2<f64>)],
) -> Result<OccupancyGrid, WiringError> {
    let (width, height) = grid.size();
    let mut occupied: Vec<bool> = (0..width * height)
        .map(|i| grid.is_occupied((i % width) as i64, (i / width) as i64))
        .collect();
    for (a, b) in lanes {
        let steps = ((b - a).norm() / (plan::RESOLUTION_M / 4.0))
            .ceil()
            .max(1.0) as usize;
        for k in 0..=steps {
            let p = a + (b - a) * (k as f64 / steps as f64);
            if let Some((col, row)) = grid.cell_of(&p) {
                occupied[row as usize * width + col as usize] = false;
            }
        }
    }
    let origin = grid.centre(0, 0) - Vector2::repeat(plan::RESOLUTION_M / 2.0);
    Ok(OccupancyGrid::new(
        width,
        height,
        plan::RESOLUTION_M,
        origin,
        occupied,
    )?)
}

/// The centre of the free cell of `grid` nearest to `p`, within 0.3 m: the doorway's middle may
/// fall on a cell boundary next to the inflated door posts.
fn free_near(grid: &OccupancyGrid, p: Point2<f64>) -> Option<Point2<f64>> {
    let (col, row) = grid.cell_of(&p)?;
    let reach = (0.3 / plan::RESOLUTION_M).round() as i64;
    (-reach..=reach)
        .flat_map(|dr| (-reach..=reach).map(move |dc| (col + dc, row + dr)))
        .filter(|(c, r)| !grid.is_occupied(*c, *r))
        .map(|(c, r)| grid.centre(c, r))
        .min_by(|a, b| (a - p).norm().total_cmp(&(b - p).norm()))
}

/// The rooms of a map: connected free regions (4-connected) with every door shut, on a grid
/// slightly inflated so no rasterised wall leaks.
struct Rooms {
    grid: OccupancyGrid,
    label: Vec<Option<usize>>,
}

impl Rooms {
    fn of(map: &Map) -> Result<Rooms, WiringError> {
        let grid = plan::raster(map, |_| true)?.inflated(plan::RESOLUTION_M * 1.5);
        let (width, height) = grid.size();
        let mut label = vec![None; width * height];
        let mut next = 0;
        for start in 0..width * height {
            let (col, row) = ((start % width) as i64, (start / width) as i64);
            if label[start].is_some() || grid.is_occupied(col, row) {
                continue;
            }
            let mut queue = VecDeque::from([(col, row)]);
            label[start] = Some(next);
            while let Some((c, r)) = queue.pop_front() {
                for (dc, dr) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                    let (nc, nr) = (c + dc, r + dr);
                    if !grid.is_occupied(nc, nr) {
                        let i = nr as usize * width + nc as usize;
                        if label[i].is_none() {
                            label[i] = Some(next);
                            queue.push_back((nc, nr));
                        }
                    }
                }
            }
            next += 1;
        }
        Ok(Rooms { grid, label })
    }

    fn at(&self, p: &Point2<f64>) -> Option<usize> {
        let (col, row) = self.grid.cell_of(p)?;
        self.label[row as usize * self.grid.size().0 + col as usize]
    }
}

/// One body shared by the agents of a chair (perception reads, control reads and commands).
/// The board is read at most once between two commands, so a serial board that advances one
/// control period per read is advanced once per period however many agents read it.
#[derive(Clone)]
pub struct SharedBody {
    inner: Arc<Mutex<Cached>>,
    /// How long the body may stay unreadable and still come back (see [`SharedBody::outages`]).
    outage: Option<Duration>,
    /// The last wheel command the body took was not a stop.
    moving: Arc<std::sync::atomic::AtomicBool>,
}

/// A body and the frame read since its last command.
type Cached = (Box<dyn Body + Send>, Option<SensorFrame>);

impl SharedBody {
    /// Shares `body`.
    pub fn new(body: impl Body + Send + 'static) -> Self {
        SharedBody {
            inner: Arc::new(Mutex::new((Box::new(body), None))),
            outage: None,
            moving: Arc::default(),
        }
    }

    /// Whether the last wheel command the body took was not a stop (what a chair container
    /// reports of its wheels).
    pub fn moving(&self) -> bool {
        self.moving.load(std::sync::atomic::Ordering::Acquire)
    }

    /// A body whose faults are outages of up to `wait` that it recovers from by itself (a
    /// virtual chair's world link re-attaching, a serial link stalled in a loaded computer's
    /// kernel): the control agent holds a task through one, wheels stopped, instead of failing
    /// it after its short fault window (a sensor that fails is reported at once).
    pub fn outages(mut self, wait: Duration) -> Self {
        self.outage = Some(wait);
        self
    }
}

impl Body for SharedBody {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        let mut guard = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        let (body, cached) = &mut *guard;
        if let Some(frame) = cached {
            return Ok(frame.clone());
        }
        let frame = body.read()?;
        *cached = Some(frame.clone());
        Ok(frame)
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        let mut guard = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        guard.1 = None;
        guard.0.command(speeds)?;
        self.moving.store(
            speeds != WheelSpeeds::STOP,
            std::sync::atomic::Ordering::Release,
        );
        Ok(())
    }
}

/// A chair's agents, ready to be added to its container's host, and the handles the container
/// keeps (inputs for the interface agent, what the on-chair display shows).
pub struct ChairAgents {
    /// The agents with their names, in [`CHAIR_ROLES`] order.
    pub agents: Vec<(AgentId, Box<dyn Agent>)>,
    /// Where device drivers (or a dashboard) push raw inputs for the interface agent.
    pub inputs: InputQueue,
    /// What the interface agent shows.
    pub display: Arc<Mutex<Display>>,
    /// What the user asked by hand and what shared control applied, from the control agent.
    pub drive_status: SharedDriveStatus,
}

/// Composes chair `name`'s perception, control, cognitive and interface agents over `body`,
/// starting at `t_world_body` in `building`; `visual` is the perception agent's RGB-D camera, if
/// any; `recognizer` holds the user's bound input sequences.
pub fn chair_agents(
    name: &str,
    t_world_body: &Isometry2<f64>,
    building: &Building,
    body: SharedBody,
    visual: Option<VisualConfig>,
    recognizer: Recognizer<iw_interface::Command>,
) -> Result<ChairAgents, WiringError> {
    let setup = |what: &str, source: Cause| {
        WiringError::Start(StartError {
            container: name.to_string(),
            what: what.into(),
            source,
        })
    };
    let start = Pose2 {
        x: t_world_body.translation.x,
        y: t_world_body.translation.y,
        theta: t_world_body.rotation.angle(),
    };
    let perception_id = agent_id("perception", name);
    let control_id = agent_id("control", name);
    let cognitive_id = agent_id("cognitive", name);
    let perception_config = PerceptionConfig::prototype(AgentId::new(name), start);
    // The pose stays bounded by matching the laser and sonars to the map: odometry alone
    // drifts half a metre in 15 m, enough to touch a wall at a goal.
    let localizer = Localizer::new(
        building.localization.clone(),
        iw_sim::localization::localizer_config(&ChairSpec::default()),
        Some((start, perception_config.start_covariance)),
    );
    // a chair without a camera cannot read a marker: a detour past one would not reset its error
    let reads_markers = visual.is_some();
    let perception = PerceptionAgent::new(perception_config, Box::new(body.clone()), visual)
        .map_err(|e| setup("the perception agent", e.into()))?
        .with_localizer(localizer);
    let mut control_config = ControlConfig::prototype(Some(perception_id.clone()))
        .map_err(|e| setup("the control agent's configuration", e.into()))?;
    // Indoors the chair turns on the spot before it drives, so its long front does not sweep
    // into door posts when it lines up with a doorway.
    control_config.tactical.turn_in_place_rad = TURN_IN_PLACE_RAD;
    if let Some(wait) = body.outage {
        control_config.body_fault = wait;
    }
    // the simulated chair's laser (a body without one reads no ranges, and adds no points)
    control_config.laser = ChairSpec::default().laser.map(|l| LaserMount {
        t_body_laser: l.t_body_laser,
        fov_rad: l.fov_deg.to_radians(),
        max_range_m: l.max_range_m,
    });
    let control = ControlAgent::new(control_config, Box::new(body))
        .map_err(|e| setup("the control agent", e.into()))?;
    let (mut plan, start_place) = building.with_start(name, t_world_body)?;
    if !reads_markers {
        plan.landmarks.clear();
    }
    let cognitive = CognitiveAgent::new(CognitiveConfig {
        chair: name.to_string(),
        control: control_id.clone(),
        door: agent_id("door", SERVICES),
        perception: Some(perception_id.clone()),
        watcher: Some(agent_id("watcher", SERVICES)),
        pass_wait: PASS_WAIT,
        domain: building.domain.clone(),
        map: plan,
        grid: building.grid.clone(),
        // the building's grid is inflated already (with lanes through the doorways)
        chair_radius_m: 0.0,
        start_place,
        uncertainty_m2: building.landmark_uncertainty_m2,
        max_states: 20_000,
    })
    .map_err(|e| setup("the cognitive agent", e.into()))?;
    let inputs = InputQueue::default();
    let display = Arc::new(Mutex::new(Display::default()));
    let drive_status = control.drive_status();
    let mut interface_config = InterfaceConfig::new(cognitive_id.clone(), control_id.clone());
    // the services' dashboard drive panel, relayed by the staff console
    interface_config.remote_drivers = vec![agent_id("staff", SERVICES).name];
    let interface = InterfaceAgent::new(
        interface_config,
        recognizer,
        inputs.clone(),
        display.clone(),
    );
    // The interface steps before the control agent: a drive it streams in its tick is in the
    // control agent's mailbox before that agent's tick in the same host step, so an input
    // reaches the wheels one step sooner (the in-process delivery is synchronous).
    let agents: Vec<(AgentId, Box<dyn Agent>)> = vec![
        (perception_id, Box::new(perception)),
        (agent_id("interface", name), Box::new(interface)),
        (control_id, Box::new(control)),
        (cognitive_id, Box::new(cognitive)),
    ];
    Ok(ChairAgents {
        agents,
        inputs,
        display,
        drive_status,
    })
}

/// What the service container is given.
#[derive(Debug, Clone)]
pub struct ServiceConfig {
    /// The chairs of the fleet (their container names).
    pub chairs: Vec<String>,
    /// The logger agent's log file.
    pub log_path: PathBuf,
    /// When the log is forced to disk.
    pub sync: SyncPolicy,
    /// Restricted doors (map door id) and the chairs allowed through each; every other door
    /// opens for anyone.
    pub restricted: BTreeMap<String, BTreeSet<String>>,
    /// How long a watcher grant lasts before it is taken back.
    pub lease: Duration,
}

impl ServiceConfig {
    /// No restricted doors, the log synced every 64 records (and every logger tick),
    /// [`PASS_LEASE`] leases.
    pub fn new(chairs: Vec<String>, log_path: PathBuf) -> Self {
        ServiceConfig {
            chairs,
            log_path,
            sync: SyncPolicy::EveryN(64),
            restricted: BTreeMap::new(),
            lease: PASS_LEASE,
        }
    }
}

/// The service agents and what the container keeps of them.
pub struct ServiceAgents {
    /// The agents with their names, in [`SERVICE_ROLES`] order.
    pub agents: Vec<(AgentId, Box<dyn Agent>)>,
    /// The door agent's refusals.
    pub refusals: RefusalLog,
    /// The staff console's desk: goals to send, answers received, chairs' poses.
    pub desk: SharedDesk,
    /// The AMS's white pages, listing the service agents (a container adds others it hosts).
    pub pages: WhitePages,
}

/// Composes the AMS, DF, door, logger, watcher, assistant and staff console agents of
/// `building`; `doors` moves the doors (the simulator's world or door controllers).
pub fn service_agents(
    config: &ServiceConfig,
    building: &Building,
    doors: Box<dyn DoorActuator>,
) -> Result<ServiceAgents, WiringError> {
    let setup = |reason: String| WiringError::Setup {
        container: SERVICES.to_string(),
        reason,
    };
    for door in config.restricted.keys() {
        if !building.map.doors.iter().any(|d| &d.id == door) {
            return Err(setup(format!(
                "restricted door `{door}` is not a door of the map"
            )));
        }
    }
    let policies = building
        .map
        .doors
        .iter()
        .map(|d| {
            let authorised = config.restricted.get(&d.id);
            let policy = DoorPolicy {
                restricted: authorised.is_some(),
                authorised: authorised
                    .into_iter()
                    .flatten()
                    .map(|chair| agent_id("cognitive", chair).name)
                    .collect(),
            };
            (door_name(&d.id), policy)
        })
        .collect();
    let refusals = RefusalLog::default();
    let door = DoorAgent::new(DoorConfig { doors: policies }, doors, refusals.clone());
    let logger = LoggerAgent::open(&LoggerConfig {
        path: config.log_path.clone(),
        policy: config.sync,
        sync_period: Duration::from_millis(500),
    })
    .map_err(|e| {
        WiringError::Start(StartError {
            container: SERVICES.into(),
            what: format!("log {}", config.log_path.display()),
            source: e.into(),
        })
    })?;
    let watcher = WatcherAgent::new(WatcherConfig {
        passages: building
            .plan
            .passages
            .iter()
            .map(|p| p.name.clone())
            .collect(),
        lease: config.lease,
        period: Duration::from_millis(100),
    })
    .map_err(|e| {
        WiringError::Start(StartError {
            container: SERVICES.into(),
            what: "the watcher agent".into(),
            source: e.into(),
        })
    })?;
    let assistant = AssistantAgent::new(AssistantConfig {
        chairs: config
            .chairs
            .iter()
            .map(|c| (c.clone(), agent_id("cognitive", c)))
            .collect(),
        staff: BTreeSet::new(),
    });
    let pages = WhitePages::new();
    let desk = SharedDesk::default();
    let console = Console::new(desk.clone(), agent_id("assistant", SERVICES));
    let agents: Vec<(AgentId, Box<dyn Agent>)> = vec![
        (agent_id("ams", SERVICES), Box::new(Ams::new(pages.clone()))),
        (agent_id("df", SERVICES), Box::new(Df::new())),
        (agent_id("door", SERVICES), Box::new(door)),
        (agent_id("logger", SERVICES), Box::new(logger)),
        (agent_id("watcher", SERVICES), Box::new(watcher)),
        (agent_id("assistant", SERVICES), Box::new(assistant)),
        (agent_id("staff", SERVICES), Box::new(console)),
    ];
    for (aid, _) in &agents {
        list(&pages, aid);
    }
    Ok(ServiceAgents {
        agents,
        refusals,
        desk,
        pages,
    })
}

/// Lists `aid` as an active agent in `pages` (already listed: nothing to do).
pub fn list(pages: &WhitePages, aid: &AgentId) {
    let _already_listed = pages.register(AmsAgentDescription {
        name: Some(aid.clone()),
        ownership: None,
        state: Some(AgentState::Active),
    });
}

/// A tap for a container's host that sends the logger a copy of every message its agents send
/// (not the logger's own copies and queries), so the log holds every message exchanged; also
/// calls `also` with each message (counting, dashboards). Copies cross the bus like any message.
/// Copies the bus has no route for yet (a container whose agents speak before the services
/// joined) wait, up to [`LOG_BACKLOG`], and go out in order before the next copy.
pub fn log_tap(
    bus: Arc<Bus>,
    logger: AgentId,
    mut also: impl FnMut(&AclMessage) + Send + 'static,
) -> Tap {
    let mut failing = false;
    let mut backlog: std::collections::VecDeque<(String, Vec<u8>)> =
        std::collections::VecDeque::new();
    Box::new(move |message: &AclMessage, now| {
        if message
            .ontology
            .as_deref()
            .is_some_and(|o| o.eq_ignore_ascii_case(LOG_ONTOLOGY))
        {
            return;
        }
        also(message);
        let mut copy = copy_for_logger(message, &logger, now.0);
        // the parser layer checks that `:sender` names the envelope's sender
        copy.sender = message.sender.clone();
        let sender = message
            .sender
            .as_ref()
            .map_or("unknown", |s| s.name.as_str());
        if backlog.len() == LOG_BACKLOG {
            backlog.pop_front();
            tracing::warn!("a copy for the logger was dropped: {LOG_BACKLOG} already wait");
        }
        backlog.push_back((sender.to_string(), iw_acl::codec::print(&copy).into_bytes()));
        while let Some((sender, bytes)) = backlog.front() {
            match bus.send(sender, &logger.name, bytes.clone()) {
                Ok(_) => {
                    failing = false;
                    backlog.pop_front();
                }
                // once per outage (a container starting before the services would warn per message)
                Err(err @ iw_bus::BusError::NoRoute { .. }) => {
                    if !failing {
                        failing = true;
                        tracing::warn!(error = %err, "copies for the logger wait until it is reachable");
                    }
                    break;
                }
                // the logger is behind: the bus counted the copy dropped and warns of it,
                // once per period, not once per copy
                Err(iw_bus::BusError::MailboxFull { .. }) => {
                    failing = false;
                    backlog.pop_front();
                }
                // not a matter of waiting: this copy cannot be sent
                Err(err) => {
                    tracing::warn!(error = %err, "a copy for the logger could not be sent");
                    backlog.pop_front();
                }
            }
        }
    })
}

/// Most copies for the logger a container keeps while the logger is unreachable.
pub const LOG_BACKLOG: usize = 4096;
