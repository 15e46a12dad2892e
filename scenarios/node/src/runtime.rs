//! [`Runtime`]: one container process, from its configuration to a clean shutdown.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::Sender;
use std::time::Duration;

use iw_acl::AgentId;
use iw_agent::AgentHost;
use iw_body::{Body, BodyWorker, MixedBody, Odometry, SerialBody, WheelGeometry};
use iw_bus::transport::{FrameTransport, PeerAddr};
use iw_bus::{Bus, BusConfig, Clock, LayerSet, Time};
use iw_container::{AgentEntry, Container, ContainerConfig, ContainerId, ContainerNode, Roster};
use iw_interface::Recognizer;
use iw_sim::{ChairKind, ChairSpec, Map, World};
use iw_stack::{GuardedTransport, Identity, Platform, PublicKey, StackConfig};
use iw_transport_net::{TcpTransport, UdpTransport};
use iw_transport_shm::ShmTransport;
use iw_wiring::world_link::{
    BodyRoster, WorldAgent, WorldBody, WorldDoors, WorldFaults, WorldGhost, body_endpoint,
    world_agent,
};
use iw_wiring::{Building, ServiceConfig, SharedBody, SharedDesk, StartError};
use nalgebra::{Isometry2, Point2, Vector2};

use crate::BodyKind;
use crate::config::{SpawnConfig, TransportKind};
use crate::probe::{AgreeProbe, SharedProbe, Timed};
use crate::{Cause, Event, NodeError, Role, SERVICES};

mod admin;
mod inflight;
pub use admin::{AdminCommand, MAX_ADMIN_LINE};

/// How long the services wait for a world before giving a present chair its goal anyway (a
/// deployment of real chairs only).
const WORLD_GRACE: Duration = Duration::from_secs(3);
/// The sample care building shipped with the sources, used when no map is configured.
const SAMPLE_BUILDING: &str = include_str!("../../maps/sample-building.map");
/// Longest the container thread waits for a control frame before it ticks (sooner when a
/// heartbeat or a lease is due): the delay before a change made here (an agent killed) is told.
const CONTROL_TICK: Duration = Duration::from_millis(50);
/// Steps the logger is given, alone, at shutdown to log the other agents' last messages.
const LOGGER_DRAIN_STEPS: usize = 5;
/// Shortest interval between two `security` events.
const SECURITY_REPORT: Duration = Duration::from_secs(5);

/// The control channel address next to bus address `addr`: the next UDP port, or the shared
/// memory inbox `addr-ctl`.
pub fn control_addr(kind: TransportKind, addr: &str) -> Result<String, NodeError> {
    match kind {
        TransportKind::Iceoryx2 => Ok(format!("{addr}-ctl")),
        TransportKind::Udp | TransportKind::Tcp => {
            let bad = |reason: &str| NodeError::Transport {
                addr: addr.into(),
                reason: reason.into(),
            };
            let (host, port) = addr
                .rsplit_once(':')
                .ok_or_else(|| bad("expected `host:port`"))?;
            let port: u16 = port
                .parse()
                .map_err(|_| bad("the port is not a number in 1..=65534"))?;
            match port {
                0 => Err(bad(
                    "port 0 cannot be used: the control channel takes the next port, so both must be known",
                )),
                u16::MAX => Err(bad(
                    "port 65535 leaves no next port for the control channel",
                )),
                p => Ok(format!("{host}:{}", p + 1)),
            }
        }
    }
}

fn open_transport(kind: TransportKind, addr: &str) -> Result<Arc<dyn FrameTransport>, NodeError> {
    let bad = |source| NodeError::Bind {
        addr: addr.into(),
        source,
    };
    Ok(match kind {
        TransportKind::Udp => Arc::new(UdpTransport::bind(addr).map_err(bad)?),
        TransportKind::Tcp => Arc::new(TcpTransport::bind(addr).map_err(bad)?),
        TransportKind::Iceoryx2 => Arc::new(ShmTransport::open(addr).map_err(bad)?),
    })
}

/// Writes a new Ed25519 identity to `path` (PKCS#8, mode 0600, fsynced); refuses to overwrite.
pub fn write_identity(path: &Path) -> Result<PublicKey, NodeError> {
    use std::io::Write;
    let bad = |source: Cause| NodeError::Key {
        path: path.display().to_string(),
        source,
    };
    let identity = Identity::generate().map_err(|e| bad(e.into()))?;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options.open(path).map_err(|e| bad(e.into()))?;
    file.write_all(identity.pkcs8())
        .and_then(|()| file.sync_all())
        .map_err(|e| bad(e.into()))?;
    Ok(identity.public_key())
}

fn load_identity(path: &str) -> Result<Identity, NodeError> {
    if path.is_empty() {
        tracing::warn!("no security.identity_key: using a fresh key for this run only");
        return Identity::generate().map_err(|e| NodeError::Key {
            path: "<generated>".into(),
            source: e.into(),
        });
    }
    let bad = |source: Cause| NodeError::Key {
        path: path.into(),
        source,
    };
    // An Ed25519 PKCS#8 document is under 100 bytes; a FIFO or a device is refused, not read.
    let pkcs8 = iw_sim::file::read_file(Path::new(path), 64 << 10).map_err(|e| bad(e.into()))?;
    Identity::from_pkcs8(&pkcs8).map_err(|e| bad(e.into()))
}

/// The group key that guards container control traffic, read from `path` (64 hex digits);
/// `None` when no file is configured (only allowed with `security.insecure_dev`).
fn load_control_key(path: &str) -> Result<Option<[u8; 32]>, NodeError> {
    if path.is_empty() {
        tracing::warn!("insecure_dev: container control traffic is not authenticated");
        return Ok(None);
    }
    iw_stack::read_group_key(Path::new(path))
        .map(Some)
        .map_err(NodeError::ControlKey)
}

