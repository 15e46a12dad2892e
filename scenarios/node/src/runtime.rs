//! [`Runtime`]: one container process, from its configuration to a clean shutdown.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::AgentId;
use iw_agent::AgentHost;
use iw_body::{Body, BodyWorker, MixedBody, Odometry, SerialBody, WheelGeometry};
use iw_bus::transport::{FrameTransport, PeerAddr};
use iw_bus::{Bus, BusConfig, Clock, LayerSet};
use iw_container::{AgentEntry, Container, ContainerConfig, ContainerId, ContainerNode};
use iw_control_agent::{ControlAgent, ControlConfig};
use iw_fleet::compose::SharedBody;
use iw_perception_agent::{PerceptionAgent, PerceptionConfig};
use iw_sim::{ChairKind, ChairSpec, GhostSensors, Map, SharedWorld, VirtualBody, World};
use iw_stack::{GuardedTransport, Identity, Platform, PublicKey, StackConfig};
use iw_transport_net::{TcpTransport, UdpTransport};
use iw_transport_shm::ShmTransport;
use iw_vo::Pose2;
use nalgebra::{Isometry2, Vector2};

use crate::config::{BodyKind, SpawnConfig, TransportKind};
use crate::dispatcher::{Dispatcher, Roster};
use crate::{Event, NodeError, Role, SERVICES};

/// The sample care building shipped with the sources, used when no map is configured.
const SAMPLE_BUILDING: &str = include_str!("../../maps/sample-building.map");
/// How long the container thread waits for a control frame before it ticks.
const CONTROL_TICK: Duration = Duration::from_millis(10);
/// Clearance the services' planner keeps from walls, furniture and closed doors, m (the chair's
/// half width plus a margin).
const CLEARANCE_M: f64 = 0.4;
/// Shortest interval between two `security` events.
const SECURITY_REPORT: Duration = Duration::from_secs(5);
/// Longest simulated step after a stall, s (the simulator never leaps).
const MAX_SIM_STEP_S: f64 = 0.2;

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
    let bad = |e: iw_bus::transport::TransportError| NodeError::Transport {
        addr: addr.into(),
        reason: e.to_string(),
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
    let bad = |reason: String| NodeError::Key {
        path: path.display().to_string(),
        reason,
    };
    let identity = Identity::generate().map_err(|e| bad(e.to_string()))?;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options.open(path).map_err(|e| bad(e.to_string()))?;
    file.write_all(identity.pkcs8())
        .and_then(|()| file.sync_all())
        .map_err(|e| bad(e.to_string()))?;
    Ok(identity.public_key())
}

fn load_identity(path: &str) -> Result<Identity, NodeError> {
    if path.is_empty() {
        tracing::warn!("no security.identity_key: using a fresh key for this run only");
        return Identity::generate().map_err(|e| NodeError::Key {
            path: "<generated>".into(),
            reason: e.to_string(),
        });
    }
    let bad = |reason: String| NodeError::Key {
        path: path.into(),
        reason,
    };
    let pkcs8 = std::fs::read(path).map_err(|e| bad(e.to_string()))?;
    Identity::from_pkcs8(&pkcs8).map_err(|e| bad(e.to_string()))
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
        .map_err(|e| NodeError::ControlKey {
            path: e.path,
            reason: e.reason,
        })
}

fn load_map(path: &str) -> Result<Map, NodeError> {
    if path.is_empty() {
        return Map::parse(SAMPLE_BUILDING, "sample-building.map").map_err(|e| NodeError::Map {
            map: "embedded sample building".into(),
            reason: e.to_string(),
        });
    }
    Map::load(path).map_err(|e| NodeError::Map {
        map: path.into(),
        reason: e.to_string(),
    })
}

/// The id a container gets when the configuration leaves it 0: the services 1 (they lead), a
/// chair 1000 plus a hash of its name.
fn derived_id(role: &Role) -> u64 {
    match role {
        Role::Services => 1,
        Role::Chair { name } => {
            // FNV-1a: stable across builds and platforms, unlike the std hasher
            let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
            });
            1000 + hash % 1_000_000_000
        }
    }
}

/// Agents to host, with their names.
type Agents = Vec<(AgentId, Box<dyn iw_agent::Agent>)>;

