//! The control agent (thesis 3.3, figure 3.2): the tactical and basic layers of one wheelchair as
//! an agent. It executes action sequences the cognitive agent requests, drives under shared
//! control when the user steers, and stops the chair when commands stop arriving.
//!
//! Organization:
//! - [`ControlConfig`]: who it talks to and its limits; [`ControlAgent::new`] takes it and the
//!   body to drive (a `Box<dyn iw_body::Body>`: real, virtual or mixed, it cannot tell).
//! - [`ControlConfigError`]: a configuration the control layers refuse.
//! - [`DriveStatus`]: what the user asked and what shared control applied, shared with whoever
//!   shows it (the on-chair display, the dashboard).
//!
//! # Messages
//! Understood (all `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`):
//! - REQUEST (`fipa-request`) `((action (agent-identifier :name control) A))` where `A` is
//!   `(goto-xy :x :y)`, `(spin :angle)` (absolute heading), `(wait :duration-ms)`, `(stop)`,
//!   `(follow-left-wall :distance)`, `(follow-right-wall :distance)` or
//!   `(action-sequence :steps (sequence A ...))`. Answer: AGREE, then INFORM
//!   `((done (action control A)))` when finished, or FAILURE `((error-message "..."))` when
//!   blocked (no progress for [`ControlConfig::blocked_after`]) or when a newer request or
//!   manual drive preempts it, FAILURE `((body-fault "..."))` when the body stays unreadable past
//!   [`ControlConfig::body_fault`] or takes no stop (the way is not known to be blocked: the
//!   requester may try again once the body is back). Other actions (go-to, doors, follow-line) get
//!   REFUSE; content that is not the ontology gets NOT-UNDERSTOOD.
//! - REQUEST `((action (agent-identifier :name control) (drive :linear V :angular W)))` (m/s,
//!   rad/s): manual driving as a stream, one conversation per stream (held input). The first
//!   command of a stream gets AGREE; the following ones no answer. Every command goes through
//!   the arc guard with the sonars and the laser, and feeds the watchdog: when the
//!   stream falls silent for [`ControlConfig::watchdog`] the chair stops and the stream ends
//!   with INFORM `((done ...))` if the last command was a stop (the user let go), FAILURE
//!   otherwise. Refused (REFUSE with a reason): a command out of the drive's range or not
//!   finite (mid-stream: FAILURE, and the chair stops); a driver that is not of this chair
//!   ([`ControlConfig::drivers`]); a second driver while another's stream is live, unless it is
//!   staff ([`ControlConfig::staff`]): then the first stream ends with FAILURE and the override
//!   is logged.
//! - SUBSCRIBE (`fipa-subscribe`) with content naming `drive-applied` (e.g.
//!   `((drive-applied ?agent ?command))`): AGREE; then, every tick in which the chair is driven by
//!   hand, INFORM `((drive-applied control (drive :linear V :angular W)))` with what shared
//!   control applied (a remote driver's screen shows it). One subscription per subscriber and
//!   conversation; CANCEL ends it.
//! - INFORM `((at-pose agent (pose ...)))`: the pose the tactical layer steers with, from the
//!   perception agent. At setup the agent SUBSCRIBEs (`fipa-subscribe`) to
//!   [`ControlConfig::perception`] with content `((at-pose ?agent ?pose))`; only that
//!   subscription's notifications move the pose (an INFORM in another conversation does not).
//!
//! Requests, drive streams, the `drive-applied` subscriptions and its own pose subscription run
//! on the interaction protocols' state machines (`iw_agent::conversation`): a drive stream's
//! later commands and a CANCEL are matched to their conversation by its responder, and no
//! answer is sent that the protocol does not allow.
//!
//! Driving: [`ArcGuard`] scales or steers the user's manual command and the tactical layer's so
//! the footprint swept until the chair stops (turning in place too) stays clear of the sonar
//! echoes and the laser's points (those out of its view remembered). It predicts from the speed the encoders measure ([`WheelMotion`]), not from the
//! command alone. The thesis's potential field (3.6) is not in this path: in the cluttered
//! circuits of the shared-control experiment the field's turn commands chattered in doorways, and
//! the guard alone finished more laps with fewer contacts (docs/results/shared-control.md).
//!
//! Guarantees: the body is commanded every tick; with no fresh command (manual) or no task the
//! watchdog ramps the wheels to zero; a body read error stops the chair and fails the task; no
//! message content can panic the agent.
#![warn(missing_docs)]

