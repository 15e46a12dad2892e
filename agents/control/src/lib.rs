//! The control agent (thesis 3.3, figure 3.2): the tactical and basic layers of one wheelchair as
//! an agent. It executes action sequences the cognitive agent requests, drives under shared
//! control when the user steers, and stops the chair when commands stop arriving.
//!
//! Organization:
//! - [`ControlConfig`]: who it talks to and its limits; [`ControlAgent::new`] takes it and the
//!   body to drive (a `Box<dyn iw_body::Body>`: real, virtual or mixed, it cannot tell).
//! - [`ControlError`]: a configuration the control layers refuse.
//! - [`drive_content`] / [`parse_drive`]: the manual `drive` action, which the wheelchair
//!   ontology does not carry.
//!
//! # Messages
//! Understood (all `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`):
//! - REQUEST (`fipa-request`) `((action (agent-identifier :name control) A))` where `A` is
//!   `(goto-xy :x :y)`, `(spin :angle)` (absolute heading), `(wait :duration-ms)`, `(stop)`,
//!   `(follow-left-wall :distance)`, `(follow-right-wall :distance)` or
//!   `(action-sequence :steps (sequence A ...))`. Answer: AGREE, then INFORM
//!   `((done (action control A)))` when finished, or FAILURE `((error-message "..."))` when
//!   blocked (no progress for [`ControlConfig::blocked_after_ms`]), when the body fails, or when a
//!   newer request or manual drive preempts it. Other actions (go-to, doors, follow-line) get
//!   REFUSE; content that is not the ontology gets NOT-UNDERSTOOD.
//! - REQUEST `((action (agent-identifier :name control) (drive :linear V :angular W)))` (m/s,
//!   rad/s): manual driving, no answer (it is a stream); corrected by the potential field with
//!   the sonars, fed to the watchdog. The interface must repeat it faster than
//!   [`ControlConfig::watchdog_ms`] or the chair stops.
//! - INFORM `((at-pose agent (pose ...)))`: the pose the tactical layer steers with, from the
//!   perception agent. At setup the agent SUBSCRIBEs (`fipa-subscribe`) to
//!   [`ControlConfig::perception`] with content `((at-pose ?agent ?pose))`.
//!
//! Driving: the potential field (thesis 3.6) corrects the user's manual command (not the
//! tactical layer's, whose path the planner keeps clear); then [`ArcGuard`] scales or steers either so the footprint swept until the chair stops (turning in place too) stays clear of
//! the sonar echoes.
//!
//! Guarantees: the body is commanded every tick; with no fresh command (manual) or no task the
//! watchdog ramps the wheels to zero; a body read error stops the chair and fails the task; no
//! message content can panic the agent.
#![warn(missing_docs)]

use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_body::layout::Footprint;
use iw_body::{Body, BodyError, SensorFrame};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, WheelchairAction, WheelchairContent};
use iw_shared_control::basic::{BasicControl, DiffDrive, Watchdog};
use iw_shared_control::tactical::{
    Action, ActionSequence, SequenceStatus, Side, TacticalInput, TacticalParams,
};
use iw_shared_control::{
    ArcGuard, ArcGuardParams, Guarded, PotentialField, PotentialFieldParams, SensorMount,
    SharedController, SharedInput, VelocityCommand,
};
use iw_sl::{ActionExpression, ContentExpression, Level, Term};
use nalgebra::Isometry2;

/// A configuration the control layers refuse.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ControlError {
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
    /// Potential-field constants (thesis equations 3.1-3.4).
    pub shared: PotentialFieldParams,
    /// The chair's footprint (the arc guard and wall clearances use it).
    pub footprint: Footprint,
    /// The footprint guard applied after the potential field: the chair's rectangle swept along
    /// the commanded arc (turning in place included) until stopped must stay clear of echoes.
    pub guard: ArcGuardParams,
    /// Where each of the body's sonars sits, in its order (`iw_body::SONAR_COUNT` of them).
    pub sonar_mounts: Vec<SensorMount>,
    /// Manual commands older than this stop the chair, ms.
    pub watchdog_ms: u64,
    /// Control period.
    pub period: Duration,
    /// A task during which the chair travels less than [`BLOCKED_TRAVEL_M`] and turns less than
    /// [`BLOCKED_TURN_RAD`] net for this long fails as blocked, ms.
    pub blocked_after_ms: u64,
    /// Travel of a wall-following action before it is done, m.
    pub wall_length_m: f64,
    /// How long the body may stay unreadable before the running task fails, ms. The wheels stop
    /// at the first failed read; a task survives a shorter fault (one corrupted serial frame)
    /// and resumes from rest.
    pub body_fault_ms: u64,
}

