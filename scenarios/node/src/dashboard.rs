//! The services container's dashboard (`[dashboard] listen`): `iw-dashboard`'s staff view and
//! chair views, fed from what the services learn over the bus rather than from a simulator:
//! - the chairs' poses and sonar ranges, which their perception agents publish to the staff
//!   console, and what shared control applied to a chair driven by hand, which its control
//!   agent tells the console;
//! - the goals given and their answers, and the drive panel's commands and their answers;
//! - the Global Agent List (the containers and their agents);
//! - every message the containers' agents exchange, read off the copies each container sends
//!   the logger;
//! - the doors as the door agent moved them, and its refusals;
//! - the frames this container's platform refused, per reason (the `security` event's counts).
//!
//! The page's asks go back on the bus: a goal through the assistant (as a configured goal), a
//! drive panel input mapped as the chair's interface agent maps a device and relayed by the
//! staff console to that interface agent. The door, fault and pause buttons belong to the
//! in-process demo: here they get a notice saying so.

use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::AclMessage;
use iw_agent::{Agent, Context};
use iw_bus::Time;
use iw_dashboard::{
    ChairDisplay, ChairView, ContainerView, Dashboard, DashboardConfig, MessageView, PageAction,
    State, round_cm,
};
use iw_door::{ActuatorFault, DoorActuator, RefusalLog};
use iw_interface::DriveMapping;
use iw_wiring::{Building, SharedDesk};

use crate::config::DashboardSection;
use crate::{NodeError, SERVICES};

/// How often the page gets a new state.
const PUBLISH_EVERY: Duration = Duration::from_millis(100);
/// How long a chair's applied command is shown after its control agent last told it (it tells
/// every control period while driven by hand).
const APPLIED_FOR: Duration = Duration::from_millis(500);
/// Messages kept for the sniffer.
const RECENT: usize = 40;
/// Notices kept.
const NOTICES: usize = 20;

/// The messages seen so far.
#[derive(Debug, Default)]
struct Traffic {
    recent: VecDeque<MessageView>,
    count: u64,
}

type SharedTraffic = Arc<Mutex<Traffic>>;

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The logger agent, with every copy it is sent read for the sniffer on the way in.
struct Sniffed {
    logger: Box<dyn Agent>,
    traffic: SharedTraffic,
}

impl Agent for Sniffed {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        self.logger.setup(ctx);
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        // A copy's content is the message as printed; anything else is the logger's business.
        let original = match &message.content {
            Some(iw_acl::Content::Text(text)) => iw_acl::codec::parse(text).ok(),
            _ => None,
        };
        if let Some(original) = original {
            let mut traffic = lock(&self.traffic);
            traffic.count += 1;
            traffic.recent.push_back(message_view(&original));
            while traffic.recent.len() > RECENT {
                traffic.recent.pop_front();
            }
        }
        self.logger.handle(ctx, message);
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        self.logger.tick(ctx);
    }

    fn tick_period(&self) -> Option<Duration> {
        self.logger.tick_period()
    }

    fn take_down(&mut self, ctx: &mut Context<'_>) {
        self.logger.take_down(ctx);
    }
}

fn message_view(m: &AclMessage) -> MessageView {
    MessageView {
        from: m
            .sender
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default(),
        to: m
            .receivers
            .iter()
            .map(|r| r.name.as_str())
            .collect::<Vec<_>>()
            .join(","),
        act: m.performative.to_string().to_ascii_lowercase(),
        conv: m.conversation_id.clone().unwrap_or_default(),
        dropped: false,
    }
}

/// The door actuator, with the state of each door it moved kept for the page.
struct WatchedDoors {
    inner: Box<dyn DoorActuator>,
    /// Door agent name to map door id.
    ids: BTreeMap<String, String>,
    open: Arc<Mutex<BTreeMap<String, bool>>>,
}

impl DoorActuator for WatchedDoors {
    fn set(&mut self, door: &str, open: bool) -> Result<(), ActuatorFault> {
        self.inner.set(door, open)?;
        if let Some(id) = self.ids.get(door) {
            lock(&self.open).insert(id.clone(), open);
        }
        Ok(())
    }
}

