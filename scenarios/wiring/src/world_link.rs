//! The shared world of a deployment as a server (thesis 3.3, 3.5): the world container's
//! [`WorldAgent`] owns the one simulator; a chair's container reaches it over the platform,
//! with the same bus, layers and keys as any other traffic, through the endpoint `body@CHAIR`.
//!
//! - A virtual chair's [`WorldBody`] sends wheel speeds and reads back the sensor frames the
//!   world sends every period: encoders, sonars and the laser, so its localizer matches the map
//!   as an in-process chair's does.
//! - A mixed chair's [`WorldGhost`] reports the real chair's pose and returns the virtual sonar
//!   readings there (other chairs, virtual obstacles, doors); a real chair's ghost only reports.
//! - The door agent moves the world's doors through [`WorldDoors`].
//!
//! Faults: a body whose laser the world blinds or whose laser or sonars it fails
//! ([`WorldAgent::sensor_faults`], a scenario's `laser-blind` and `sensor-failure` played across
//! processes) gets frames with no laser ranges, or garbage for that sensor's readings, while the
//! rest reads on, as a covered or broken sensor gives them. A simulated body the world hears no wheel command from for [`WORLD_WATCHDOG`] is
//! stopped there; a body that hears no frame for [`LINK_TIMEOUT`] fails its reads (the control
//! agent stops the chair) and asks to attach again every [`ATTACH_EVERY`], where it last was, so
//! chairs re-attach to a restarted world; encoder ticks continue across the restart. A virtual
//! chair's only faults are such outages: its control agent holds the task in flight through one
//! of up to [`REATTACH_WAIT`] (wheels stopped) and carries it on from rest once frames come
//! again, and fails it with the link's reason past that. While the link is down a stop that
//! cannot be sent is taken: the world's watchdog stops a body it does not hear from, and a
//! restarted world attaches it at rest.
//! Body-world traffic is sensor data, not agent conversation: it is not copied to the logger.
//!
//! Lockstep (for tests, [`WorldAgent::lockstep`] and [`WorldBody::lockstep`]): the world steps
//! by exactly [`WORLD_PERIOD`] of simulated time, and only once every simulated body it hears
//! from (within [`LINK_TIMEOUT`]) has sent wheel speeds since the last step. While it waits,
//! simulated time stands still and every period the bodies get their current frame again (so
//! their links stay up); a body silent past [`LINK_TIMEOUT`] is no longer waited for, and is
//! stopped (the watchdog of a lockstep world; a live body waited for cannot move). A lockstep
//! body sends one wheel command per world step, the first after that step's frame: the command
//! computed from it (a frame sent again while the world waits is not answered again). So the world's trajectory depends only on the seed, on when each body
//! attached (in steps) and on what each body commanded at each step, not on when the messages
//! came or how loaded the host is. The chairs' own agents still run on their own clocks: a
//! deployment's agents are not made reproducible by this.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_body::{BodyError, SONAR_COUNT, SensorFrame, VirtualSensors, WheelSpeeds};
use iw_bus::{Bus, BusError, Mailbox, Time};
use iw_door::{ActuatorFault, DoorActuator};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::Pose;
use iw_ontology::world::{BodyFrame, BodyLink, WorldContent};
use iw_sim::{ChairId, ChairKind, ChairSpec, SharedWorld};
use nalgebra::{Isometry2, Matrix3, Vector2};

use crate::{StartError, WiringError, agent_id};

/// The world container's name.
pub const WORLD: &str = "world";

/// A simulated body with no wheel command for this long is stopped by the world.
pub const WORLD_WATCHDOG: Duration = Duration::from_millis(300);

/// A body with no frame from the world for this long fails its reads.
pub const LINK_TIMEOUT: Duration = Duration::from_millis(500);

/// How often a body without a world asks to attach (while the world is routed).
pub const ATTACH_EVERY: Duration = Duration::from_millis(500);

/// The world's period: it steps and sends every body its frame this often.
pub const WORLD_PERIOD: Duration = Duration::from_millis(50);

/// How long a virtual chair's task waits for its world to come back (a world container
/// restarted, a partition healed) before it fails: process start-up plus joining, with room for
/// a loaded host. The default of a chair container's `body.reattach_wait_ms`.
pub const REATTACH_WAIT: Duration = Duration::from_secs(30);

/// A frame this far behind the last one (world time, ns) comes from a restarted world.
const RESTART_BACK_NS: u64 = 1_000_000_000;

/// Longest simulated step after a stall, s (the simulator never leaps).
const MAX_STEP_S: f64 = 0.2;

/// The world agent's name.
pub fn world_agent() -> AgentId {
    agent_id("world", WORLD)
}