use std::sync::PoisonError;
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::conversation::answers_a_conversation;
use iw_agent::{Agent, Context, EventKind, Initiated, Progress, Protocol, Responder};
use iw_body::layout::Footprint;
use iw_body::{Body, BodyError, SensorFrame, WheelGeometry};
use iw_bus::duration_ns;
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, Subscription, Topic, WheelchairAction, WheelchairContent};
use iw_shared_control::basic::{BasicControl, DiffDrive, Watchdog};
use iw_shared_control::tactical::{
    Action, ActionSequence, SequenceStatus, Side, TacticalInput, TacticalParams,
};
use iw_shared_control::{
    ArcGuard, ArcGuardParams, SensorMount, SharedController, SharedInput, VelocityCommand,
    WheelMotion,
};
use nalgebra::{Isometry2, Point2};

/// Why a request for a tactical action is refused. It stays typed up to the bus boundary,
/// where its message becomes the REFUSE's `(error-message "…")`.
#[derive(Debug, thiserror::Error)]
enum Refusal {
    /// An action this agent does not execute (a goal to a place, a door, a passage).
    #[error("cannot execute {}", .0.to_term_string())]
    NotTactical(WheelchairAction),
    /// The steps do not make an action sequence.
    #[error(transparent)]
    Sequence(iw_shared_control::ControlError),
}

/// A configuration the control layers refuse.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ControlConfigError {
    /// A parameter of the shared-control library is out of range.
    #[error("control agent configuration: {source}")]
    Config {
        /// What the library said.
        #[from]
        source: iw_shared_control::ControlError,
    },
    /// The sonar mounts do not match the body's sonar count.
    #[error("{mounts} sonar mounts given, the body has {expected} sonars")]
    Mounts {
        /// Mounts given.
        mounts: usize,
        /// Sonars on the body.
        expected: usize,
    },
}

/// Who the control agent talks to and its limits.
#[derive(Debug, Clone)]
pub struct ControlConfig {
    /// The perception agent whose poses steer the tactical layer (subscribed at setup).
    pub perception: Option<AgentId>,
    /// Wheel geometry and speed/acceleration limits.
    pub drive: DiffDrive,
    /// Gains and tolerances of the basic actions.
    pub tactical: TacticalParams,
    /// The encoders' geometry, for the motion the guard predicts from.
    pub wheels: WheelGeometry,
    /// The chair's footprint (the arc guard and wall clearances use it).
    pub footprint: Footprint,
    /// The footprint guard every command passes: the chair's rectangle swept along the commanded
    /// arc (turning in place included) until stopped must stay clear of echoes.
    pub guard: ArcGuardParams,
    /// Where each of the body's sonars sits, in its order (`iw_body::SONAR_COUNT` of them).
    pub sonar_mounts: Vec<SensorMount>,
    /// Manual commands older than this stop the chair.
    pub watchdog: Duration,
    /// Control period.
    pub period: Duration,
    /// A task during which the chair travels less than [`BLOCKED_TRAVEL_M`] and turns less than
    /// [`BLOCKED_TURN_RAD`] net for this long fails as blocked.
    pub blocked_after: Duration,
    /// Travel of a wall-following action before it is done, m.
    pub wall_length_m: f64,
    /// How long the body may stay unreadable before the running task fails. The wheels stop
    /// at the first failed read; a task survives a shorter fault (one corrupted serial frame)
    /// and resumes from rest, its no-progress time counted afresh.
    pub body_fault: Duration,
    /// Agents that may drive this chair by hand. Empty: the agents of this chair's own
    /// container, the part of their name after `@` being the control agent's.
    pub drivers: Vec<String>,
    /// Staff agents: they may drive any chair, and take it over from its driver (logged).
    pub staff: Vec<String>,
    /// The laser scanner, if fitted: its points join the sonar echoes in the arc guard, for the
    /// user's commands and the tasks' alike, so a wall between two sonar cones is seen too (and
    /// remembered once it is beside the chair, out of the laser's view).
    pub laser: Option<LaserMount>,
}

/// Where a laser scanner sits on the chair and how its beams spread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserMount {
    /// Its pose in the body frame.
    pub t_body_laser: Isometry2<f64>,
    /// Field of view, rad: the beams are spread evenly from -fov/2 to +fov/2.
    pub fov_rad: f64,
    /// A beam at this range or beyond saw nothing, m.
    pub max_range_m: f64,
}