/// The deployment's roster from `path`; `None` when none is configured (the weaker mode, said
/// once at start).
fn load_roster(path: &str) -> Result<Option<Arc<Roster>>, NodeError> {
    if path.is_empty() {
        tracing::warn!(
            "no security.roster: container ids are bound to keys first come, first served (a \
             holder of the control key can claim an id nobody holds); pin them with a roster"
        );
        return Ok(None);
    }
    Roster::load(Path::new(path))
        .map(|r| Some(Arc::new(r)))
        .map_err(roster_error)
}

fn roster_error(e: iw_container::ContainerError) -> NodeError {
    NodeError::Setting {
        file: "security.roster".into(),
        source: e.into(),
    }
}

/// Writes the identity keys of `members` (name, and id or 0 to derive it from the name) into
/// `dir` as `NAME.pk8` (a key already there is kept and read), then the deployment's roster of
/// them to `roster` (replaced whole, fsynced): what `security.roster` reads.
pub fn write_roster(
    roster: &Path,
    dir: &Path,
    members: &[(String, u64)],
) -> Result<Roster, NodeError> {
    use std::io::Write;
    let mut pins = Vec::new();
    for (name, id) in members {
        let id = container_id(*id, &Role::of_name(name));
        if name.is_empty() || name.contains(['/', '\\']) || name.starts_with('.') {
            return Err(NodeError::Flag {
                flag: "--member",
                value: name.clone(),
                reason: "a container name is a plain file name (no `/`, not starting with `.`)"
                    .into(),
            });
        }
        let path = dir.join(format!("{name}.pk8"));
        let key = if path.exists() {
            load_identity(&path.display().to_string())?.public_key()
        } else {
            write_identity(&path)?
        };
        pins.push((
            ContainerId(id),
            iw_container::Pin {
                name: name.clone(),
                key,
            },
        ));
    }
    let shown = roster.display().to_string();
    let roster_text = Roster::new(&shown, pins).map_err(roster_error)?;
    let bad = |e: std::io::Error| NodeError::Setting {
        file: shown.clone(),
        source: e.into(),
    };
    // written beside and renamed over, so a reader never sees half a roster
    let part = roster.with_extension("part");
    let mut file = std::fs::File::create(&part).map_err(bad)?;
    file.write_all(roster_text.to_string().as_bytes())
        .and_then(|()| file.sync_all())
        .and_then(|()| std::fs::rename(&part, roster))
        .map_err(bad)?;
    Ok(roster_text)
}

fn load_map(path: &str) -> Result<Map, NodeError> {
    if path.is_empty() {
        return Map::parse(SAMPLE_BUILDING, "sample-building.map").map_err(|e| {
            NodeError::MapLoad {
                map: "embedded sample building".into(),
                source: e.into(),
            }
        });
    }
    Map::load(path).map_err(|e| NodeError::MapLoad {
        map: path.into(),
        source: e.into(),
    })
}

/// The container id: `configured`, or when that is 0 the one derived from its role.
fn container_id(configured: u64, role: &Role) -> u64 {
    match configured {
        0 => derived_id(role),
        id => id,
    }
}

/// The id a container gets when the configuration leaves it 0: the services 1 (they lead), a
/// chair 1000 plus a hash of its name.
fn derived_id(role: &Role) -> u64 {
    match role {
        Role::Services => 1,
        Role::World => 2,
        Role::Chair { name } => {
            // FNV-1a: stable across builds and platforms, unlike the std hasher
            let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
            });
            1000 + hash % 1_000_000_000
        }
    }
}

/// The names a container registers on its bus and in the agent lists: its agents, and a chair's
/// body endpoint (the world link).
fn endpoints(role: &Role) -> Vec<String> {
    match role {
        Role::Chair { name } => iw_wiring::CHAIR_ROLES
            .iter()
            .map(|r| iw_wiring::agent_id(r, name).name)
            .chain([body_endpoint(name).name])
            .collect(),
        Role::Services => iw_wiring::SERVICE_ROLES
            .iter()
            .map(|r| iw_wiring::agent_id(r, SERVICES).name)
            .collect(),
        Role::World => vec![world_agent().name],
    }
}

/// Agents to host, with their names.
pub(crate) type Agents = Vec<(AgentId, Box<dyn iw_agent::Agent>)>;

/// The building of `config`'s map, as the wiring derives it.
fn building(config: &SpawnConfig) -> Result<Building, NodeError> {
    let map_name = if config.world.map.is_empty() {
        "embedded sample building"
    } else {
        &config.world.map
    };
    Building::from_map(load_map(&config.world.map)?).map_err(|e| NodeError::MapLoad {
        map: map_name.into(),
        source: e.into(),
    })
}

/// A chair's agents and what the runtime must keep of its body.
struct ChairParts {
    agents: Agents,
    body: SharedBody,
    drive: DriveWatch,
}

/// A chair's control agent's drive status, watched for the first command of each manual drive
/// that reaches the wheels ([`Event::DriveApplied`]).
struct DriveWatch {
    chair: String,
    status: iw_wiring::SharedDriveStatus,
    /// A non-zero command was applied at the last look.
    driving: bool,
    /// The wheels turned at the last look.
    moving: bool,
}

/// The serial body on its own I/O thread: a read blocks up to the board timeout (200 ms), four
/// control periods; the control agent takes the newest frame and refuses one older than this.
fn off_the_control_path(serial: SerialBody) -> Result<BodyWorker, NodeError> {
    BodyWorker::start(serial, Duration::from_millis(STALE_FRAME_MS)).map_err(|e| NodeError::Body {
        what: "its I/O thread".into(),
        source: e.into(),
    })
}

/// Age past which a serial sensor frame is refused, ms (the board answers every 50 ms period).
const STALE_FRAME_MS: u64 = 300;