/// The endpoint of chair `chair`'s body on its container's bus.
pub fn body_endpoint(chair: &str) -> AgentId {
    agent_id("body", chair)
}

fn pose_of(t_world_body: &Isometry2<f64>) -> Pose {
    Pose {
        x_m: t_world_body.translation.x,
        y_m: t_world_body.translation.y,
        theta_rad: t_world_body.rotation.angle(),
        covariance: Matrix3::zeros(),
    }
}

/// The bus could not carry a message to the world: the bus's error stays the source.
fn unreachable(e: BusError) -> BodyError {
    BodyError::World {
        what: "world unreachable",
        source: Box::new(e),
    }
}

/// One chair's end of the world link: its mailbox, the last frame and the attach state.
pub struct WorldLink {
    bus: Arc<Bus>,
    mailbox: Mailbox,
    chair: String,
    link: BodyLink,
    /// Where the body was last (start, then the world's frames or the real chair's reports).
    t_world_body: Isometry2<f64>,
    /// The last frame, ticks already continued, and when it arrived.
    latest: Option<(BodyFrame, Time)>,
    /// Added to the world's ticks so they continue across a world restart.
    tick_offset: (i64, i64),
    last_attach: Option<Time>,
    /// Whether the last send failed (one warning per outage).
    failing: bool,
    /// The body's true pose in the last frame (a simulated body), for its camera.
    truth: TruePose,
    /// Lockstep: send one wheel command per frame.
    lockstep: bool,
    /// The world time (ns) of the frame the last wheel command answered.
    answered: Option<u64>,
}

/// A simulated body's true pose in the world as its last sensor frame gave it, with the frame's
/// local arrival time (ns, the time the body's reads carry; `None` before the first): what a
/// chair container renders its camera from, stamped with that time (`crate::camera`).
pub type TruePose = Arc<std::sync::Mutex<Option<(u64, Isometry2<f64>)>>>;

impl WorldLink {
    /// Opens `body@CHAIR` on `bus` for chair `chair` starting at `t_world_body`.
    pub fn open(
        bus: Arc<Bus>,
        chair: &str,
        link: BodyLink,
        t_world_body: Isometry2<f64>,
    ) -> Result<WorldLink, WiringError> {
        let mailbox = bus.register(&body_endpoint(chair).name).map_err(|e| {
            WiringError::Start(StartError {
                container: chair.into(),
                what: "world link endpoint".into(),
                source: e.into(),
            })
        })?;
        Ok(WorldLink {
            bus,
            mailbox,
            chair: chair.into(),
            link,
            t_world_body,
            latest: None,
            tick_offset: (0, 0),
            last_attach: None,
            failing: false,
            truth: TruePose::default(),
            lockstep: false,
            answered: None,
        })
    }

    fn send(&mut self, content: &WorldContent) -> Result<(), BusError> {
        let world = world_agent();
        let message = content.fill(
            AclMessage::new(Performative::Inform)
                .with_sender(body_endpoint(&self.chair))
                .with_receiver(world.clone()),
        );
        let sent = self.bus.send(
            &body_endpoint(&self.chair).name,
            &world.name,
            iw_acl::codec::print(&message).into_bytes(),
        );
        match sent {
            Ok(_) => {
                self.failing = false;
                Ok(())
            }
            Err(e) => {
                if !self.failing {
                    tracing::warn!(chair = %self.chair, error = %e, "world unreachable");
                }
                self.failing = true;
                Err(e)
            }
        }
    }