impl LaserMount {
    /// `ranges` (one per beam) as obstacle points in the body frame, into `out`; beams that saw
    /// nothing, or read something not finite, are left out.
    fn points(&self, ranges: &[f64], out: &mut Vec<Point2<f64>>) {
        out.clear();
        let n = ranges.len();
        for (i, &r) in ranges.iter().enumerate() {
            if !(r.is_finite() && r >= 0.0 && r < self.max_range_m - 1e-6) {
                continue;
            }
            let a = if n > 1 {
                -self.fov_rad / 2.0 + self.fov_rad * i as f64 / (n - 1) as f64
            } else {
                0.0
            };
            out.push(self.t_body_laser * Point2::new(r * a.cos(), r * a.sin()));
        }
    }
}

impl ControlConfig {
    /// The prototype's defaults: its footprint and the 16 sonars of thesis figure 3.4 where the
    /// simulator puts them too ([`Footprint::PROTOTYPE`]), the body's wheel track
    /// ([`WheelGeometry`]), 1 m/s wheels, 0.5 s watchdog, 20 Hz.
    pub fn prototype(perception: Option<AgentId>) -> Result<Self, ControlConfigError> {
        let footprint = Footprint::PROTOTYPE;
        let sonar_mounts = footprint.sonar_mounts().to_vec();
        Ok(ControlConfig {
            perception,
            footprint,
            guard: ArcGuardParams::default(),
            drive: DiffDrive::new(WheelGeometry::default().track_m, 1.0, 1.5)?,
            tactical: TacticalParams::default(),
            wheels: WheelGeometry::default(),
            sonar_mounts,
            watchdog: Duration::from_millis(500),
            period: Duration::from_millis(50),
            blocked_after: Duration::from_secs(8),
            wall_length_m: 3.0,
            body_fault: Duration::from_millis(500),
            drivers: Vec::new(),
            staff: Vec::new(),
            laser: None,
        })
    }
}

/// Net travel below which a task window counts as no progress, m.
pub const BLOCKED_TRAVEL_M: f64 = 0.05;
/// Net heading change below which a task window counts as no progress, rad.
pub const BLOCKED_TURN_RAD: f64 = 0.5;

/// Whether the chair moved from `anchor` to `now` by more than jitter: [`BLOCKED_TRAVEL_M`] of
/// travel or [`BLOCKED_TURN_RAD`] of net turn (wrapped, so +-pi is no turn).
fn progressed(anchor: &Isometry2<f64>, now: &Isometry2<f64>) -> bool {
    (now.translation.vector - anchor.translation.vector).norm() > BLOCKED_TRAVEL_M
        || anchor.rotation.angle_to(&now.rotation).abs() > BLOCKED_TURN_RAD
}

/// What the agent is doing.
enum Mode {
    Idle,
    Manual(Box<Stream>),
    Task(Box<Task>),
}

/// A live manual drive stream: who drives, in which conversation, and the last command.
struct Stream {
    /// The stream's conversation: answered once at its start and once at its end, and the
    /// judge of which later commands are the stream's (same driver and conversation, not ended).
    responder: Responder,
    driver: String,
    user: VelocityCommand,
}

fn sender_name(message: &AclMessage) -> &str {
    message.sender.as_ref().map_or("", |s| s.name.as_str())
}

/// What the user asked for and what shared control sent to the basic layer, at the last tick
/// of manual driving (`None` while no one drives).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct DriveStatus {
    /// The user's last command.
    pub user: Option<VelocityCommand>,
    /// What the potential field and the arc guard made of it.
    pub applied: Option<VelocityCommand>,
}

/// A [`DriveStatus`] shared with a display (cloning shares).
pub type SharedDriveStatus = std::sync::Arc<std::sync::Mutex<DriveStatus>>;

struct Task {
    responder: Responder,
    actor: AgentId,
    action: WheelchairAction,
    sequence: ActionSequence,
    /// Where progress was last measured and when, ns.
    progress_at: Option<(Isometry2<f64>, u64)>,
}

/// The control agent of one wheelchair.
pub struct ControlAgent {
    config: ControlConfig,
    body: Box<dyn Body + Send>,
    basic: BasicControl,
    /// The footprint sweep every command passes (the user's and the tactical layer's).
    guard: ArcGuard,
    /// The chair's measured motion, from the encoder ticks of each frame.
    motion: WheelMotion,
    mode: Mode,
    /// The pose subscription to the perception agent.
    poses: Initiated<()>,
    t_map_base: Option<Isometry2<f64>>,
    manual_watchdog: Watchdog,
    /// When the body's reads started failing, while they fail, ns.
    body_fault_since_ns: Option<u64>,
    status: SharedDriveStatus,
    /// The `drive-applied` subscriptions, each its conversation's responder.
    applied_to: Vec<Responder>,
    /// The laser's points of this tick, body frame (kept to reuse the allocation).
    laser_points: Vec<Point2<f64>>,
}