impl ControlConfig {
    /// The prototype's defaults: its footprint and the 16 sonars of thesis figure 3.4 where the
    /// simulator puts them too ([`Footprint::PROTOTYPE`]), 0.56 m track, 1 m/s wheels, 0.5 s
    /// watchdog, 20 Hz.
    pub fn prototype(perception: Option<AgentId>) -> Result<Self, ControlError> {
        let footprint = Footprint::PROTOTYPE;
        let sonar_mounts = footprint.sonar_mounts().to_vec();
        Ok(ControlConfig {
            perception,
            footprint,
            guard: ArcGuardParams::default(),
            drive: DiffDrive::new(0.56, 1.0, 1.5)?,
            tactical: TacticalParams::default(),
            shared: PotentialFieldParams::default(),
            sonar_mounts,
            watchdog_ms: 500,
            period: Duration::from_millis(50),
            blocked_after_ms: 8000,
            wall_length_m: 3.0,
            body_fault_ms: 500,
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
    Manual { user: VelocityCommand },
    Task(Box<Task>),
}

struct Task {
    request: AclMessage,
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
    /// The potential field, then the arc guard; tactical commands take only `shared.guard`.
    shared: Guarded<PotentialField>,
    mode: Mode,
    t_map_base: Option<Isometry2<f64>>,
    manual_watchdog: Watchdog,
    /// When the body's reads started failing, while they fail, ns.
    body_fault_since_ns: Option<u64>,
}

impl ControlAgent {
    /// A control agent driving `body`.
    pub fn new(config: ControlConfig, body: Box<dyn Body + Send>) -> Result<Self, ControlError> {
        if config.sonar_mounts.len() != iw_body::SONAR_COUNT {
            return Err(ControlError::Mounts {
                mounts: config.sonar_mounts.len(),
                expected: iw_body::SONAR_COUNT,
            });
        }
        ActionSequence::new(config.tactical, [])?;
        let shared = Guarded {
            inner: PotentialField::new(config.shared, config.sonar_mounts.clone())?,
            guard: ArcGuard::new(config.guard, config.footprint, config.sonar_mounts.clone())?,
        };
        let basic = BasicControl::new(config.drive, config.watchdog_ms.saturating_mul(1_000_000));
        Ok(ControlAgent {
            body,
            basic,
            shared,
            mode: Mode::Idle,
            t_map_base: None,
            manual_watchdog: Watchdog::new(config.watchdog_ms.saturating_mul(1_000_000)),
            body_fault_since_ns: None,
            config,
        })
    }

    fn handle_request(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if let Some(user) = parse_drive(&message) {
            match user.validate() {
                Ok(user) => {
                    self.preempt(ctx, "preempted by manual driving");
                    self.mode = Mode::Manual { user };
                    self.manual_watchdog.feed(ctx.now().0);
                }
                Err(err) => {
                    let _ = ctx.not_understood(&message, &format!("bad drive command: {err}"));
                }
            }
            return;
        }
        let Some((actor, action)) =
            ctx.understand(&message, "expected ((action actor act))", |c| match c {
                WheelchairContent::Request { actor, action } => Some((actor, action)),
                _ => None,
            })
        else {
            return;
        };
        let mut steps = Vec::new();
        if let Err(refused) = self.tactical_actions(&action, &mut steps) {
            reply(
                ctx,
                &message,
                Performative::Refuse,
                &format!("cannot execute {refused}"),
            );
            return;
        }
        let sequence = match ActionSequence::new(self.config.tactical, steps) {
            Ok(sequence) => sequence,
            Err(err) => {
                reply(ctx, &message, Performative::Refuse, &err.to_string());
                return;
            }
        };
        self.preempt(ctx, "preempted by a newer request");
        reply(ctx, &message, Performative::Agree, "");
        self.mode = Mode::Task(Box::new(Task {
            request: message,
            actor,
            action,
            sequence,
            progress_at: None,
        }));
    }

    /// Maps an ontology action to tactical actions; `Err` names what cannot be driven.
    fn tactical_actions(
        &self,
        action: &WheelchairAction,
        out: &mut Vec<Action>,
    ) -> Result<(), String> {
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
            other => return Err(other.to_term_string()),
        }
        Ok(())
    }

    /// Ends a running task with FAILURE.
    fn preempt(&mut self, ctx: &mut Context<'_>, why: &str) {
        if let Mode::Task(task) = std::mem::replace(&mut self.mode, Mode::Idle) {
            reply(ctx, &task.request, Performative::Failure, why);
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
        self.preempt(ctx, &format!("{why}; the wheel stop failed too: {stop}"));
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
        let blocked = now_ns.saturating_sub(since)
            > self.config.blocked_after_ms.saturating_mul(1_000_000)
            && !task.is_waiting();
        match outcome {
            Ok(out) if out.status == SequenceStatus::Finished => {
                let done = WheelchairContent::Done {
                    actor: task.actor.clone(),
                    action: task.action.clone(),
                };
                let inform = done.fill(
                    task.request
                        .create_reply()
                        .with_performative(Performative::Inform),
                );
                let _ = ctx.send(inform);
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

/// Reply helper: `performative` with an `error-message` reason (none for an empty one).
fn reply(ctx: &mut Context<'_>, to: &AclMessage, performative: Performative, reason: &str) {
    let mut message = to.create_reply().with_performative(performative);
    if !reason.is_empty() {
        message = message.with_content(format!(
            "((error-message \"{}\"))",
            reason.replace('"', "'")
        ));
    } else if performative == Performative::Agree {
        message = message.with_content(to.content_text().unwrap_or_default().to_string());
    }
    let _ = ctx.send(message);
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
            let subscribe = AclMessage::new(Performative::Subscribe)
                .with_receiver(perception)
                .with_protocol("fipa-subscribe")
                .with_ontology(iw_ontology::wheelchair::ONTOLOGY)
                .with_language(Level::Sl0.language())
                .with_conversation_id(format!("pose-{}", ctx.name()))
                .with_content("((at-pose ?agent ?pose))");
            let _ = ctx.send(subscribe);
        }
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Request => self.handle_request(ctx, message),
            Performative::Inform => match WheelchairContent::from_message(&message) {
                Ok(WheelchairContent::Inform(Fact::AtPose { pose, .. })) => {
                    self.t_map_base = Some(pose.t_map_base())
                }
                Ok(_) => {}
                Err(err) => tracing::debug!(error = %err, "ignored an inform"),
            },
            Performative::Agree
            | Performative::Refuse
            | Performative::Failure
            | Performative::NotUnderstood => {
                tracing::debug!(performative = %message.performative, "answer to our subscription");
            }
            _ => {
                let _ = ctx.not_understood(
                    &message,
                    "the control agent takes requests and pose informs",
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
                self.body_fault_since_ns = None;
                frame
            }
            Err(err) => {
                self.basic.halt(now_ns);
                if let Err(stop) = self.stop_wheels() {
                    self.stop_failed(ctx, &format!("body: {err}"), &stop);
                    return;
                }
                let since = *self.body_fault_since_ns.get_or_insert(now_ns);
                if now_ns.saturating_sub(since)
                    < self.config.body_fault_ms.saturating_mul(1_000_000)
                {
                    tracing::warn!(error = %err, "body read failed; wheels stopped, task held");
                    return;
                }
                tracing::warn!(error = %err, fault_ms = self.config.body_fault_ms, "body unreadable past the fault window; chair stopped, task failed");
                self.preempt(ctx, &format!("body: {err}"));
                if let Mode::Manual { .. } = self.mode {
                    self.mode = Mode::Idle;
                }
                return;
            }
        };
        if let Mode::Manual { .. } = self.mode
            && self.manual_watchdog.expired(now_ns)
        {
            tracing::info!("watchdog: manual commands stopped arriving; stopping");
            self.mode = Mode::Idle;
        }
        // The user's commands go through the potential field (thesis 3.6); the tactical layer's
        // own commands do not (its path is planned clear), only through the arc guard.
        let (user, shared) = match &self.mode {
            Mode::Manual { user } => (Some(*user), true),
            Mode::Task(_) => (self.run_task(ctx, &frame), false),
            Mode::Idle => (None, false),
        };
        let command = match user {
            Some(user) => {
                let input = SharedInput {
                    user,
                    speed_mps: user.linear_mps.abs(),
                    sonar_m: &frame.sonar_m,
                    points_chair: &[],
                };
                let out = if shared {
                    self.shared.step(&input)
                } else {
                    self.shared.guard.step(&input)
                };
                out.map_or(VelocityCommand::STOP, |out| out.command)
            }
            None => VelocityCommand::STOP,
        };
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

/// The content of a manual drive request to `control` (its agent name): linear speed m/s,
/// angular speed rad/s (counter-clockwise positive).
pub fn drive_content(control: &str, linear_mps: f64, angular_radps: f64) -> String {
    format!(
        "((action (agent-identifier :name {}) (drive :linear {linear_mps:?} :angular {angular_radps:?})))",
        iw_sl::Term::string(control)
    )
}

/// The user's command in a manual `drive` request, or `None` when the content is something else.
pub fn parse_drive(message: &AclMessage) -> Option<VelocityCommand> {
    let content = iw_sl::parse(message.content_text()?, Level::Sl0).ok()?;
    let [ContentExpression::Action(ActionExpression::Action { act, .. })] =
        content.expressions.as_slice()
    else {
        return None;
    };
    let Term::Functional { symbol, args } = act else {
        return None;
    };
    if !symbol.eq_ignore_ascii_case("drive") {
        return None;
    }
    let number = |name: &str| match args.get(name)?.as_constant()? {
        iw_sl::Constant::Float(x) => Some(*x),
        iw_sl::Constant::Integer(i) => Some(*i as f64),
        _ => None,
    };
    Some(VelocityCommand::new(number("linear")?, number("angular")?))
}