    /// Takes what the world sent; asks to attach when the link is down and it is time.
    fn poll(&mut self) {
        let now = self.bus.clock().now();
        while let Some(envelope) = self.mailbox.try_recv() {
            let Some(Ok(message)) = envelope.payload_str().map(iw_acl::codec::parse) else {
                continue;
            };
            if envelope.header.sender != world_agent().name {
                continue;
            }
            let Ok(WorldContent::SensorFrame { chair, mut frame }) =
                WorldContent::from_message(&message)
            else {
                continue;
            };
            if chair != self.chair {
                continue;
            }
            // A world's clock restarts with it: a frame well behind the last one is from a new
            // world (even one back within the link timeout); one just behind is a late frame.
            let behind = self
                .latest
                .as_ref()
                .map(|(last, _)| last.time_ns.saturating_sub(frame.time_ns));
            let restarted = behind.is_some_and(|ns| ns > RESTART_BACK_NS);
            if behind.is_some_and(|ns| ns > 0) && !restarted && self.fresh(now) {
                continue;
            }
            // After a silence, a frame whose world time did not go on is from a new world: a
            // new attachment, whose ticks continue from where they were. One whose time went on
            // is the same world after a stall (its process or the link late): its ticks go on as
            // they are, since its first step after the stall moved the body (up to
            // MAX_STEP_S of driving) and the scans show it; rebased, that motion was lost to
            // the odometry, every scan then missed the estimate by it (10 cm in a
            // `sonar-garbage` run across processes) and the chair was taken for lost.
            // Assumption: a restarted world has run for less time than the one it replaces when
            // its first frame comes.
            let new_world = restarted || (!self.fresh(now) && behind.is_some_and(|ns| ns > 0));
            if new_world {
                // a new attachment: continue the ticks from where they were
                if let Some((last, _)) = &self.latest {
                    self.tick_offset = (
                        last.left_ticks - frame.left_ticks,
                        last.right_ticks - frame.right_ticks,
                    );
                }
            }
            frame.left_ticks += self.tick_offset.0;
            frame.right_ticks += self.tick_offset.1;
            if self.link == BodyLink::Simulated {
                self.t_world_body = frame.pose.t_map_base();
                *self
                    .truth
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner) =
                    Some((now.as_ns(), self.t_world_body));
            }
            self.latest = Some((frame, now));
        }
        let due = self
            .last_attach
            .is_none_or(|last| now >= last.plus(ATTACH_EVERY));
        if !self.fresh(now) && due {
            let attach = WorldContent::Attach {
                chair: self.chair.clone(),
                link: self.link,
                pose: pose_of(&self.t_world_body),
            };
            // not sent (no route to the world yet): try again at the next read
            if self.send(&attach).is_ok() {
                self.last_attach = Some(now);
            }
        }
    }

    fn fresh(&self, now: Time) -> bool {
        self.latest
            .as_ref()
            .is_some_and(|(_, at)| now.since(*at) <= LINK_TIMEOUT)
    }

    /// The last frame as the body's sensor frame, if the link is up.
    fn frame(&mut self) -> Result<SensorFrame, BodyError> {
        self.poll();
        let now = self.bus.clock().now();
        if !self.fresh(now) {
            let silent = match &self.latest {
                Some((_, at)) => format!("for {} ms", now.since(*at).as_millis()),
                None => "yet".to_string(),
            };
            return Err(BodyError::Virtual {
                reason: format!(
                    "no sensor frame from the world {silent}: link down, attaching again every {} ms",
                    ATTACH_EVERY.as_millis()
                ),
            });
        }
        let (frame, at) = self.latest.as_ref().expect("fresh implies a frame");
        let mut sonar_m = [None; SONAR_COUNT];
        for (out, r) in sonar_m.iter_mut().zip(&frame.sonar_m) {
            *out = *r;
        }
        Ok(SensorFrame {
            // local time of arrival: the world's clock restarts with the world
            time_ns: at.0,
            left_ticks: frame.left_ticks,
            right_ticks: frame.right_ticks,
            sonar_m,
            laser_m: frame.laser_m.clone(),
            // the world steps and senses a simulated body together
            ranges_time_ns: at.0,
            // the world's own steps, which are not the chair's reads (see the field)
            ticks_time_ns: frame.time_ns,
        })
    }
}

/// A virtual chair's body in the world container.
pub struct WorldBody(WorldLink);

impl WorldBody {
    /// The body of virtual chair `chair` on `bus`, starting at `t_world_body`.
    pub fn open(
        bus: Arc<Bus>,
        chair: &str,
        t_world_body: Isometry2<f64>,
    ) -> Result<WorldBody, WiringError> {
        WorldLink::open(bus, chair, BodyLink::Simulated, t_world_body).map(WorldBody)
    }

    /// Where the world has the body, updated with each frame (for the chair's camera).
    pub fn true_pose(&self) -> TruePose {
        self.0.truth.clone()
    }

    /// For a lockstep world: one wheel command per world step, the first after its frame (later
    /// ones for the same step are taken and not sent; the world holds the first until it steps).
    pub fn lockstep(mut self, on: bool) -> Self {
        self.0.lockstep = on;
        self
    }
}

impl iw_body::Body for WorldBody {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        self.0.frame()
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        let frame = self.0.latest.as_ref().map(|(frame, _)| frame.time_ns);
        if self.0.lockstep {
            if frame.is_some() && frame == self.0.answered {
                return Ok(());
            }
            self.0.answered = frame;
        }
        let content = WorldContent::WheelSpeeds {
            chair: self.0.chair.clone(),
            left_mps: speeds.left_mps,
            right_mps: speeds.right_mps,
        };
        match self.0.send(&content) {
            // No world hears this body: its watchdog stops the body (or the world is gone, and
            // the next one attaches it at rest), so the stop holds.
            Err(_) if speeds == WheelSpeeds::STOP && !self.0.fresh(self.0.bus.clock().now()) => {
                Ok(())
            }
            sent => sent.map_err(unreachable),
        }
    }
}