impl ControlAgent {
    /// A control agent driving `body`.
    pub fn new(
        config: ControlConfig,
        body: Box<dyn Body + Send>,
    ) -> Result<Self, ControlConfigError> {
        if config.sonar_mounts.len() != iw_body::SONAR_COUNT {
            return Err(ControlConfigError::Mounts {
                mounts: config.sonar_mounts.len(),
                expected: iw_body::SONAR_COUNT,
            });
        }
        ActionSequence::new(config.tactical, [])?;
        let guard = ArcGuard::new(config.guard, config.footprint, config.sonar_mounts.clone())?;
        let guard = match &config.laser {
            Some(laser) => guard.with_dense_view(laser.t_body_laser, laser.fov_rad),
            None => guard,
        };
        let motion = WheelMotion::new(config.wheels);
        let basic = BasicControl::new(config.drive, duration_ns(config.watchdog));
        Ok(ControlAgent {
            body,
            basic,
            guard,
            motion,
            mode: Mode::Idle,
            poses: Initiated::new(),
            t_map_base: None,
            manual_watchdog: Watchdog::new(duration_ns(config.watchdog)),
            body_fault_since_ns: None,
            status: SharedDriveStatus::default(),
            applied_to: Vec::new(),
            laser_points: Vec::new(),
            config,
        })
    }

    /// Where the agent tells what the user asked and what shared control applied.
    pub fn drive_status(&self) -> SharedDriveStatus {
        self.status.clone()
    }

    /// Whether `name` may drive this chair by hand (staff always may).
    fn may_drive(&self, own: &AgentId, name: &str) -> bool {
        let platform = |n: &str| n.split_once('@').map(|(_, p)| p.to_string());
        self.config.staff.iter().any(|s| s == name)
            || if self.config.drivers.is_empty() {
                platform(name) == platform(&own.name)
            } else {
                self.config.drivers.iter().any(|d| d == name)
            }
    }