/// The dashboard of a services container. See the module docs.
pub(crate) struct LiveDashboard {
    server: Dashboard,
    traffic: SharedTraffic,
    doors: Arc<Mutex<BTreeMap<String, bool>>>,
    refusals: RefusalLog,
    /// The map's places (destinations): a click goes to the nearest.
    places: Vec<(String, [f64; 2])>,
    mapping: DriveMapping,
    started: Option<Time>,
    last_publish: Option<Time>,
    notices: VecDeque<String>,
    /// Each chair's last two poses and when they arrived, for its speed.
    motion: BTreeMap<String, Motion>,
    /// The drive command last relayed to each chair, while held.
    driving: BTreeMap<String, [f64; 2]>,
}

/// A chair's pose as last seen and the speed derived from the previous one.
#[derive(Debug, Clone, Copy)]
struct Motion {
    pose: [f64; 3],
    at: Time,
    twist: [f64; 2],
}

/// Shortest interval over which a speed is derived from two poses, s.
const MIN_SPEED_DT_S: f64 = 0.15;

impl LiveDashboard {
    /// Starts the dashboard `section` asks for (`None` when `listen` is empty), drawing
    /// `building`.
    pub(crate) fn start(
        section: &DashboardSection,
        building: &Building,
    ) -> Result<Option<Self>, NodeError> {
        if section.listen.is_empty() {
            return Ok(None);
        }
        let bind: SocketAddr = section.listen.parse().map_err(|e| NodeError::Value {
            key: "dashboard.listen".into(),
            what: format!("`{}` is not `ip:port`", section.listen),
            source: Box::new(e),
        })?;
        let token = (!section.token.is_empty()).then(|| section.token.clone());
        let server = Dashboard::start(
            DashboardConfig { bind, token },
            &iw_wiring::view::map_view(&building.map),
        )
        .map_err(|e| NodeError::Setting {
            file: if bind.ip().is_loopback() {
                "dashboard.listen".into()
            } else {
                "dashboard.token".into()
            },
            source: e.into(),
        })?;
        Ok(Some(LiveDashboard {
            server,
            traffic: SharedTraffic::default(),
            doors: Arc::default(),
            refusals: RefusalLog::default(),
            places: building
                .destinations()
                .map(|(n, p)| (n.clone(), [p.x, p.y]))
                .collect(),
            mapping: DriveMapping::default(),
            started: None,
            last_publish: None,
            notices: VecDeque::new(),
            motion: BTreeMap::new(),
            driving: BTreeMap::new(),
        }))
    }

    /// The page's URL (with the token, when there is one).
    pub(crate) fn url(&self) -> String {
        self.server.url()
    }

    /// `agents` with the logger wrapped, so the page sees every message it is sent a copy of;
    /// the page shows the door agent's `refusals`.
    pub(crate) fn attach(
        &mut self,
        agents: crate::runtime::Agents,
        refusals: RefusalLog,
    ) -> crate::runtime::Agents {
        self.refusals = refusals;
        let logger = iw_wiring::agent_id("logger", SERVICES);
        agents
            .into_iter()
            .map(|(aid, agent)| {
                let agent: Box<dyn Agent> = if aid == logger {
                    Box::new(Sniffed {
                        logger: agent,
                        traffic: self.traffic.clone(),
                    })
                } else {
                    agent
                };
                (aid, agent)
            })
            .collect()
    }

    /// `doors` (moving the doors of `ids`, door agent name to map id), watched for the page.
    pub(crate) fn watch_doors(
        &self,
        doors: Box<dyn DoorActuator>,
        ids: BTreeMap<String, String>,
    ) -> Box<dyn DoorActuator> {
        // every door starts closed (the door agent's rule)
        *lock(&self.doors) = ids.values().map(|id| (id.clone(), false)).collect();
        Box::new(WatchedDoors {
            inner: doors,
            ids,
            open: self.doors.clone(),
        })
    }