/// A real chair's ghost in the world: reports the chair's pose; `senses` (mixed reality) also
/// returns the virtual readings there, and fails while the world is unreachable.
///
/// The world senses the ghost where it was last placed, at its next step, and the answer comes
/// back a message later: the readings a read returns were taken where the chair was one or more
/// reads before (one or two periods in `mixed-reality` run as processes, more when the host is
/// loaded). Matched as if taken now, they pulled the estimate back along the motion and, in a
/// turn, off in heading, until the scans stopped fitting and the chair was taken for lost. The
/// world's frame carries the pose it sensed at, so the ghost finds the read that reported that
/// pose and stamps the readings with its time ([`SensorFrame::ranges_time_ns`]); a frame it
/// already returned keeps its stamp, so it is not taken for a new scan.
pub struct WorldGhost {
    link: WorldLink,
    senses: bool,
    /// The last reports: the caller's time and the pose sent then, oldest first.
    reported: VecDeque<(u64, Isometry2<f64>)>,
    /// The world time of the last frame returned, and the stamp it was given.
    stamped: Option<(u64, u64)>,
}

/// Reports a ghost remembers to stamp its readings: 40 reads, longer than [`LINK_TIMEOUT`] at
/// the 20 reads a second of a chair's agents.
const GHOST_REPORTS: usize = 40;

/// A world frame's pose matches a report within this (m, rad): the pose goes out and comes
/// back as decimal text of the same doubles.
const SAME_POSE: f64 = 1e-6;

impl WorldGhost {
    /// The ghost of real chair `chair` on `bus`; `senses`: a mixed chair.
    pub fn open(
        bus: Arc<Bus>,
        chair: &str,
        t_world_body: Isometry2<f64>,
        senses: bool,
    ) -> Result<WorldGhost, WiringError> {
        let link = WorldLink::open(bus, chair, BodyLink::Tracked, t_world_body)?;
        Ok(WorldGhost {
            link,
            senses,
            reported: VecDeque::with_capacity(GHOST_REPORTS),
            stamped: None,
        })
    }

    /// When (the caller's time) the ghost was reported where the world sensed it: the latest
    /// report of that pose (a chair that stands reports it many times; the latest is the
    /// shortest lag), `None` when none of the remembered reports placed it there.
    fn reported_at(&self, sensed: &Isometry2<f64>) -> Option<u64> {
        self.reported.iter().rev().find_map(|(time_ns, pose)| {
            let apart = (pose.translation.vector - sensed.translation.vector).norm();
            let turned = pose.rotation.angle_to(&sensed.rotation).abs();
            (apart <= SAME_POSE && turned <= SAME_POSE).then_some(*time_ns)
        })
    }
}

impl VirtualSensors for WorldGhost {
    fn sense_at(
        &mut self,
        t_world_body: Isometry2<f64>,
        time_ns: u64,
    ) -> Result<SensorFrame, BodyError> {
        self.link.t_world_body = t_world_body;
        let report = WorldContent::BodyPose {
            chair: self.link.chair.clone(),
            pose: pose_of(&t_world_body),
        };
        let sent = self.link.send(&report);
        if !self.senses {
            // a real chair drives on its own sensors, world or not
            self.link.poll();
            return Ok(SensorFrame::empty(time_ns));
        }
        sent.map_err(unreachable)?;
        if self.reported.len() == GHOST_REPORTS {
            self.reported.pop_front();
        }
        self.reported.push_back((time_ns, t_world_body));
        let frame = self.link.frame()?;
        let Some((world_ns, sensed)) = self
            .link
            .latest
            .as_ref()
            .map(|(f, _)| (f.time_ns, f.pose.t_map_base()))
        else {
            return Ok(SensorFrame {
                time_ns,
                ranges_time_ns: time_ns,
                ..frame
            });
        };
        let ranges_time_ns = match self.stamped {
            Some((last_ns, stamp)) if last_ns == world_ns => stamp,
            // Assumption: a pose none of the remembered reports placed (a restarted world that
            // attached the ghost where it last was) is taken as sensed now.
            _ => self.reported_at(&sensed).unwrap_or(time_ns),
        };
        self.stamped = Some((world_ns, ranges_time_ns));
        Ok(SensorFrame {
            time_ns,
            ranges_time_ns,
            ..frame
        })
    }
}

/// The door agent's actuator when the doors are the world's: each move is sent to the world
/// (a world that is unreachable faults the move).
pub struct WorldDoors {
    bus: Arc<Bus>,
    /// The door agent's name (the sender).
    door_agent: AgentId,
    /// The door agent's door names to map door ids.
    ids: BTreeMap<String, String>,
}