/// A chair's agents and what the runtime must keep of its body.
struct ChairParts {
    agents: Agents,
    world: Option<SharedWorld>,
    body: SharedBody,
}

/// The serial body on its own I/O thread: a read blocks up to the board timeout (200 ms), four
/// control periods; the control agent takes the newest frame and refuses one older than this.
fn off_the_control_path(serial: SerialBody) -> Result<BodyWorker, NodeError> {
    BodyWorker::start(serial, Duration::from_millis(STALE_FRAME_MS)).map_err(|e| NodeError::Body {
        reason: e.to_string(),
    })
}

/// Age past which a serial sensor frame is refused, ms (the board answers every 50 ms period).
const STALE_FRAME_MS: u64 = 300;

fn chair_parts(name: &str, config: &SpawnConfig) -> Result<ChairParts, NodeError> {
    let body_err = |reason: String| NodeError::Body { reason };
    let [x, y, heading_deg] = config.body.start;
    let t_world_body = Isometry2::new(Vector2::new(x, y), heading_deg.to_radians());
    let serial = || {
        SerialBody::open(
            &config.body.port,
            config.body.baud,
            Duration::from_millis(config.body.timeout_ms),
        )
        .map_err(|e| body_err(format!("serial port `{}`: {e}", config.body.port)))
    };
    let (body, world) = match config.body.kind {
        BodyKind::Serial => (SharedBody::new(off_the_control_path(serial()?)?), None),
        BodyKind::Virtual | BodyKind::Mixed => {
            let mut world = World::new(load_map(&config.world.map)?, config.world.seed);
            let kind = if config.body.kind == BodyKind::Virtual {
                ChairKind::Simulated
            } else {
                ChairKind::Tracked
            };
            let id = world.add_chair(ChairSpec::default(), t_world_body, kind);
            if let Some(what) = world.obstruction(id).map_err(|e| body_err(e.to_string()))? {
                return Err(NodeError::Config {
                    file: "body.start".into(),
                    reason: format!(
                        "{:?} puts the chair's footprint on {} of the map",
                        config.body.start,
                        world.describe(what)
                    ),
                });
            }
            let world = iw_sim::shared(world);
            let body = if config.body.kind == BodyKind::Virtual {
                SharedBody::new(VirtualBody::new(world.clone(), id))
            } else {
                let ghost = GhostSensors::new(world.clone(), id);
                SharedBody::new(MixedBody::new(
                    off_the_control_path(serial()?)?,
                    ghost,
                    Odometry::new(WheelGeometry::default(), t_world_body),
                ))
            };
            (body, Some(world))
        }
    };
    let setup = |reason: String| NodeError::Setup {
        container: name.into(),
        reason,
    };
    let start = Pose2 {
        x,
        y,
        theta: heading_deg.to_radians(),
    };
    let perception_id = AgentId::new(format!("perception@{name}"));
    let perception = PerceptionAgent::new(
        PerceptionConfig::prototype(AgentId::new(name), start),
        Box::new(body.clone()),
        None,
    )
    .map_err(|e| setup(e.to_string()))?;
    let control_config =
        ControlConfig::prototype(Some(perception_id.clone())).map_err(|e| setup(e.to_string()))?;
    let control = ControlAgent::new(control_config, Box::new(body.clone()))
        .map_err(|e| setup(e.to_string()))?;
    Ok(ChairParts {
        agents: vec![
            (perception_id, Box::new(perception)),
            (AgentId::new(format!("control@{name}")), Box::new(control)),
        ],
        world,
        body,
    })
}

fn service_agents(
    config: &SpawnConfig,
    roster: Roster,
    events: Sender<Event>,
) -> Result<Agents, NodeError> {
    let map_name = if config.world.map.is_empty() {
        "embedded sample building"
    } else {
        &config.world.map
    };
    let map = load_map(&config.world.map)?;
    let grid = iw_fleet::plan::raster(&map, |door| {
        map.doors.iter().any(|d| d.id == door && !d.open)
    })
    .map_err(|e| NodeError::Map {
        map: map_name.into(),
        reason: e.to_string(),
    })?
    .inflated(CLEARANCE_M);
    let goals = config
        .services
        .goals
        .iter()
        .map(|g| {
            let target = map
                .place(&g.place)
                .or_else(|| parse_point(&g.place))
                .ok_or_else(|| NodeError::Map {
                    map: map_name.into(),
                    reason: format!(
                        "goal of {}: `{}` is neither a place of the map nor `x,y` in metres",
                        g.chair, g.place
                    ),
                })?;
            Ok((g.chair.clone(), g.place.clone(), target))
        })
        .collect::<Result<Vec<_>, NodeError>>()?;
    let report_every = Duration::from_millis(config.services.pose_report_ms);
    let dispatcher = Dispatcher::new(grid, goals, roster, report_every, events);
    Ok(vec![(
        AgentId::new(format!("dispatcher@{SERVICES}")),
        Box::new(dispatcher),
    )])
}