    /// Takes the page's asks: drive inputs go on `desk` for the staff console; the goals are
    /// returned (chair, place) for the services to give like configured ones.
    pub(crate) fn take_actions(&mut self, desk: &SharedDesk) -> Vec<(String, String)> {
        let mut goals = Vec::new();
        while let Some(action) = self.server.try_action() {
            match action {
                PageAction::Goal { chair, x, y } => {
                    let nearest = self
                        .places
                        .iter()
                        .filter(|_| x.is_finite() && y.is_finite())
                        .min_by(|a, b| {
                            let d = |p: &[f64; 2]| (p[0] - x).hypot(p[1] - y);
                            d(&a.1).total_cmp(&d(&b.1))
                        });
                    match nearest.map(|(place, _)| place.clone()) {
                        Some(place) => {
                            self.notice(format!("{chair} -> {place}: sent to the assistant"));
                            goals.push((chair, place));
                        }
                        None => self.notice(format!("goal ({x}, {y}) for {chair}: not a point")),
                    }
                }
                PageAction::Drive { chair, input } => {
                    let raw = iw_wiring::view::raw_input(input);
                    let command = match self.mapping.command(&raw) {
                        Some(Ok(c)) => (c.linear_mps, c.angular_radps),
                        Some(Err(err)) => {
                            // a broken reading counts as letting go: the chair stops
                            self.notice(format!("{chair}: drive input refused ({err}); stopped"));
                            (0.0, 0.0)
                        }
                        None => continue,
                    };
                    if command == (0.0, 0.0) {
                        self.driving.remove(&chair);
                    } else {
                        self.driving.insert(chair.clone(), [command.0, command.1]);
                    }
                    iw_wiring::desk(desk).drives.insert(chair, command);
                }
                other => self.notice(format!(
                    "{other:?}: not available on a live deployment (the in-process demo has it)"
                )),
            }
        }
        goals
    }

    fn notice(&mut self, text: String) {
        self.notices.push_back(text);
        while self.notices.len() > NOTICES {
            self.notices.pop_front();
        }
    }