/// How long a serial chair holds its task, wheels stopped, while its board's link is stalled
/// before the task fails (the control agent's default, 500 ms, failed it 0.8 s after the last
/// frame). A board's bytes reach the driver through the kernel's tty buffer worker, which on a
/// saturated core waited on its run queue for up to 3.09 s (every process of a deployment pinned
/// to one core beside two busy loops; docs/results/localization.md, "The real boards' serial
/// link stalls"), and a request and its answer over a pty cross it twice. The wheels still stop
/// when the newest frame is [`STALE_FRAME_MS`] old; a board silent for longer than this fails
/// the task.
const SERIAL_STALL_WAIT: Duration = Duration::from_secs(5);

/// A log file no other services container uses: named by process, a per-process counter and
/// the clock, so neither two containers in one process nor a recycled process id share one.
fn fresh_log_path() -> PathBuf {
    static STARTED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = STARTED.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    std::env::temp_dir().join(format!(
        "intellwheels-agents-{}-{n}-{nanos}.log",
        std::process::id()
    ))
}

/// Refuses a start pose outside the map's bounds, outside its free space (on a wall, inside
/// furniture, or walled off from every place of the map), or whose footprint overlaps a wall,
/// furniture or a closed door of the map (checked on a scratch copy of the world: the shared one lives in
/// the world container).
fn refuse_an_obstructed_start(config: &SpawnConfig) -> Result<(), NodeError> {
    let t_world_body = &start_pose(config);
    let map = load_map(&config.world.map)?;
    let (min, max) = map.bounds();
    let at = t_world_body.translation.vector;
    if !(min.x..=max.x).contains(&at.x) || !(min.y..=max.y).contains(&at.y) {
        return Err(NodeError::Config {
            file: "body.start".into(),
            reason: format!(
                "{:?} (--start X,Y,DEG) is outside the map, which spans x {:.2}..{:.2} m and \
                 y {:.2}..{:.2} m",
                config.body.start, min.x, max.x, min.y, max.y
            ),
        });
    }
    let free = map.free_space_at(&Point2::from(at));
    let mut scratch = World::new(map, config.world.seed);
    let id = scratch.add_chair(ChairSpec::default(), *t_world_body, ChairKind::Simulated);
    let obstruction = scratch.obstruction(id).map_err(|e| NodeError::Body {
        what: "its start pose".into(),
        source: e.into(),
    })?;
    match obstruction {
        Some(what) => Err(NodeError::Config {
            file: "body.start".into(),
            reason: format!(
                "{:?} puts the chair's footprint on {} of the map",
                config.body.start,
                scratch.describe(what)
            ),
        }),
        None => free.map_err(|why| NodeError::Config {
            file: "body.start".into(),
            reason: format!("{:?} (--start X,Y,DEG) is {why}", config.body.start),
        }),
    }
}

/// `body.start` as a pose in the map frame.
fn start_pose(config: &SpawnConfig) -> Isometry2<f64> {
    let [x, y, heading_deg] = config.body.start;
    Isometry2::new(Vector2::new(x, y), heading_deg.to_radians())
}

/// Chair `name`'s agents over its body: a virtual body lives in the world container; a real
/// (serial) or mixed one reports its pose there, and a mixed one senses the world's obstacles.
fn chair_parts(name: &str, config: &SpawnConfig, bus: &Arc<Bus>) -> Result<ChairParts, NodeError> {
    let link_err = |e: iw_wiring::WiringError| {
        NodeError::Start(StartError {
            container: name.into(),
            what: "its world link".into(),
            source: e.into(),
        })
    };
    let t_world_body = start_pose(config);
    let serial = || {
        SerialBody::open(&config.body.port, config.body.baud, config.body.timeout).map_err(|e| {
            NodeError::Body {
                what: format!("serial port `{}`", config.body.port),
                source: e.into(),
            }
        })
    };
    let building = building(config)?;
    let mut visual = None;
    let body = match config.body.kind {
        BodyKind::Virtual => {
            let body = WorldBody::open(bus.clone(), name, t_world_body)
                .map_err(link_err)?
                .lockstep(config.world.lockstep);
            if config.body.visual_odometry {
                visual = Some(
                    iw_wiring::camera::mirror_camera(
                        name,
                        load_map(&config.world.map)?,
                        t_world_body,
                        body.true_pose(),
                    )
                    .map_err(link_err)?,
                );
            }
            SharedBody::new(body).outages(config.body.reattach_wait)
        }
        BodyKind::Real | BodyKind::Mixed => {
            let senses = config.body.kind == BodyKind::Mixed;
            let ghost =
                WorldGhost::open(bus.clone(), name, t_world_body, senses).map_err(link_err)?;
            SharedBody::new(MixedBody::new(
                off_the_control_path(serial()?)?,
                ghost,
                Odometry::new(WheelGeometry::default(), t_world_body),
            ))
            .outages(SERIAL_STALL_WAIT)
        }
    };
    let parts = iw_wiring::chair_agents(
        name,
        &t_world_body,
        &building,
        body.clone(),
        visual,
        Recognizer::new(iw_interface::sequence::DEFAULT_MAX_GAP),
    )
    .map_err(|e| {
        NodeError::Start(StartError {
            container: name.into(),
            what: "its agents".into(),
            source: e.into(),
        })
    })?;
    Ok(ChairParts {
        agents: parts.agents,
        body,
        drive: DriveWatch {
            chair: name.to_string(),
            status: parts.drive_status,
            driving: false,
            moving: false,
        },
    })
}

/// The world container's agent over `config`'s map.
fn world_parts(config: &SpawnConfig) -> Result<(Agents, WorldReports), NodeError> {
    let world = World::new(load_map(&config.world.map)?, config.world.seed);
    let agent = WorldAgent::new(iw_sim::shared(world), iw_wiring::agent_id("door", SERVICES))
        .lockstep(config.world.lockstep);
    let (world, roster) = agent.reports();
    let reports = WorldReports {
        world,
        roster,
        faults: agent.sensor_faults(),
        last: None,
    };
    Ok((vec![(world_agent(), Box::new(agent))], reports))
}