    /// One manual `drive` command: starts, continues, or (refused) leaves alone a stream.
    fn on_drive(
        &mut self,
        ctx: &mut Context<'_>,
        message: AclMessage,
        request: WheelchairContent,
        user: VelocityCommand,
    ) {
        let driver = sender_name(&message).to_string();
        if let Mode::Manual(_) = self.mode
            && self.manual_watchdog.expired(ctx.now().0)
        {
            self.end_stream(ctx, None);
        }
        let current = match &mut self.mode {
            Mode::Manual(stream) => Some(ctx.continues(&mut stream.responder, &message)),
            _ => None,
        };
        let limit = self.range_error(user);
        if current == Some(true) {
            if let Some(why) = limit {
                // A broken device mid-stream: end the stream, stop the chair.
                self.end_stream(ctx, Some(&WheelchairContent::error(why)));
                return;
            }
            if let Mode::Manual(stream) = &mut self.mode {
                stream.user = user;
            }
            self.manual_watchdog.feed(ctx.now().0);
            return;
        }
        let Some(mut responder) = ctx.accept(&message) else {
            return;
        };
        let mut refuse = |ctx: &mut Context<'_>, why: &str| {
            let _ = ctx.answer_error(&mut responder, Performative::Refuse, why);
        };
        if let Some(why) = limit {
            refuse(ctx, &why);
            return;
        }
        if !self.may_drive(ctx.aid(), &driver) {
            refuse(
                ctx,
                &format!("`{driver}` is not a driver of this chair (nor staff)"),
            );
            return;
        }
        let why = match &self.mode {
            Mode::Manual(stream) if stream.driver != driver => {
                if !self.config.staff.contains(&driver) {
                    refuse(ctx, &format!("the chair is driven by `{}`", stream.driver));
                    return;
                }
                tracing::warn!(staff = %driver, driver = %stream.driver, "staff override: taking the chair over");
                format!("overridden by staff `{driver}`")
            }
            Mode::Manual(_) => "replaced by a newer drive stream".to_string(),
            _ => "preempted by manual driving".to_string(),
        };
        self.preempt(ctx, &why);
        if ctx
            .answer(&mut responder, Performative::Agree, &request)
            .is_err()
        {
            return;
        }
        self.mode = Mode::Manual(Box::new(Stream {
            responder,
            driver,
            user,
        }));
        self.manual_watchdog.feed(ctx.now().0);
    }

    /// Why `user` cannot be driven: not finite, or beyond what the wheels can do.
    fn range_error(&self, user: VelocityCommand) -> Option<String> {
        if user.validate().is_err() {
            return Some(format!(
                "drive command not finite: linear {} m/s, angular {} rad/s",
                user.linear_mps, user.angular_radps
            ));
        }
        let drive = &self.config.drive;
        let max_angular_radps = 2.0 * drive.max_wheel_mps / drive.track_width_m;
        (user.linear_mps.abs() > drive.max_wheel_mps
            || user.angular_radps.abs() > max_angular_radps)
            .then(|| {
                format!(
                    "drive command out of range: linear {} m/s (|v| <= {}), angular {} rad/s \
                     (|w| <= {max_angular_radps:.2})",
                    user.linear_mps, drive.max_wheel_mps, user.angular_radps
                )
            })
    }

    /// Ends the live drive stream: FAILURE with `why`, or (none) INFORM done when the user had
    /// let go (last command a stop), FAILURE for silence otherwise. The chair stops.
    fn end_stream(&mut self, ctx: &mut Context<'_>, why: Option<&WheelchairContent>) {
        let Mode::Manual(mut stream) = std::mem::replace(&mut self.mode, Mode::Idle) else {
            return;
        };
        let released = stream.user == VelocityCommand::STOP;
        match why {
            None if released => {
                let done = WheelchairContent::Done {
                    actor: ctx.aid().clone(),
                    action: WheelchairAction::Drive {
                        linear_mps: 0.0,
                        angular_radps: 0.0,
                    },
                };
                let _ = ctx.answer(&mut stream.responder, Performative::Inform, &done);
            }
            None => {
                let why = format!(
                    "watchdog: no drive command for {} ms; chair stopped",
                    self.config.watchdog.as_millis()
                );
                let _ = ctx.answer_error(&mut stream.responder, Performative::Failure, &why);
            }
            Some(why) => {
                let _ = ctx.answer(&mut stream.responder, Performative::Failure, why);
            }
        }
    }

    fn handle_request(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let Some((actor, action)) =
            ctx.understand(&message, "expected ((action actor act))", |c| match c {
                WheelchairContent::Request { actor, action } => Some((actor, action)),
                _ => None,
            })
        else {
            return;
        };
        let request = WheelchairContent::Request {
            actor: actor.clone(),
            action: action.clone(),
        };
        if let WheelchairAction::Drive {
            linear_mps,
            angular_radps,
        } = action
        {
            let user = VelocityCommand::new(linear_mps, angular_radps);
            self.on_drive(ctx, message, request, user);
            return;
        }
        let Some(mut responder) = ctx.accept(&message) else {
            return;
        };
        let mut steps = Vec::new();
        let sequence = self.tactical_actions(&action, &mut steps).and_then(|()| {
            ActionSequence::new(self.config.tactical, steps).map_err(Refusal::Sequence)
        });
        let sequence = match sequence {
            Ok(sequence) => sequence,
            // The bus boundary: the typed refusal becomes the REFUSE's `(error-message "…")`,
            // the only form in which another agent can read it.
            Err(why) => {
                let _ = ctx.answer_error(&mut responder, Performative::Refuse, &why.to_string());
                return;
            }
        };
        self.preempt(ctx, "preempted by a newer request");
        if ctx
            .answer(&mut responder, Performative::Agree, &request)
            .is_err()
        {
            return;
        }
        self.mode = Mode::Task(Box::new(Task {
            responder,
            actor,
            action,
            sequence,
            progress_at: None,
        }));
    }

    /// A SUBSCRIBE to `drive-applied` (agreed and kept) or a CANCEL of one.
    fn handle_subscription(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if message.performative == Performative::Cancel {
            self.applied_to.retain_mut(|s| !ctx.continues(s, &message));
            return;
        }
        let Some(mut responder) = ctx.accept(&message) else {
            return;
        };
        if !Subscription::from_message(&message).is_ok_and(|s| s.wants(Topic::DriveApplied)) {
            let _ = ctx.answer_error(
                &mut responder,
                Performative::Refuse,
                "the control agent's subscription is to ((drive-applied ?agent ?command))",
            );
            return;
        }
        if ctx
            .acknowledge(&mut responder, Performative::Agree)
            .is_err()
        {
            return;
        }
        // a SUBSCRIBE again in a live subscription's conversation renews it
        self.applied_to.retain(|s| {
            s.conversation_id() != responder.conversation_id()
                || s.initiator() != responder.initiator()
        });
        self.applied_to.push(responder);
    }

    /// Tells the `drive-applied` subscribers what shared control applied this tick.
    fn inform_applied(&mut self, ctx: &mut Context<'_>, command: VelocityCommand) {
        if self.applied_to.is_empty() {
            return;
        }
        let fact = WheelchairContent::Inform(Fact::Applied {
            agent: ctx.aid().clone(),
            linear_mps: command.linear_mps,
            angular_radps: command.angular_radps,
        });
        for subscription in &mut self.applied_to {
            if let Err(err) = ctx.answer(subscription, Performative::Inform, &fact) {
                tracing::debug!(error = %err, "could not inform a drive-applied subscriber");
            }
        }
    }

    /// Maps an ontology action to tactical actions; `Err` names what cannot be driven.
    fn tactical_actions(
        &self,
        action: &WheelchairAction,
        out: &mut Vec<Action>,
    ) -> Result<(), Refusal> {
        match action {
            WheelchairAction::GotoXy { x_m, y_m } => out.push(Action::GoTo {
                target: nalgebra::Point2::new(*x_m, *y_m),
            }),
            WheelchairAction::Spin { angle_rad } => out.push(Action::TurnTo {
                heading_rad: *angle_rad,
            }),
            WheelchairAction::Wait { duration_ms } => out.push(Action::Wait {
                duration_ns: u64::try_from(*duration_ms)
                    .unwrap_or(0)
                    .saturating_mul(1_000_000),
            }),
            WheelchairAction::Stop => out.push(Action::Stop),
            WheelchairAction::FollowLeftWall { distance_m } => out.push(Action::FollowWall {
                side: Side::Left,
                distance_m: *distance_m,
                length_m: self.config.wall_length_m,
            }),
            WheelchairAction::FollowRightWall { distance_m } => out.push(Action::FollowWall {
                side: Side::Right,
                distance_m: *distance_m,
                length_m: self.config.wall_length_m,
            }),
            WheelchairAction::Sequence { steps } => {
                for step in steps {
                    self.tactical_actions(step, out)?;
                }
            }
            other => return Err(Refusal::NotTactical(other.clone())),
        }
        Ok(())
    }

    /// Ends a running task or drive stream with FAILURE `((error-message why))`.
    fn preempt(&mut self, ctx: &mut Context<'_>, why: &str) {
        self.fail(ctx, &WheelchairContent::error(why));
    }

    /// Ends a running task or drive stream with FAILURE `((body-fault why))`: the body failed,
    /// so the requester may try again when it is back rather than take the way for blocked.
    fn body_failed(&mut self, ctx: &mut Context<'_>, why: &str) {
        self.fail(ctx, &WheelchairContent::body_fault(why));
    }

    /// Ends a running task or drive stream with FAILURE and `why`.
    fn fail(&mut self, ctx: &mut Context<'_>, why: &WheelchairContent) {
        match std::mem::replace(&mut self.mode, Mode::Idle) {
            Mode::Task(mut task) => {
                let _ = ctx.answer(&mut task.responder, Performative::Failure, why);
            }
            manual @ Mode::Manual(_) => {
                self.mode = manual;
                self.end_stream(ctx, Some(why));
            }
            Mode::Idle => {}
        }
    }

    /// Stops the wheels, retrying once at once; the second error when both attempts fail.
    fn stop_wheels(&mut self) -> Result<(), BodyError> {
        self.body.stop().or_else(|first| {
            tracing::warn!(error = %first, "wheel stop failed; retrying");
            self.body.stop()
        })
    }

    /// The wheels did not take a stop: nothing this agent commands can be trusted to happen, so
    /// the task (or manual driving) ends at once with both reasons; the stop is retried every
    /// period while the fault lasts.
    fn stop_failed(&mut self, ctx: &mut Context<'_>, why: &str, stop: &BodyError) {
        tracing::error!(%why, error = %stop, "the wheels did not take a stop; task failed");
        self.body_failed(ctx, &format!("{why}; the wheel stop failed too: {stop}"));
        if let Mode::Manual { .. } = self.mode {
            self.mode = Mode::Idle;
        }
    }

    /// Wall clearances from the chair's centre line, from the side sonars (those facing 45..135
    /// degrees left or right): the lateral offset of each echo in the body frame.
    fn walls(&self, frame: &SensorFrame) -> (Option<f64>, Option<f64>) {
        let mut left: Option<f64> = None;
        let mut right: Option<f64> = None;
        for (mount, range) in self.config.sonar_mounts.iter().zip(frame.sonar_m.iter()) {
            let Some(range) = *range else { continue };
            let angle = mount.rotation.angle();
            let clearance = (mount * nalgebra::Point2::new(range, 0.0)).y.abs();
            let keep = |slot: &mut Option<f64>| {
                *slot = Some(slot.map_or(clearance, |c: f64| c.min(clearance)))
            };
            if (0.78..=2.36).contains(&angle) {
                keep(&mut left);
            } else if (-2.36..=-0.78).contains(&angle) {
                keep(&mut right);
            }
        }
        (left, right)
    }

    fn run_task(&mut self, ctx: &mut Context<'_>, frame: &SensorFrame) -> Option<VelocityCommand> {
        let now_ns = ctx.now().0;
        let (left_wall_m, right_wall_m) = self.walls(frame);
        let Mode::Task(task) = &mut self.mode else {
            return None;
        };
        let Some(t_world_chair) = self.t_map_base else {
            return Some(VelocityCommand::STOP);
        };
        let input = TacticalInput {
            time_ns: now_ns,
            t_world_chair,
            left_wall_m,
            right_wall_m,
        };
        let outcome = task.sequence.step(&input);
        let since = match task.progress_at {
            Some((anchor, since)) if !progressed(&anchor, &t_world_chair) => since,
            _ => {
                task.progress_at = Some((t_world_chair, now_ns));
                now_ns
            }
        };
        let blocked = now_ns.saturating_sub(since) > duration_ns(self.config.blocked_after)
            && !task.is_waiting();
        match outcome {
            Ok(out) if out.status == SequenceStatus::Finished => {
                let done = WheelchairContent::Done {
                    actor: task.actor.clone(),
                    action: task.action.clone(),
                };
                let _ = ctx.answer(&mut task.responder, Performative::Inform, &done);
                self.mode = Mode::Idle;
                Some(VelocityCommand::STOP)
            }
            Ok(_) if blocked => {
                self.preempt(ctx, "blocked: no progress");
                Some(VelocityCommand::STOP)
            }
            Ok(out) => Some(out.command),
            Err(err) => {
                self.preempt(ctx, &err.to_string());
                Some(VelocityCommand::STOP)
            }
        }
    }
}