impl WorldDoors {
    /// Moves the doors of `ids` (door agent name to map door id) for `door_agent` over `bus`.
    pub fn new(bus: Arc<Bus>, door_agent: AgentId, ids: BTreeMap<String, String>) -> Self {
        WorldDoors {
            bus,
            door_agent,
            ids,
        }
    }
}

impl DoorActuator for WorldDoors {
    fn set(&mut self, door: &str, open: bool) -> Result<(), ActuatorFault> {
        let id = crate::map_door(&self.ids, door)?;
        let world = world_agent();
        let message = WorldContent::Door {
            door: id.clone(),
            open,
        }
        .fill(
            AclMessage::new(Performative::Request)
                .with_sender(self.door_agent.clone())
                .with_receiver(world.clone()),
        );
        self.bus
            .send(
                &self.door_agent.name,
                &world.name,
                iw_acl::codec::print(&message).into_bytes(),
            )
            .map(drop)
            .map_err(|e| ActuatorFault::caused(door, "world unreachable", e))
    }
}

/// The bodies in the world by chair name, shared with whoever reports on the world.
pub type BodyRoster = Arc<std::sync::Mutex<BTreeMap<String, ChairId>>>;

/// A sensor a scenario's `sensor-failure` fails.
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum FailedSensor {
    /// Every read of the body fails. No frame can say so: across processes a world that sends a
    /// chair nothing is an outage the chair waits out, so only an in-process body plays it.
    #[default]
    All,
    /// The laser returns garbage: every beam at [`GARBAGE_RANGE_M`].
    Laser,
    /// The sonars return garbage: every transducer at [`GARBAGE_RANGE_M`].
    Sonars,
}

impl std::fmt::Display for FailedSensor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            FailedSensor::All => "all",
            FailedSensor::Laser => "laser",
            FailedSensor::Sonars => "sonars",
        })
    }
}

/// What a failed range sensor returns for every reading: past any range the chair's sensors
/// read (a scanner's error codes lie above 65.5 m), so the localizer counts it as garbage, and
/// finite, so it crosses the world link as a reading does.
pub const GARBAGE_RANGE_M: f64 = 65.533;

/// What is wrong with a chair's range sensors: the same faults in process (the fleet's body
/// wrapper) and in the frames a world container sends.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameFaults {
    /// The laser returns no ranges (covered).
    pub laser_blind: bool,
    /// The laser returns garbage.
    pub laser_garbage: bool,
    /// The sonars return garbage.
    pub sonar_garbage: bool,
}

impl FrameFaults {
    /// Whether nothing is wrong.
    pub fn none(&self) -> bool {
        *self == FrameFaults::default()
    }

    /// Sets (`on`) or clears the garbage of `sensor` (`All` is not a frame fault: ignored).
    pub fn set_garbage(&mut self, sensor: FailedSensor, on: bool) {
        match sensor {
            FailedSensor::All => {}
            FailedSensor::Laser => self.laser_garbage = on,
            FailedSensor::Sonars => self.sonar_garbage = on,
        }
    }

    /// Applies the faults to one frame's readings (a blind laser gives nothing, garbage or not).
    pub fn apply(&self, laser_m: &mut Vec<f64>, sonar_m: &mut [Option<f64>]) {
        if self.laser_garbage {
            laser_m.fill(GARBAGE_RANGE_M);
        }
        if self.sonar_garbage {
            sonar_m.fill(Some(GARBAGE_RANGE_M));
        }
        if self.laser_blind {
            laser_m.clear();
        }
    }
}

/// The faults of the chairs' sensors the world plays in the frames it sends, by chair (a chair
/// with none is absent). Shared with whoever plays them (a scenario's `laser-blind` and
/// `sensor-failure` across processes).
pub type WorldFaults = Arc<std::sync::Mutex<BTreeMap<String, FrameFaults>>>;

/// One body in the world.
struct Attached {
    id: ChairId,
    link: BodyLink,
    /// When its chair last sent anything (attach, wheel speeds, pose).
    last_heard: Time,
    /// Whether it sent wheel speeds since the last step (lockstep waits for every body's).
    commanded: bool,
}

/// The world container's agent: the simulator, stepped in real time (or in lockstep with its
/// bodies), its bodies driven and placed by their chairs' links, its doors moved by the door
/// agent.
pub struct WorldAgent {
    world: SharedWorld,
    bodies: BTreeMap<String, Attached>,
    roster: BodyRoster,
    faults: WorldFaults,
    last_step: Option<Time>,
    door_agent: AgentId,
    lockstep: bool,
}