/// What the world runtime reports from: the world, its bodies, the last report; and the faults
/// it plays in its bodies' frames (admin commands).
struct WorldReports {
    world: iw_sim::SharedWorld,
    roster: BodyRoster,
    faults: WorldFaults,
    last: Option<Time>,
}

/// What the services runtime keeps: the console's desk, the goals to give and what became of
/// them.
struct ServiceDesk {
    desk: SharedDesk,
    /// Goals not yet given: chair, place.
    waiting: Vec<(String, String)>,
    /// Goals given and not answered for good (AGREE is not final), by conversation: chair,
    /// place.
    given: BTreeMap<String, (String, String)>,
    /// Console answers already reported.
    reported: usize,
    conversations: u64,
    last_pose_report: BTreeMap<String, Time>,
    /// When each present chair's cognitive agent was first seen.
    seen_at: BTreeMap<String, Time>,
    /// Chairs asked for their goal under way and not yet answered: how many times.
    goal_asked: BTreeMap<String, u32>,
    /// The dashboard, when configured.
    dashboard: Option<crate::dashboard::LiveDashboard>,
    /// The assistant's REQUEST/AGREE round trips to the chairs.
    probe: SharedProbe,
}

fn service_parts(config: &SpawnConfig, bus: &Arc<Bus>) -> Result<(Agents, ServiceDesk), NodeError> {
    let building = building(config)?;
    let map_name = if config.world.map.is_empty() {
        "embedded sample building"
    } else {
        &config.world.map
    };
    let mut waiting = Vec::new();
    for g in &config.services.goals {
        let place = if building.destinations().any(|(n, _)| *n == g.place) {
            g.place.clone()
        } else {
            let point = parse_point(&g.place).ok_or_else(|| NodeError::Map {
                map: map_name.into(),
                reason: format!(
                    "goal of {}: `{}` is neither a place of the map nor `x,y` in metres",
                    g.chair, g.place
                ),
            })?;
            building.place_at(point).map_err(|source| NodeError::Goal {
                map: map_name.into(),
                chair: g.chair.clone(),
                source,
            })?
        };
        waiting.push((g.chair.clone(), place));
    }
    let mut chairs: BTreeSet<String> = config.services.chairs.iter().cloned().collect();
    chairs.extend(waiting.iter().map(|(c, _)| c.clone()));
    chairs.extend(config.services.restricted.values().flatten().cloned());
    let log_path = if config.services.log.is_empty() {
        fresh_log_path()
    } else {
        PathBuf::from(&config.services.log)
    };
    tracing::info!(log = %log_path.display(), "the logger agent writes every message here");
    let service_config = ServiceConfig {
        restricted: config
            .services
            .restricted
            .iter()
            .map(|(door, chairs)| (door.clone(), chairs.iter().cloned().collect()))
            .collect(),
        ..ServiceConfig::new(chairs.into_iter().collect(), log_path)
    };
    let door_ids = iw_wiring::door_ids(&building.map);
    let mut doors: Box<dyn iw_door::DoorActuator> = Box::new(WorldDoors::new(
        bus.clone(),
        iw_wiring::agent_id("door", SERVICES),
        door_ids.clone(),
    ));
    let mut dashboard = crate::dashboard::LiveDashboard::start(&config.dashboard, &building)?;
    if let Some(dashboard) = &dashboard {
        doors = dashboard.watch_doors(doors, door_ids);
    }
    let parts = iw_wiring::service_agents(&service_config, &building, doors).map_err(|e| {
        NodeError::Start(StartError {
            container: SERVICES.into(),
            what: "its agents".into(),
            source: e.into(),
        })
    })?;
    let probe = SharedProbe::default();
    let agents: Vec<_> = parts
        .agents
        .into_iter()
        .map(|(aid, agent)| {
            let agent: Box<dyn iw_agent::Agent> =
                if aid.name == iw_wiring::agent_id("assistant", SERVICES).name {
                    Box::new(Timed {
                        inner: agent,
                        probe: probe.clone(),
                    })
                } else {
                    agent
                };
            (aid, agent)
        })
        .collect();
    let agents = match &mut dashboard {
        Some(dashboard) => {
            // the chair views show the sonar picture and what shared control applied
            iw_wiring::desk(&parts.desk).screen = true;
            dashboard.attach(agents, parts.refusals)
        }
        None => agents,
    };
    Ok((
        agents,
        ServiceDesk {
            desk: parts.desk,
            waiting,
            given: BTreeMap::new(),
            reported: 0,
            conversations: 0,
            last_pose_report: BTreeMap::new(),
            seen_at: BTreeMap::new(),
            goal_asked: BTreeMap::new(),
            dashboard,
            probe,
        },
    ))
}

/// `x,y` in metres, both finite.
fn parse_point(text: &str) -> Option<nalgebra::Point2<f64>> {
    let (x, y) = text.split_once(',')?;
    let (x, y) = (x.trim().parse::<f64>().ok()?, y.trim().parse::<f64>().ok()?);
    (x.is_finite() && y.is_finite()).then(|| nalgebra::Point2::new(x, y))
}

/// The control channel's rejections: its group-key guard's, and the container's own (ids and
/// keys the roster does not pin, lists carrying foreign agents).
fn control_counters(
    guard: Option<&GuardedTransport>,
    container: Option<&ContainerNode>,
) -> iw_bus::Counters {
    let mut counters = guard.map(|g| g.counters()).unwrap_or_default();
    if let Some(container) = container {
        container.with(|c| counters.merge(c.counters()));
    }
    counters
}

/// An agent of another container, as installed on this bus.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Installed {
    container: ContainerId,
    /// The container's life: a restart (a higher one) is a leave and a join, even when it came
    /// back within the lease with the same key and address.
    incarnation: u32,
    key: PublicKey,
    addr: PeerAddr,
}