/// `x,y` in metres, both finite.
fn parse_point(text: &str) -> Option<nalgebra::Point2<f64>> {
    let (x, y) = text.split_once(',')?;
    let (x, y) = (x.trim().parse::<f64>().ok()?, y.trim().parse::<f64>().ok()?);
    (x.is_finite() && y.is_finite()).then(|| nalgebra::Point2::new(x, y))
}

/// An agent of another container, as installed on this bus.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Installed {
    container: ContainerId,
    key: PublicKey,
    addr: PeerAddr,
}

/// One running container. See the crate docs.
pub struct Runtime {
    name: String,
    config: SpawnConfig,
    host: AgentHost,
    platform: Platform,
    container: Option<ContainerNode>,
    control_guard: Option<Arc<GuardedTransport>>,
    installed: BTreeMap<String, Installed>,
    roster: Roster,
    world: Option<SharedWorld>,
    body: Option<SharedBody>,
    events: Sender<Event>,
}

impl Runtime {
    /// Binds, registers and starts everything `config` asks for `role`; reports [`Event::Ready`].
    pub fn start(
        role: &Role,
        config: SpawnConfig,
        events: Sender<Event>,
    ) -> Result<Runtime, NodeError> {
        config.validate(role)?;
        let name = role.name().to_string();
        let setup = |reason: String| NodeError::Setup {
            container: name.clone(),
            reason,
        };
        let layers: LayerSet = config
            .security
            .layers
            .parse()
            .map_err(|e: iw_bus::BusError| NodeError::Config {
                file: "security.layers".into(),
                reason: e.to_string(),
            })?;
        let identity = Arc::new(load_identity(&config.security.identity_key)?);
        let control_key = load_control_key(&config.security.control_key)?;
        let roster: Roster = Arc::new(Mutex::new(BTreeSet::new()));
        let (agents, world, body) = match role {
            Role::Chair { name } => {
                let parts = chair_parts(name, &config)?;
                (parts.agents, parts.world, Some(parts.body))
            }
            Role::Services => (
                service_agents(&config, roster.clone(), events.clone())?,
                None,
                None,
            ),
        };

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
        let names: Vec<&str> = agents.iter().map(|(aid, _)| aid.name.as_str()).collect();
        for agent in &names {
            platform.register(agent, identity.public_key());
        }
        let node = iw_stack::Node {
            identity: identity.clone(),
            agents: names.iter().map(|a| a.to_string()).collect(),
        };
        let stack = platform.stack(&node, &StackConfig::with_layers(layers));
        let clock = Clock::system();
        let bus = Bus::start(stack, bus_transport, clock.clone(), BusConfig::default())
            .map_err(|e| setup(e.to_string()))?;
        let mut host = AgentHost::new(Arc::new(bus));
        let agent_names: Vec<String> = names.iter().map(|a| a.to_string()).collect();
        for (aid, agent) in agents {
            host.add(aid, agent).map_err(|e| setup(e.to_string()))?;
        }

        let id = match config.container.id {
            0 => derived_id(role),
            id => id,
        };
        let incarnation = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as u32);
        let container_config = ContainerConfig {
            incarnation,
            heartbeat_ms: config.container.heartbeat_ms,
            lease_ms: config.container.lease_ms,
            ..ContainerConfig::new(ContainerId(id), PeerAddr(control_listen), seeds)
        };
        let mut container = Container::new(container_config);
        for agent in &agent_names {
            container.register(AgentEntry {
                name: agent.clone(),
                public_key: identity.public_key().to_vec(),
                addr: PeerAddr(advertise.clone()),
            });
        }
        let control_guard = match control_key {
            Some(key) => Some(Arc::new(
                GuardedTransport::new(
                    control_transport.clone(),
                    &format!("container-{id}.{incarnation}"),
                    key,
                    clock.clone(),
                )
                .map_err(|e| setup(e.to_string()))?,
            )),
            None => None,
        };
        let control_transport: Arc<dyn FrameTransport> = match &control_guard {
            Some(guard) => guard.clone(),
            None => control_transport,
        };
        let container = ContainerNode::start(container, control_transport, clock, CONTROL_TICK)
            .map_err(|e| setup(e.to_string()))?;
        // a closed receiver only means nobody is listening to reports
        let _ = events.send(Event::Ready {
            container: name.clone(),
            id,
            bus: advertise,
            agents: agent_names,
        });
        Ok(Runtime {
            name,
            config,
            host,
            platform,
            container: Some(container),
            control_guard,
            installed: BTreeMap::new(),
            roster,
            world,
            body,
            events,
        })
    }

    /// Steps the agents (and a virtual body's world) every `container.step_ms` of real time until
    /// `stop` is set, then shuts down cleanly. Fails, after shutting down, if another live
    /// container holds this one's id.
    pub fn run(mut self, stop: &AtomicBool) -> Result<(), NodeError> {
        let period = Duration::from_millis(self.config.container.step_ms);
        let clock = self.host.bus().clock().clone();
        let mut last = clock.now();
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
            self.sync_agent_lists();
            self.host.step(now);
            if let Some(world) = &self.world {
                let dt_s = now.since(last).as_secs_f64().min(MAX_SIM_STEP_S);
                iw_sim::step(
                    &mut world.lock().unwrap_or_else(PoisonError::into_inner),
                    dt_s,
                );
            }
            last = now;
            std::thread::sleep(period.saturating_sub(clock.now().since(now)));
        }
        self.shutdown();
        Ok(())
    }

    /// Routes and trusts exactly the other containers' agents the GAL lists under a live
    /// container; reports who joined and who left.
    fn sync_agent_lists(&mut self) {
        let Some(container) = &self.container else {
            return;
        };
        let present: BTreeMap<String, Installed> = container.with(|c| {
            let live = c.live_peers();
            c.gal()
                .entries()
                .filter(|(id, _)| live.contains(id))
                .filter_map(|(id, e)| {
                    let key = <PublicKey>::try_from(e.public_key.as_slice()).ok()?;
                    Some((
                        e.name.clone(),
                        Installed {
                            container: id,
                            key,
                            addr: e.addr.clone(),
                        },
                    ))
                })
                .collect()
        });
        let bus = self.host.bus().clone();
        let gone: Vec<(String, Installed)> = self
            .installed
            .iter()
            .filter(|(name, was)| present.get(*name) != Some(was))
            .map(|(n, w)| (n.clone(), w.clone()))
            .collect();
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
        *self.roster.lock().unwrap_or_else(PoisonError::into_inner) =
            self.installed.keys().cloned().collect();
    }

    /// Sends a `security` event if the rejection counts changed since `reported`.
    fn report_security(&self, reported: &mut (iw_bus::Counters, iw_bus::Counters)) {
        let bus = self.host.bus().counters();
        let control = self
            .control_guard
            .as_ref()
            .map(|g| g.counters())
            .unwrap_or_default();
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
        let now = self.host.bus().clock().now();
        self.host.shutdown(now);
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
            std::thread::sleep(Duration::from_millis(
                self.config.container.shutdown_grace_ms,
            ));
            container.stop();
        }
        let _ = self.events.send(Event::Stopped {
            container: self.name.clone(),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_start_pose_on_a_wall_is_refused_with_the_key() {
        let mut config = SpawnConfig::default();
        // On the sample building's wall from (0, 7) to (1.4, 7).
        config.body.start = [0.7, 7.0, 0.0];
        let err = chair_parts("chair-a", &config)
            .err()
            .expect("a start pose on a wall is refused")
            .to_string();
        assert!(
            err.contains("body.start") && err.contains("a wall"),
            "{err}"
        );
        config.body.start = SpawnConfig::default().body.start;
        assert!(chair_parts("chair-a", &config).is_ok());
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
        assert!(
            load_control_key(missing.to_str().unwrap())
                .unwrap_err()
                .to_string()
                .contains("missing.key")
        );
    }
}