impl Task {
    /// A wait action makes no progress on purpose; it must not count as blocked.
    fn is_waiting(&self) -> bool {
        matches!(self.action, WheelchairAction::Wait { .. })
    }
}

trait TermString {
    fn to_term_string(&self) -> String;
}

impl TermString for WheelchairAction {
    fn to_term_string(&self) -> String {
        iw_ontology::Concept::to_term(self).to_string()
    }
}

impl Agent for ControlAgent {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        if let Some(perception) = self.config.perception.clone() {
            let subscribe = Subscription::to([Topic::AtPose]).fill(
                AclMessage::new(Performative::Subscribe)
                    .with_receiver(perception)
                    .with_conversation_id(format!("pose-{}", ctx.name())),
            );
            if let Err(err) = self.poses.open(ctx, Protocol::Subscribe, subscribe, ()) {
                tracing::warn!(error = %err, "could not subscribe to the chair's pose");
            }
        }
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match self.poses.handle(ctx, &message) {
            Some(Ok(Progress::Continues(event))) if event.kind == EventKind::Notified => {
                match WheelchairContent::from_message(&message) {
                    Ok(WheelchairContent::Inform(Fact::AtPose { pose, .. })) => {
                        self.t_map_base = Some(pose.t_map_base())
                    }
                    Ok(_) => {}
                    Err(err) => tracing::debug!(error = %err, "ignored a pose notification"),
                }
            }
            Some(Ok(Progress::Continues(_))) => {}
            Some(Ok(Progress::Ended(event, ()))) => {
                tracing::warn!(kind = ?event.kind, "the pose subscription ended");
            }
            Some(Err(err)) => tracing::debug!(error = %err, "out-of-protocol pose message"),
            None if message.performative == Performative::Request => {
                self.handle_request(ctx, message)
            }
            None if matches!(
                message.performative,
                Performative::Subscribe | Performative::Cancel
            ) =>
            {
                self.handle_subscription(ctx, message)
            }
            // An answer in no conversation of ours is not answered: NOT-UNDERSTOOD back to a
            // stray NOT-UNDERSTOOD would start an endless exchange.
            None if answers_a_conversation(message.performative) => {
                tracing::debug!(performative = %message.performative, "answer in no conversation of ours");
            }
            None => {
                let _ = ctx.not_understood(
                    &message,
                    "the control agent takes requests, drive-applied subscriptions and its pose \
                     subscription's informs",
                );
            }
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(self.config.period)
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let now_ns = ctx.now().0;
        let frame = match self.body.read() {
            Ok(frame) => {
                if self.body_fault_since_ns.take().is_some()
                    && let Mode::Task(task) = &mut self.mode
                {
                    // the wheels were stopped for the fault: that time is not the way's fault
                    task.progress_at = None;
                }
                frame
            }
            Err(err) => {
                self.basic.halt(now_ns);
                if let Err(stop) = self.stop_wheels() {
                    self.stop_failed(ctx, &format!("body: {err}"), &stop);
                    return;
                }
                let since = *self.body_fault_since_ns.get_or_insert(now_ns);
                if now_ns.saturating_sub(since) < duration_ns(self.config.body_fault) {
                    tracing::warn!(error = %err, "body read failed; wheels stopped, task held");
                    return;
                }
                tracing::warn!(error = %err, fault_ms = self.config.body_fault.as_millis(), "body unreadable past the fault window; chair stopped, task failed");
                self.body_failed(ctx, &format!("body: {err}"));
                return;
            }
        };
        if let Mode::Manual(_) = self.mode
            && self.manual_watchdog.expired(now_ns)
        {
            tracing::info!("watchdog: manual commands stopped arriving; stopping");
            self.end_stream(ctx, None);
        }
        let motion = self
            .motion
            .update(frame.time_ns, frame.left_ticks, frame.right_ticks);
        // The user's commands and the tactical layer's pass the same guard.
        let (user, manual) = match &self.mode {
            Mode::Manual(stream) => (Some(stream.user), true),
            Mode::Task(_) => (self.run_task(ctx, &frame), false),
            Mode::Idle => (None, false),
        };
        // The laser joins the sonars for the user's commands and the tactical layer's alike: a
        // plan is clear of the map, not of a trolley or a jamb the localizer has placed a few
        // centimetres off; the guard also remembers the laser's points once out of its view.
        match &self.config.laser {
            Some(laser) => laser.points(&frame.laser_m, &mut self.laser_points),
            None => self.laser_points.clear(),
        }
        // A person pushing into a spot the guard holds is backed out of it; a task is not (the
        // cognitive agent re-plans a blocked route).
        self.guard.set_recovery(manual);
        let command = match user {
            Some(user) => {
                let input = SharedInput {
                    user,
                    speed_mps: motion.map_or(0.0, |m| m.twist.linear_mps.abs()),
                    sonar_m: &frame.sonar_m,
                    points_chair: &self.laser_points,
                    motion,
                };
                self.guard
                    .step(&input)
                    .map_or(VelocityCommand::STOP, |out| out.command)
            }
            None => VelocityCommand::STOP,
        };
        *self.status.lock().unwrap_or_else(PoisonError::into_inner) = DriveStatus {
            user: user.filter(|_| manual),
            applied: manual.then_some(command),
        };
        if manual {
            self.inform_applied(ctx, command);
        }
        if let Err(err) = self.basic.command(command, now_ns) {
            tracing::warn!(error = %err, "command refused; stopping");
            let _ = self.basic.command(VelocityCommand::STOP, now_ns);
        }
        let wheels = self.basic.output(now_ns);
        if let Err(err) = self.body.command(wheels) {
            tracing::warn!(error = %err, "body command failed; stopping the wheels");
            self.basic.halt(now_ns);
            if let Err(stop) = self.stop_wheels() {
                self.stop_failed(ctx, &format!("wheel command failed: {err}"), &stop);
            }
        }
    }

    fn take_down(&mut self, ctx: &mut Context<'_>) {
        self.preempt(ctx, "control agent stopped");
        if let Err(err) = self.stop_wheels() {
            tracing::error!(error = %err, "control agent stopping: the wheels did not take the stop");
        }
    }
}