/// One running container. See the crate docs.
pub struct Runtime {
    name: String,
    /// The agents this container hosts.
    agent_names: Vec<String>,
    /// The HTTP MTP gateway, when configured (services).
    mtp: Option<crate::mtp::HttpMtp>,
    config: SpawnConfig,
    host: AgentHost,
    platform: Platform,
    container: Option<ContainerNode>,
    control_guard: Option<Arc<GuardedTransport>>,
    installed: BTreeMap<String, Installed>,
    /// The container's list revision `installed` reflects: unchanged lists are not walked again
    /// (every step, at 100 chairs 500 entries in every process).
    lists_revision: Option<u64>,
    services: Option<ServiceDesk>,
    messages_sent: Arc<AtomicU64>,
    world: Option<WorldReports>,
    body: Option<SharedBody>,
    drive: Option<DriveWatch>,
    events: Sender<Event>,
    /// Admin commands from the parent process ([`Runtime::with_admin`]).
    admin: Option<std::sync::mpsc::Receiver<Result<AdminCommand, String>>>,
}

impl Runtime {
    /// Binds, registers and starts everything `config` asks for `role`; reports [`Event::Ready`].
    pub fn start(
        role: &Role,
        config: SpawnConfig,
        events: Sender<Event>,
    ) -> Result<Runtime, NodeError> {
        config.validate(role)?;
        if let Role::Chair { .. } = role {
            // before anything binds: a chair that cannot start there takes no port
            refuse_an_obstructed_start(&config)?;
        }
        let name = role.name().to_string();
        let setup = |what: &str, source: Cause| {
            NodeError::Start(StartError {
                container: name.clone(),
                what: what.into(),
                source,
            })
        };
        let layers: LayerSet = config
            .security
            .layers
            .parse()
            .map_err(|e: iw_bus::BusError| NodeError::Setting {
                file: "security.layers".into(),
                source: e.into(),
            })?;
        let identity = Arc::new(load_identity(&config.security.identity_key)?);
        let control_key = load_control_key(&config.security.control_key)?;
        let roster = load_roster(&config.security.roster)?;
        let id = container_id(config.container.id, role);
        if let Some(roster) = &roster {
            roster
                .check_own(ContainerId(id), Some(&name), &identity.public_key())
                .map_err(roster_error)?;
        }
        let t = &config.transport;
        let advertise = if t.advertise.is_empty() {
            t.listen.clone()
        } else {
            t.advertise.clone()
        };
        let bus_transport = open_transport(t.kind, &t.listen)?;
        let control_listen = control_addr(t.kind, &t.listen)?;
        let control_transport = open_transport(t.kind, &control_listen)?;
        let seeds = t
            .peers
            .iter()
            .map(|p| control_addr(t.kind, p).map(PeerAddr))
            .collect::<Result<Vec<_>, _>>()?;

        let platform = Platform::new();
        let names = endpoints(role);
        for agent in &names {
            platform.register(agent, identity.public_key());
        }
        let node = iw_stack::Node {
            identity: identity.clone(),
            agents: names.clone(),
        };
        let stack = platform.stack(&node, &StackConfig::with_layers(layers));
        let clock = Clock::system();
        let bus = Bus::start(stack, bus_transport, clock.clone(), BusConfig::default())
            .map_err(|e| setup("the bus", e.into()))?;
        let bus = Arc::new(bus);
        let (agents, body, drive, services, world) = match role {
            Role::Chair { name } => {
                let parts = chair_parts(name, &config, &bus)?;
                (
                    parts.agents,
                    Some(parts.body),
                    Some(parts.drive),
                    None,
                    None,
                )
            }
            Role::Services => {
                let (agents, desk) = service_parts(&config, &bus)?;
                (agents, None, None, Some(desk), None)
            }
            Role::World => {
                let (agents, reports) = world_parts(&config)?;
                (agents, None, None, None, Some(reports))
            }
        };
        let mtp = match role {
            Role::Services => crate::mtp::HttpMtp::start(
                &config.mtp.http.listen,
                bus.clone(),
                &platform,
                identity.public_key(),
            )?,
            _ => None,
        };
        let mut host = AgentHost::new(bus.clone());
        let messages_sent = Arc::new(AtomicU64::new(0));
        if *role != Role::World {
            // every message sent here is copied to the logger, as in the in-process fleet
            // (the world's sensor frames are not conversation)
            let sent = messages_sent.clone();
            let probe = services.as_ref().map(|s| s.probe.clone());
            host.set_tap(iw_wiring::log_tap(
                bus,
                iw_wiring::agent_id("logger", SERVICES),
                move |message| {
                    sent.fetch_add(1, Ordering::AcqRel);
                    if let Some(probe) = &probe {
                        AgreeProbe::on_sent(probe, message);
                    }
                },
            ));
        }
        let agent_names: Vec<String> = agents.iter().map(|(aid, _)| aid.name.clone()).collect();
        for (aid, agent) in agents {
            let what = format!("agent `{}`", aid.name);
            host.add(aid, agent).map_err(|e| setup(&what, e.into()))?;
        }

        let incarnation = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as u32);
        let container_config = ContainerConfig {
            incarnation,
            heartbeat: config.container.heartbeat,
            lease: config.container.lease,
            roster,
            ..ContainerConfig::new(ContainerId(id), PeerAddr(control_listen), seeds)
        };
        let mut container = Container::new(container_config);
        for agent in &names {
            container.register(AgentEntry {
                name: agent.clone(),
                public_key: identity.public_key().to_vec(),
                addr: PeerAddr(advertise.clone()),
            });
        }
        // The guard's sender name keys the temporal layer's sequence numbers at each receiver, so
        // it is unique per process: a duplicate started in the same second as the holder (same
        // id and incarnation) must not make the holder's frames look out of order.
        let nonce = std::hash::BuildHasher::hash_one(
            &std::collections::hash_map::RandomState::new(),
            std::process::id(),
        );
        let control_guard = match control_key {
            Some(key) => Some(Arc::new(
                GuardedTransport::new(
                    control_transport.clone(),
                    &format!("container-{id}.{incarnation}.{nonce:016x}"),
                    key,
                    clock.clone(),
                )
                .map_err(|e| setup("the control guard", e.into()))?,
            )),
            None => None,
        };
        let control_transport: Arc<dyn FrameTransport> = match &control_guard {
            Some(guard) => guard.clone(),
            None => control_transport,
        };
        let container = ContainerNode::start(
            container,
            identity.clone(),
            control_transport,
            clock,
            CONTROL_TICK,
        )
        .map_err(|e| setup("its control plane", e.into()))?;
        // a closed receiver only means nobody is listening to reports
        let _ = events.send(Event::Ready {
            container: name.clone(),
            id,
            bus: advertise,
            agents: agent_names.clone(),
        });
        if let Some(dashboard) = services.as_ref().and_then(|s| s.dashboard.as_ref()) {
            let _ = events.send(Event::Serving {
                container: name.clone(),
                service: "dashboard".into(),
                url: dashboard.url(),
            });
        }
        if let Some(mtp) = &mtp {
            let _ = events.send(Event::Serving {
                container: name.clone(),
                service: "mtp-http".into(),
                url: mtp.url(),
            });
        }
        Ok(Runtime {
            mtp,
            agent_names,
            name,
            config,
            host,
            platform,
            container: Some(container),
            control_guard,
            installed: BTreeMap::new(),
            lists_revision: None,
            messages_sent,
            services,
            world,
            body,
            drive,
            events,
            admin: None,
        })
    }

    /// Steps the agents every `container.step` of real time until `stop` is set, then shuts
    /// down cleanly. Fails, after shutting down, if another live container holds this one's id.
    pub fn run(mut self, stop: &AtomicBool) -> Result<(), NodeError> {
        let period = self.config.container.step;
        let clock = self.host.bus().clock().clone();
        let mut reported = (iw_bus::Counters::default(), iw_bus::Counters::default());
        let mut next_report = clock.now();
        while !stop.load(Ordering::Acquire) {
            let refused = self
                .container
                .as_ref()
                .and_then(|c| c.with(|c| c.refusal().map(str::to_owned)));
            if let Some(reason) = refused {
                let container = self.name.clone();
                self.shutdown();
                return Err(NodeError::Setup { container, reason });
            }
            let now = clock.now();
            if now >= next_report {
                next_report = now.plus(SECURITY_REPORT);
                self.report_security(&mut reported);
            }
            let left = self.sync_agent_lists();
            self.obey(now);
            self.serve(now, &left);
            self.report_bodies(now);
            self.host.step(now);
            self.report_drive();
            std::thread::sleep(period.saturating_sub(clock.now().since(now)));
        }
        self.shutdown();
        Ok(())
    }

    /// Routes and trusts exactly the other containers' agents the GAL lists under a live
    /// container; reports who joined and who left, and returns who left.
    fn sync_agent_lists(&mut self) -> Vec<String> {
        let Some(container) = &self.container else {
            return Vec::new();
        };
        let present: Option<BTreeMap<String, Installed>> = container.with(|c| {
            if self.lists_revision == Some(c.revision()) {
                return None;
            }
            self.lists_revision = Some(c.revision());
            // A container hears only the leader and its seeds; the leader's list keeps only
            // live containers, so while the leader is live its list is trusted as it stands
            // (chairs reach the world through it).
            let live = c.live_peers();
            let leader_live = live.contains(&c.leader());
            let me = c.id();
            let versions = c.gal().versions();
            c.gal()
                .entries()
                .filter(|(id, _)| *id != me && (live.contains(id) || leader_live))
                .filter_map(|(id, e)| {
                    let key = <PublicKey>::try_from(e.public_key.as_slice()).ok()?;
                    Some((
                        e.name.clone(),
                        Installed {
                            container: id,
                            incarnation: versions.get(&id).map_or(0, |g| (g >> 32) as u32),
                            key,
                            addr: e.addr.clone(),
                        },
                    ))
                })
                .collect::<BTreeMap<_, _>>()
                .into()
        });
        let Some(present) = present else {
            return Vec::new();
        };
        let bus = self.host.bus().clone();
        let gone: Vec<(String, Installed)> = self
            .installed
            .iter()
            .filter(|(name, was)| present.get(*name) != Some(was))
            .map(|(n, w)| (n.clone(), w.clone()))
            .collect();
        let left: Vec<String> = gone.iter().map(|(agent, _)| agent.clone()).collect();
        for (agent, was) in gone {
            self.platform.deregister(&agent);
            bus.remove_route(&agent);
            self.installed.remove(&agent);
            let _ = self.events.send(Event::Left {
                agent,
                container: was.container.0,
            });
        }
        for (agent, entry) in present {
            if self.installed.contains_key(&agent) {
                continue;
            }
            self.platform.register(&agent, entry.key);
            bus.add_route(&agent, entry.addr.clone());
            let _ = self.events.send(Event::Joined {
                agent: agent.clone(),
                container: entry.container.0,
            });
            self.installed.insert(agent, entry);
        }
        left
    }

    /// Chairs only: reports the first non-zero command of each manual drive as it reaches the
    /// wheels, and each change between turning and stopped wheels.
    fn report_drive(&mut self) {
        let Some(watch) = &mut self.drive else { return };
        let unix_ms = || {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64() * 1e3)
        };
        let moving = self.body.as_ref().is_some_and(SharedBody::moving);
        if moving != watch.moving {
            watch.moving = moving;
            let _ = self.events.send(Event::Wheels {
                chair: watch.chair.clone(),
                moving,
                unix_ms: unix_ms(),
            });
        }
        let applied = watch
            .status
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .applied
            .filter(|v| v.linear_mps != 0.0 || v.angular_radps != 0.0);
        let driving = applied.is_some();
        if let Some(v) = applied
            && !watch.driving
        {
            let _ = self.events.send(Event::DriveApplied {
                chair: watch.chair.clone(),
                linear_mps: v.linear_mps,
                angular_radps: v.angular_radps,
                unix_ms: unix_ms(),
            });
        }
        watch.driving = driving;
    }

    /// World only: reports every body every `services.pose_report`.
    fn report_bodies(&mut self, now: Time) {
        let Some(reports) = &mut self.world else {
            return;
        };
        let every = self.config.services.pose_report;
        if reports.last.is_some_and(|last| now < last.plus(every)) {
            return;
        }
        reports.last = Some(now);
        let bodies = reports
            .roster
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone();
        let world = reports
            .world
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        for (chair, id) in bodies {
            let (Ok(pose), Ok(distance_m), Ok(collisions)) =
                (world.pose(id), world.distance_m(id), world.collisions(id))
            else {
                continue;
            };
            let _ = self.events.send(Event::Body {
                chair,
                x_m: pose.translation.x,
                y_m: pose.translation.y,
                theta_rad: pose.rotation.angle(),
                distance_m,
                collisions,
                world_s: world.time_ns() as f64 * 1e-9,
            });
        }
    }

    /// Services only: watches the chairs present, gives each configured goal once its chair's
    /// cognitive agent is present and its pose known, and reports the console's answers and the
    /// chairs' poses. A goal in flight to a chair whose cognitive agent `left` (its container
    /// stopped, or restarted and lost its plan) is reported failed, with the reason, and given
    /// again once the chair is back: never silently lost.
    fn serve(&mut self, now: Time, left: &[String]) {
        let Some(services) = &mut self.services else {
            return;
        };
        let installed = &self.installed;
        let world_present = installed.contains_key(&world_agent().name);
        let chairs: BTreeSet<String> = installed
            .keys()
            .filter_map(|a| a.strip_prefix("cognitive@"))
            .map(str::to_string)
            .collect();
        let gone: BTreeSet<&str> = left
            .iter()
            .filter_map(|a| a.strip_prefix("cognitive@"))
            .collect();
        services
            .seen_at
            .retain(|c, _| chairs.contains(c) && !gone.contains(c.as_str()));
        services.goal_asked.retain(|c, _| chairs.contains(c));
        // A chair that joins (or joins again) is asked for the goal it carries out: one given
        // past these services, or by their earlier life, is taken up below.
        let joined: Vec<String> = chairs
            .iter()
            .filter(|c| !services.seen_at.contains_key(*c))
            .cloned()
            .collect();
        for chair in &chairs {
            services.seen_at.entry(chair.clone()).or_insert(now);
        }
        let answers = {
            let mut desk = iw_wiring::desk(&services.desk);
            desk.goal_queries.extend(joined);
            std::mem::take(&mut desk.current_goals)
        };
        let assistant = iw_wiring::agent_id("assistant", SERVICES).name;
        for (chair, answer) in answers {
            let present = chairs.contains(&chair);
            for event in services.take_goal_answer(chair, answer, present, &assistant) {
                let _ = self.events.send(event);
            }
        }
        let mut desk = iw_wiring::desk(&services.desk);
        desk.watch = installed
            .keys()
            .filter_map(|a| a.strip_prefix("perception@"))
            .map(str::to_string)
            .collect();
        for answer in &desk.events[services.reported..] {
            let Some((chair, place)) = services.given.get(&answer.conversation) else {
                continue;
            };
            let _ = self.events.send(Event::Goal {
                chair: chair.clone(),
                place: place.clone(),
                conversation: answer.conversation.clone(),
                performative: answer.performative.clone(),
                reason: answer.reason.clone(),
                requester: None,
            });
            if answer.performative != "AGREE" {
                // answered for good: nothing more is expected in this conversation
                services.given.remove(&answer.conversation);
            }
        }
        services.reported = desk.events.len();
        for &chair in &gone {
            // its pose and subscription died with it: wait for the new agent's
            desk.poses.remove(chair);
            desk.sonar.remove(chair);
            desk.applied.remove(chair);
            desk.resubscribe.insert(chair.to_string());
            services.last_pose_report.remove(chair);
            let lost: Vec<String> = services
                .given
                .iter()
                .filter(|(_, (c, _))| c == chair)
                .map(|(conversation, _)| conversation.clone())
                .collect();
            for conversation in lost {
                let Some((chair, place)) = services.given.remove(&conversation) else {
                    continue;
                };
                let _ = self.events.send(Event::Goal {
                    chair: chair.clone(),
                    place: place.clone(),
                    conversation,
                    performative: "FAILURE".into(),
                    reason: Some(format!(
                        "{chair} left before the goal was done (its container stopped or restarted); the goal is given again when it is back"
                    )),
                    requester: None,
                });
                services.waiting.push((chair, place));
            }
        }
        let (ready, waiting): (Vec<_>, Vec<_>) = std::mem::take(&mut services.waiting)
            .into_iter()
            // a chair takes goals once its perception agent publishes and the world is there for
            // its body (a deployment without a world: after WORLD_GRACE)
            .partition(|(chair, _)| {
                let since = services.seen_at.get(chair);
                desk.poses.contains_key(chair)
                    && since.is_some_and(|at| world_present || now >= at.plus(WORLD_GRACE))
            });
        services.waiting = waiting;
        for (chair, place) in ready {
            admin::give(
                &mut desk,
                &mut services.conversations,
                &mut services.given,
                chair,
                place,
            );
        }
        for (chair, round_trip_ms) in AgreeProbe::take(&services.probe) {
            let _ = self.events.send(Event::Agreed {
                chair,
                round_trip_ms,
            });
        }
        let every = self.config.services.pose_report;
        for (chair, [x_m, y_m, theta_rad]) in &desk.poses {
            let due = services
                .last_pose_report
                .get(chair)
                .is_none_or(|last| now >= last.plus(every));
            if due {
                services.last_pose_report.insert(chair.clone(), now);
                let _ = self.events.send(Event::Pose {
                    chair: chair.clone(),
                    x_m: *x_m,
                    y_m: *y_m,
                    theta_rad: *theta_rad,
                });
            }
        }
        drop(desk);
        if let Some(dashboard) = &mut services.dashboard {
            let goals = dashboard.take_actions(&services.desk);
            services.waiting.extend(goals);
            dashboard.publish(
                now,
                &services.desk,
                &services.given,
                &mut installed.keys(),
                &self.agent_names,
                || {
                    let control =
                        control_counters(self.control_guard.as_deref(), self.container.as_ref());
                    let bus = self.host.bus().counters();
                    let bus = bus.nonzero().map(|(r, n)| (r.name().to_string(), n));
                    let control = control
                        .nonzero()
                        .map(|(r, n)| (format!("control:{}", r.name()), n))
                        .collect::<Vec<_>>();
                    bus.chain(control).collect()
                },
            );
        }
    }

    /// Sends a `security` event if the rejection counts changed since `reported`.
    fn report_security(&self, reported: &mut (iw_bus::Counters, iw_bus::Counters)) {
        let bus = self.host.bus().counters();
        let control = control_counters(self.control_guard.as_deref(), self.container.as_ref());
        if (&bus, &control) == (&reported.0, &reported.1) {
            return;
        }
        let named = |c: &iw_bus::Counters| {
            c.nonzero()
                .map(|(r, n)| (r.name().to_string(), n))
                .collect()
        };
        let _ = self.events.send(Event::Security {
            container: self.name.clone(),
            bus: named(&bus),
            control: named(&control),
        });
        *reported = (bus, control);
    }

    fn shutdown(mut self) {
        // foreign platforms first: nothing arrives from them while the agents take down
        drop(self.mtp.take());
        let clock = self.host.bus().clock().clone();
        // The logger goes last, after it has taken the copies of the others' last messages
        // (sent by their take-downs), so the log holds every message the container sent.
        let logger = iw_wiring::agent_id("logger", SERVICES).name;
        for name in self.host.agent_names() {
            if name != logger {
                self.host.remove(&name, clock.now());
            }
        }
        if self.services.is_some() {
            let period = self.config.container.step;
            for _ in 0..LOGGER_DRAIN_STEPS {
                std::thread::sleep(period);
                self.host.step(clock.now());
            }
        }
        self.host.shutdown(clock.now());
        if let Some(body) = &mut self.body
            && let Err(e) = body.stop()
        {
            tracing::error!(container = %self.name, error = %e, "could not send the body a last stop");
        }
        if let Some(container) = self.container.take() {
            container.with(|c| {
                let names: Vec<String> = c.lal().entries().map(|e| e.name.clone()).collect();
                for name in names {
                    c.deregister(&name);
                }
            });
            // The leader asks for the new list with its next heartbeat; give it that long.
            std::thread::sleep(self.config.container.shutdown_grace);
            container.stop();
        }
        let _ = self.events.send(Event::Stopped {
            container: self.name.clone(),
            messages_sent: self.messages_sent.load(Ordering::Acquire),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_start_pose_on_a_wall_or_outside_the_map_is_refused_with_the_key() {
        let mut config = SpawnConfig::default();
        // On the sample building's wall from (0, 7) to (1.4, 7).
        config.body.start = [0.7, 7.0, 0.0];
        let err = refuse_an_obstructed_start(&config)
            .expect_err("a start pose on a wall is refused")
            .to_string();
        assert!(
            err.contains("body.start") && err.contains("a wall"),
            "{err}"
        );
        // Far outside the building, and at coordinates no map reaches.
        for start in [[1e9, 6.0, 0.0], [1.0, -1e6, 0.0]] {
            config.body.start = start;
            let err = refuse_an_obstructed_start(&config)
                .expect_err("a start pose outside the map is refused")
                .to_string();
            assert!(
                err.contains("body.start") && err.contains("--start") && err.contains("outside"),
                "{err}"
            );
        }
        // Inside the building's outer box, clear of every wall, but not where a chair can be:
        // wholly inside the therapy room's 2 x 1 m bed (its footprint touches no outline).
        config.body.start = [14.0, 2.5, 0.0];
        let err = refuse_an_obstructed_start(&config)
            .expect_err("a start inside furniture is refused")
            .to_string();
        assert!(
            err.contains("body.start") && err.contains("--start") && err.contains("furniture"),
            "{err}"
        );
        config.body.start = SpawnConfig::default().body.start;
        assert!(refuse_an_obstructed_start(&config).is_ok());
    }

    #[test]
    fn control_key_file_is_64_hex_digits() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("control.key");
        std::fs::write(&path, format!("{}\n", "0f".repeat(32))).unwrap();
        assert_eq!(
            load_control_key(path.to_str().unwrap()).unwrap(),
            Some([0x0f; 32])
        );
        assert_eq!(load_control_key("").unwrap(), None);
        for bad in ["0f".repeat(31), "zz".repeat(32), "é".repeat(64)] {
            std::fs::write(&path, &bad).unwrap();
            let err = load_control_key(path.to_str().unwrap())
                .unwrap_err()
                .to_string();
            assert!(
                err.contains("control.key") && err.contains("64 hex digits"),
                "{err}"
            );
        }
        let missing = dir.path().join("missing.key");
        let err = load_control_key(missing.to_str().unwrap()).unwrap_err();
        assert!(err.to_string().contains("missing.key"), "{err}");
        // the OS's error is kept under the message
        let io = std::error::Error::source(&err)
            .and_then(|s| s.downcast_ref::<std::io::Error>())
            .unwrap_or_else(|| panic!("no io::Error under `{err}`"));
        assert_eq!(io.kind(), std::io::ErrorKind::NotFound);
    }
}