impl WorldAgent {
    /// Serves `world`; doors move only at the request of `door_agent`.
    pub fn new(world: SharedWorld, door_agent: AgentId) -> Self {
        WorldAgent {
            world,
            bodies: BTreeMap::new(),
            roster: BodyRoster::default(),
            faults: WorldFaults::default(),
            last_step: None,
            door_agent,
            lockstep: false,
        }
    }

    /// Steps in lockstep with the simulated bodies (see the module docs) instead of in real
    /// time.
    pub fn lockstep(mut self, on: bool) -> Self {
        self.lockstep = on;
        self
    }

    /// Lockstep: whether every simulated body still heard from has sent wheel speeds since the
    /// last step (with no such body: always, the world then steps every period).
    fn all_commanded(&self, now: Time) -> bool {
        self.bodies
            .values()
            .filter(|b| b.link == BodyLink::Simulated && now.since(b.last_heard) <= LINK_TIMEOUT)
            .all(|b| b.commanded)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, iw_sim::World> {
        self.world
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn on_body(&mut self, now: Time, content: WorldContent) -> Result<(), Refused> {
        match content {
            WorldContent::Attach { chair, link, pose } => {
                if let Some(body) = self.bodies.get_mut(&chair) {
                    if body.link != link {
                        return Err(Refused::Link(format!(
                            "chair `{chair}` is attached with another link"
                        )));
                    }
                    body.last_heard = now;
                    return Ok(());
                }
                let kind = match link {
                    BodyLink::Simulated => ChairKind::Simulated,
                    BodyLink::Tracked => ChairKind::Tracked,
                };
                let t_world_body = Isometry2::new(Vector2::new(pose.x_m, pose.y_m), pose.theta_rad);
                let id = self
                    .lock()
                    .add_chair(ChairSpec::default(), t_world_body, kind);
                tracing::info!(%chair, ?link, x = pose.x_m, y = pose.y_m, "body attached");
                self.roster
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .insert(chair.clone(), id);
                self.bodies.insert(
                    chair,
                    Attached {
                        id,
                        link,
                        last_heard: now,
                        commanded: false,
                    },
                );
                Ok(())
            }
            WorldContent::WheelSpeeds {
                chair,
                left_mps,
                right_mps,
            } => {
                let body = self
                    .bodies
                    .get_mut(&chair)
                    .ok_or_else(|| Refused::Link("not attached".into()))?;
                if body.link != BodyLink::Simulated {
                    return Err(Refused::Link("a tracked body is placed, not driven".into()));
                }
                body.last_heard = now;
                body.commanded = true;
                let id = body.id;
                self.lock()
                    .command(
                        id,
                        WheelSpeeds {
                            left_mps,
                            right_mps,
                        },
                    )
                    .map_err(Refused::World)
            }
            WorldContent::BodyPose { chair, pose } => {
                let body = self
                    .bodies
                    .get_mut(&chair)
                    .ok_or_else(|| Refused::Link("not attached".into()))?;
                if body.link != BodyLink::Tracked {
                    return Err(Refused::Link(
                        "a simulated body is driven, not placed".into(),
                    ));
                }
                body.last_heard = now;
                let id = body.id;
                self.lock()
                    .place(id, pose.t_map_base())
                    .map_err(Refused::World)
            }
            _ => Err(Refused::Link("not something a body sends".into())),
        }
    }

    /// Stops simulated bodies whose chairs went quiet, steps the world (`advance`) by the real
    /// time since the last step (lockstep: by [`WORLD_PERIOD`]), and sends every body its frame.
    fn step(&mut self, ctx: &mut Context<'_>, advance: bool) {
        let now = ctx.now();
        let dt_s = match self.last_step {
            _ if !advance => 0.0,
            _ if self.lockstep => WORLD_PERIOD.as_secs_f64(),
            Some(last) => now.since(last).as_secs_f64().min(MAX_STEP_S),
            None => 0.0,
        };
        if advance {
            self.last_step = Some(now);
            for body in self.bodies.values_mut() {
                body.commanded = false;
            }
        }
        let watchdog = if self.lockstep {
            LINK_TIMEOUT
        } else {
            WORLD_WATCHDOG
        };
        let faults = self
            .faults
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone();
        let frames: Vec<(String, BodyFrame)> = {
            let mut world = self.lock();
            for body in self.bodies.values() {
                if body.link == BodyLink::Simulated && now.since(body.last_heard) > watchdog {
                    let _ = world.command(body.id, WheelSpeeds::STOP);
                }
            }
            if dt_s > 0.0 {
                iw_sim::step(&mut world, dt_s);
            }
            self.bodies
                .iter()
                // a chair gone quiet (its process killed) gets no frames until it attaches again
                .filter(|(_, body)| now.since(body.last_heard) <= LINK_TIMEOUT)
                .filter_map(|(chair, body)| {
                    let sensed = world.sensors(body.id).ok()?;
                    let pose = world.pose(body.id).ok()?;
                    let mut sonar_m = sensed.sonar_m.to_vec();
                    let mut laser_m = sensed.laser_m.clone();
                    if let Some(f) = faults.get(chair) {
                        f.apply(&mut laser_m, &mut sonar_m);
                    }
                    Some((
                        chair.clone(),
                        BodyFrame {
                            time_ns: sensed.time_ns,
                            left_ticks: sensed.left_ticks,
                            right_ticks: sensed.right_ticks,
                            sonar_m,
                            laser_m,
                            pose: pose_of(&pose),
                        },
                    ))
                })
                .collect()
        };
        for (chair, frame) in frames {
            let to = body_endpoint(&chair);
            let message = WorldContent::SensorFrame { chair, frame }
                .fill(AclMessage::new(Performative::Inform).with_receiver(to));
            // a chair that is gone stays in the world where it stopped
            let _ = ctx.send(message);
        }
    }

    /// The world and its bodies by chair, for reports.
    pub fn reports(&self) -> (SharedWorld, BodyRoster) {
        (self.world.clone(), self.roster.clone())
    }

    /// The faults of the chairs' sensors: what is set for a chair applies from its next frame
    /// on.
    pub fn sensor_faults(&self) -> WorldFaults {
        self.faults.clone()
    }
}

/// Why the world agent did not act on a body's or the door agent's message (it is logged).
#[derive(Debug, thiserror::Error)]
enum Refused {
    /// The message does not fit the sender or the body's link.
    #[error("{0}")]
    Link(String),
    /// The simulator refused it (an unknown chair or door, a blocked door).
    #[error("the simulator: {0}")]
    World(#[source] iw_sim::SimError),
}

impl Agent for WorldAgent {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let sender = message
            .sender
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default();
        let content = match WorldContent::from_message(&message) {
            Ok(content) => content,
            Err(e) => {
                let _ = ctx.not_understood(&message, &e.to_string());
                return;
            }
        };
        if let WorldContent::Door { door, open } = &content {
            let answer = if sender != self.door_agent.name {
                Err(Refused::Link(format!(
                    "only {} moves doors",
                    self.door_agent.name
                )))
            } else {
                self.lock().set_door(door, *open).map_err(Refused::World)
            };
            if let Err(reason) = answer {
                tracing::warn!(%door, %reason, "door not moved");
            }
            return;
        }
        let chair = match &content {
            WorldContent::Attach { chair, .. }
            | WorldContent::WheelSpeeds { chair, .. }
            | WorldContent::BodyPose { chair, .. }
            | WorldContent::SensorFrame { chair, .. } => chair.clone(),
            _ => return,
        };
        // a chair drives and places only its own body
        if sender != body_endpoint(&chair).name {
            tracing::warn!(%sender, %chair, "refused: not that chair's body");
            return;
        }
        let now = ctx.now();
        let wheels = matches!(content, WorldContent::WheelSpeeds { .. });
        if let Err(reason) = self.on_body(now, content) {
            tracing::debug!(%chair, %reason, "body message refused");
        }
        if self.lockstep && wheels && self.all_commanded(now) {
            self.step(ctx, true);
        }
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let advance = !self.lockstep || self.all_commanded(ctx.now());
        self.step(ctx, advance);
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(WORLD_PERIOD)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_agent::AgentHost;
    use iw_body::Body;
    use iw_bus::InProcNetwork;
    use iw_bus::transport::PeerAddr;
    use iw_bus::{BusConfig, Clock, Stack};

    /// A virtual chair drives its body in a world on another bus, over real frames: it attaches,
    /// moves, and stops when its commands stop coming.
    #[test]
    fn a_body_drives_in_a_world_on_another_bus() {
        let network = InProcNetwork::new();
        let clock = Clock::system();
        let bus = |name: &str| {
            let transport = network.endpoint(name).unwrap();
            Arc::new(
                Bus::start(
                    Stack::new(),
                    Arc::new(transport),
                    clock.clone(),
                    BusConfig::default(),
                )
                .unwrap(),
            )
        };
        let (world_bus, chair_bus) = (bus(WORLD), bus("c1"));
        world_bus.add_route(&body_endpoint("c1").name, PeerAddr("c1".into()));
        chair_bus.add_route(&world_agent().name, PeerAddr(WORLD.into()));
        let map = iw_sim::Map::parse(
            include_str!("../../maps/sample-building.map"),
            "sample-building.map",
        )
        .unwrap();
        let world = iw_sim::shared(iw_sim::World::new(map, 1));
        let mut host = AgentHost::new(world_bus);
        let agent = WorldAgent::new(world.clone(), agent_id("door", "services"));
        let (_, roster) = agent.reports();
        let faults = agent.sensor_faults();
        host.add(world_agent(), Box::new(agent)).unwrap();
        let start = Isometry2::new(Vector2::new(7.5, 6.0), 0.0);
        let mut body = WorldBody::open(chair_bus, "c1", start).unwrap();
        let deadline = std::time::Instant::now() + Duration::from_secs(20);
        let mut read = None;
        while read.is_none() {
            assert!(std::time::Instant::now() < deadline, "never attached");
            host.step(clock.now());
            read = body.read().ok();
            std::thread::sleep(Duration::from_millis(10));
        }
        let id = roster.lock().unwrap()["c1"];
        for _ in 0..100 {
            body.command(WheelSpeeds {
                left_mps: 0.3,
                right_mps: 0.3,
            })
            .unwrap();
            host.step(clock.now());
            std::thread::sleep(Duration::from_millis(10));
        }
        let moved = world.lock().unwrap().pose(id).unwrap();
        assert!(moved.translation.x > 7.6, "{moved}");
        let frame = body.read().unwrap();
        assert!(frame.left_ticks > 0);
        // the laser comes over the link: the localizer of a spawned chair matches the map with it
        let beams = ChairSpec::default().laser.unwrap().beams;
        assert_eq!(frame.laser_m.len(), beams);
        assert!(
            frame.laser_m.iter().any(|r| *r < 5.0),
            "{:?}",
            frame.laser_m
        );
        // the first frame (over the link) that `wanted` takes
        let until = |host: &mut AgentHost,
                     body: &mut WorldBody,
                     what: &str,
                     wanted: &dyn Fn(&SensorFrame) -> bool| {
            let sent_at = std::time::Instant::now();
            loop {
                host.step(clock.now());
                std::thread::sleep(Duration::from_millis(10));
                let frame = body.read().unwrap();
                if wanted(&frame) {
                    return frame;
                }
                assert!(sent_at.elapsed() < Duration::from_secs(20), "never {what}");
            }
        };
        let set = |f: FrameFaults| {
            let mut faults = faults.lock().unwrap();
            if f.none() {
                faults.remove("c1");
            } else {
                faults.insert("c1".into(), f);
            }
        };
        // a blinded laser: the frames come on (encoders and sonars), with no ranges, until the
        // laser is given back
        set(FrameFaults {
            laser_blind: true,
            ..FrameFaults::default()
        });
        let frame = until(&mut host, &mut body, "blind", &|f| f.laser_m.is_empty());
        assert!(frame.sonar_m.iter().any(Option::is_some), "{frame:?}");
        set(FrameFaults::default());
        let frame = until(&mut host, &mut body, "seeing", &|f| !f.laser_m.is_empty());
        assert_eq!(frame.laser_m.len(), beams);
        // a failed laser, then failed sonars: every reading of that sensor is garbage (past any
        // range, yet a number the link carries), the other sensor reads on
        let garbage = |r: f64| r == GARBAGE_RANGE_M;
        set(FrameFaults {
            laser_garbage: true,
            ..FrameFaults::default()
        });
        let frame = until(&mut host, &mut body, "laser garbage", &|f| {
            f.laser_m.first().is_some_and(|r| garbage(*r))
        });
        assert_eq!(frame.laser_m.len(), beams);
        assert!(frame.laser_m.iter().all(|r| garbage(*r)), "{frame:?}");
        assert!(
            frame.sonar_m.iter().flatten().all(|r| *r < 3.5),
            "{frame:?}"
        );
        set(FrameFaults {
            sonar_garbage: true,
            ..FrameFaults::default()
        });
        let frame = until(&mut host, &mut body, "sonar garbage", &|f| {
            f.sonar_m.iter().all(|r| r.is_some_and(garbage))
        });
        assert!(frame.laser_m.iter().any(|r| *r < 5.0), "{frame:?}");
        set(FrameFaults::default());
        until(&mut host, &mut body, "sonars back", &|f| {
            !f.sonar_m.iter().flatten().any(|r| garbage(*r))
        });
        // no more commands: the world's watchdog stops the body
        for _ in 0..60 {
            host.step(clock.now());
            std::thread::sleep(Duration::from_millis(10));
        }
        let twist = world.lock().unwrap().twist(id).unwrap();
        assert!(twist.0.abs() < 0.05, "{twist:?}");
    }
}