    /// Publishes the state at most every [`PUBLISH_EVERY`]: `desk` (poses, answers), `given`
    /// (goal conversation to chair and place), `agents` (the other containers' agents in the
    /// GAL), `own` (this container's agents) and `refused` (frames the platform refused here,
    /// per reason).
    pub(crate) fn publish(
        &mut self,
        now: Time,
        desk: &SharedDesk,
        given: &BTreeMap<String, (String, String)>,
        agents: &mut dyn Iterator<Item = &String>,
        own: &[String],
        refused: impl FnOnce() -> BTreeMap<String, u64>,
    ) {
        let started = *self.started.get_or_insert(now);
        if self
            .last_publish
            .is_some_and(|last| now < last.plus(PUBLISH_EVERY))
        {
            return;
        }
        self.last_publish = Some(now);
        let now_s = now.0 as f64 * 1e-9;
        let (poses, answers, sonar, applied) = {
            let desk = iw_wiring::desk(desk);
            // the newest answer about each chair's goal or drive
            let mut answers: BTreeMap<String, String> = BTreeMap::new();
            for e in &desk.events {
                let chair = given
                    .get(&e.conversation)
                    .map(|(c, _)| c.clone())
                    .or_else(|| {
                        e.conversation
                            .strip_prefix("drive-")
                            .and_then(|rest| rest.split_once("-staff@"))
                            .map(|(c, _)| c.to_string())
                    });
                if let Some(chair) = chair {
                    let why = e
                        .reason
                        .as_deref()
                        .map(|r| format!(": {r}"))
                        .unwrap_or_default();
                    answers.insert(chair, format!("{} from {}{why}", e.performative, e.from));
                }
            }
            // what shared control applied, while the control agent keeps telling it
            let applied: BTreeMap<String, [f64; 2]> = desk
                .applied
                .iter()
                .filter(|(_, (_, at_s))| now_s - at_s <= APPLIED_FOR.as_secs_f64())
                .map(|(chair, (v, _))| (chair.clone(), *v))
                .collect();
            (desk.poses.clone(), answers, desk.sonar.clone(), applied)
        };
        for (chair, pose) in &poses {
            let seen = self.motion.entry(chair.clone()).or_insert(Motion {
                pose: *pose,
                at: now,
                twist: [0.0; 2],
            });
            let dt = now.since(seen.at).as_secs_f64();
            if *pose != seen.pose && dt >= MIN_SPEED_DT_S {
                let (dx, dy) = (pose[0] - seen.pose[0], pose[1] - seen.pose[1]);
                let heading = pose[2];
                let turn = (pose[2] - seen.pose[2])
                    .sin()
                    .atan2((pose[2] - seen.pose[2]).cos());
                seen.twist = [(dx * heading.cos() + dy * heading.sin()) / dt, turn / dt];
                seen.pose = *pose;
                seen.at = now;
            } else if *pose == seen.pose && dt >= 2.0 * MIN_SPEED_DT_S {
                seen.twist = [0.0; 2];
            }
        }
        let goal_of: BTreeMap<&String, &String> = given.values().map(|(c, p)| (c, p)).collect();
        let chairs = poses
            .iter()
            .map(|(name, p)| {
                let twist = self.motion.get(name).map_or([0.0; 2], |m| m.twist);
                let goal = goal_of.get(name).map(|p| (*p).clone());
                let at = goal
                    .as_ref()
                    .and_then(|g| self.places.iter().find(|(n, _)| n == g))
                    .map(|(_, at)| [round_cm(at[0]), round_cm(at[1])]);
                ChairView {
                    n: name.clone(),
                    // the services do not know the body: virtual, serial and mixed look alike
                    k: "deployed".into(),
                    p: [round_cm(p[0]), round_cm(p[1]), round_cm(p[2])],
                    v: [round_cm(twist[0]), round_cm(twist[1])],
                    s: sonar
                        .get(name)
                        .map(|r| r.iter().map(|&r| round_cm(r)).collect())
                        .unwrap_or_default(),
                    g: at,
                    path: Vec::new(),
                    u: 0.0,
                    c: 0,
                    d: ChairDisplay {
                        action: if twist[0].abs() > 0.01 || twist[1].abs() > 0.01 {
                            "driving".into()
                        } else {
                            "idle".into()
                        },
                        goal,
                        warn: false,
                        seq: None,
                        answer: answers.get(name).cloned(),
                        user: self
                            .driving
                            .get(name)
                            .map(|v| [round_cm(v[0]), round_cm(v[1])]),
                        applied: applied.get(name).map(|v| [round_cm(v[0]), round_cm(v[1])]),
                    },
                }
            })
            .collect();
        let mut containers: BTreeMap<String, Vec<String>> = BTreeMap::new();
        for agent in agents {
            let container = agent.split_once('@').map_or("?", |(_, c)| c).to_string();
            containers.entry(container).or_default().push(agent.clone());
        }
        containers.insert(SERVICES.into(), own.to_vec());
        let mut notices: Vec<String> = lock(&self.refusals)
            .iter()
            .rev()
            .take(NOTICES)
            .rev()
            .map(|r| format!("door {} refused {}: {}", r.door, r.requester, r.reason))
            .collect();
        notices.extend(self.notices.iter().cloned());
        let (msgs, sent) = {
            let traffic = lock(&self.traffic);
            (traffic.recent.iter().cloned().collect(), traffic.count)
        };
        let state = State {
            t: now.since(started).as_secs_f32(),
            paused: false,
            chairs,
            doors: lock(&self.doors)
                .iter()
                .map(|(d, o)| (d.clone(), *o))
                .collect(),
            containers: containers
                .into_iter()
                .map(|(name, agents)| ContainerView { name, agents })
                .collect(),
            msgs,
            notices,
            sent,
            features: None,
            sec: refused(),
        };
        if let Err(err) = self.server.publish(&state) {
            tracing::warn!(error = %err, "could not publish the dashboard state");
        }
    }
}
