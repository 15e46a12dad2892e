//! The staff console of the service container (`staff@services`): what staff type at the desk
//! becomes a `fipa-request` to the assistant agent (`go-to` a place for a chair), and the
//! answers relayed back are recorded. It plans nothing: the chair's cognitive agent does. It also
//! subscribes to the pose of the chairs the container puts on its watch list (a live deployment
//! has no simulator to read them from), with a screen also to their sonar readings and to what
//! their control agents apply while driven by hand, and relays a dashboard's drive panel to a chair's
//! interface agent as `drive` requests (one request stream per hold). It asks the chairs the
//! container names (when they join) for the goal they are carrying out, with a QUERY-REF to
//! their cognitive agent, so goals nobody here follows can be taken up. Every conversation runs
//! on the interaction protocols' state machines (`iw_agent::Initiated`).

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, FipaDateTime, Performative};
use iw_agent::{Agent, Context, EventKind, Initiated, Progress, Protocol};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{
    Fact, GoalInFlight, SensorReading, Subscription, Topic, WheelchairAction, WheelchairContent,
};

/// How long a chair has to answer a query for its goal.
pub const GOAL_QUERY_WAIT: Duration = Duration::from_secs(10);

/// What a chair's cognitive agent said when asked for the goal it is carrying out.
#[derive(Debug, Clone, PartialEq)]
pub enum GoalAnswer {
    /// Its goal under way, and the last that ended and was not told before (with its
    /// outcome), each if it has one.
    Told {
        /// Under way.
        goal: Option<Box<GoalInFlight>>,
        /// Ended.
        ended: Option<Box<GoalInFlight>>,
    },
    /// No answer within [`GOAL_QUERY_WAIT`] (it may not reach this container yet).
    Silent,
    /// An answer that tells nothing (a refusal, not understood, unreadable): why.
    Unusable(String),
}

/// An answer the console received about one goal.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GoalEvent {
    /// The conversation (one per goal).
    pub conversation: String,
    /// The answering agent.
    pub from: String,
    /// AGREE, INFORM (done), FAILURE, REFUSE, NOT-UNDERSTOOD.
    pub performative: String,
    /// When, s of simulated time.
    pub time_s: f64,
    /// The `error-message` of a FAILURE or REFUSE, if it carries one.
    pub reason: Option<String>,
}

/// The reason of an `(error-message "...")` fact (the wheelchair ontology's), as the platform's
/// agents explain a FAILURE or REFUSE.
fn error_message(message: &AclMessage) -> Option<String> {
    WheelchairContent::from_message(message)
        .ok()?
        .reason()
        .map(str::to_string)
}

/// What the fleet and the console agent share.
#[derive(Debug, Default)]
pub struct Desk {
    /// Goals waiting for the console's next tick: conversation, chair, place.
    pub outbox: VecDeque<(String, String, String)>,
    /// Answers, in arrival order.
    pub events: Vec<GoalEvent>,
    /// Chairs whose pose the console subscribes to (their perception agent must be reachable).
    pub watch: BTreeSet<String>,
    /// Watched chairs whose subscription must be sent again: their perception agent restarted
    /// and lost it, possibly without ever leaving the watch list between two ticks.
    pub resubscribe: BTreeSet<String>,
    /// The last pose each watched chair published: x (m), y (m), heading (rad), map frame.
    pub poses: BTreeMap<String, [f64; 3]>,
    /// Drive commands waiting for the console's next tick, the newest per chair: linear (m/s),
    /// angular (rad/s); a stop ends the chair's drive conversation.
    pub drives: BTreeMap<String, (f64, f64)>,
    /// A screen shows the watched chairs as their users see them: the console also subscribes
    /// to their sonar readings and to what their control agents apply while driven by hand.
    pub screen: bool,
    /// The last sonar ranges each watched chair published, m, in the body's sonar order
    /// (with [`Desk::screen`]).
    pub sonar: BTreeMap<String, Vec<f64>>,
    /// What shared control last applied to each chair driven by hand: linear (m/s), angular
    /// (rad/s), and when it was told, s of the bus clock (with [`Desk::screen`]).
    pub applied: BTreeMap<String, ([f64; 2], f64)>,
    /// Chairs whose cognitive agent the console is to ask for the goal it carries out.
    pub goal_queries: BTreeSet<String>,
    /// What the chairs asked answered, in arrival order.
    pub current_goals: Vec<(String, GoalAnswer)>,
}

/// The shared desk handle.
pub type SharedDesk = Arc<Mutex<Desk>>;

/// Locks the desk (a panicked holder leaves it usable).
pub fn desk(shared: &SharedDesk) -> std::sync::MutexGuard<'_, Desk> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Sends the desk's goals to the assistant every 50 ms and records the answers.
pub struct Console {
    desk: SharedDesk,
    assistant: AgentId,
    /// Chairs whose pose subscription was sent.
    subscribed: BTreeSet<String>,
    /// The goals given to the assistant, each a fipa-request.
    goals: Initiated<()>,
    /// The pose, reading and drive-applied subscriptions, each with its chair.
    subscriptions: Initiated<String>,
    /// The drive streams to chairs' interface agents, one per hold, each with its chair.
    streams: Initiated<String>,
    /// The drive conversation of each chair being driven from the desk.
    driving: BTreeMap<String, String>,
    /// Drive conversations started so far.
    holds: u64,
    /// The queries for chairs' goals under way, each with its chair.
    queries: Initiated<String>,
}

impl Console {
    /// A console working from `desk`, talking to `assistant`.
    pub fn new(desk: SharedDesk, assistant: AgentId) -> Self {
        Console {
            desk,
            assistant,
            subscribed: BTreeSet::new(),
            goals: Initiated::new(),
            subscriptions: Initiated::new(),
            streams: Initiated::new(),
            driving: BTreeMap::new(),
            holds: 0,
            queries: Initiated::new(),
        }
    }

    fn record(
        &self,
        ctx: &Context<'_>,
        conversation: String,
        from: String,
        performative: Performative,
        reason: Option<String>,
    ) {
        let time_s = ctx.now().0 as f64 * 1e-9;
        desk(&self.desk).events.push(GoalEvent {
            conversation,
            from,
            performative: performative.to_string(),
            time_s,
            reason,
        });
    }
}

impl Agent for Console {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if let Some(answer) = self.subscriptions.handle(ctx, &message) {
            match answer {
                Ok(Progress::Continues(_)) if message.performative == Performative::Inform => {
                    self.on_notification(ctx, &message);
                }
                Ok(Progress::Ended(event, chair)) => {
                    tracing::debug!(%chair, kind = ?event.kind, "a subscription ended");
                }
                Ok(Progress::Continues(_)) => {}
                Err(err) => tracing::debug!(error = %err, "out-of-protocol notification"),
            }
            return;
        }
        if let Some(answer) = self.queries.handle(ctx, &message) {
            match answer {
                Ok(Progress::Ended(event, chair)) => {
                    let told = match (event.kind, WheelchairContent::from_message(&message)) {
                        (
                            EventKind::Informed,
                            Ok(WheelchairContent::Inform(Fact::CurrentGoal {
                                goal, ended, ..
                            })),
                        ) => GoalAnswer::Told { goal, ended },
                        (_, content) => GoalAnswer::Unusable(format!(
                            "{} {}",
                            message.performative,
                            content.map_or_else(
                                |e| e.to_string(),
                                |c| c.reason().map_or_else(|| format!("{c:?}"), str::to_string)
                            )
                        )),
                    };
                    desk(&self.desk).current_goals.push((chair, told));
                }
                Ok(Progress::Continues(_)) => {}
                Err(err) => tracing::debug!(error = %err, "out-of-protocol answer to a goal query"),
            }
            return;
        }
        if let Some(answer) = self.streams.handle(ctx, &message) {
            if let Ok(Progress::Ended(event, chair)) = answer {
                // the interface agent refused or ended the hold: the next drive starts anew
                tracing::info!(%chair, kind = ?event.kind, reason = ?error_message(&message), "drive stream ended");
                if self.driving.get(&chair) == message.conversation_id.as_ref() {
                    self.driving.remove(&chair);
                }
            }
            return;
        }
        let Some(answer) = self.goals.handle(ctx, &message) else {
            tracing::debug!(performative = %message.performative, "a message in no conversation of ours");
            return;
        };
        if let Err(err) = answer {
            tracing::debug!(error = %err, "out-of-protocol answer about a goal");
            return;
        }
        let conversation = message.conversation_id.clone().unwrap_or_default();
        let from = message
            .sender
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default();
        self.record(
            ctx,
            conversation,
            from,
            message.performative,
            error_message(&message),
        );
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let (pending, watch, again, drives, screen, ask) = {
            let mut desk = desk(&self.desk);
            let again = std::mem::take(&mut desk.resubscribe);
            for (_, chair) in self.queries.expire(ctx.now()) {
                desk.current_goals.push((chair, GoalAnswer::Silent));
            }
            (
                desk.outbox.drain(..).collect::<Vec<_>>(),
                desk.watch.clone(),
                again,
                std::mem::take(&mut desk.drives),
                desk.screen,
                std::mem::take(&mut desk.goal_queries),
            )
        };
        for chair in ask {
            self.ask_goal(ctx, chair);
        }
        for (chair, (linear_mps, angular_radps)) in drives {
            self.drive(ctx, &chair, linear_mps, angular_radps);
        }
        // A chair that left or restarted is subscribed to again when it is back.
        self.subscribed
            .retain(|c| watch.contains(c) && !again.contains(c));
        let me = ctx.name().to_string();
        for chair in watch.difference(&self.subscribed.clone()) {
            let subscribe = |to: &str, conversation: &str, topics: &[Topic]| {
                Subscription::to(topics.iter().copied()).fill(
                    AclMessage::new(Performative::Subscribe)
                        .with_receiver(AgentId::new(format!("{to}@{chair}")))
                        .with_conversation_id(format!("{conversation}-{chair}-{me}")),
                )
            };
            let poses = if screen {
                subscribe("perception", "pose", &[Topic::AtPose, Topic::SensorReading])
            } else {
                subscribe("perception", "pose", &[Topic::AtPose])
            };
            let opened = self
                .subscriptions
                .open(ctx, Protocol::Subscribe, poses, chair.clone());
            if opened.is_ok() {
                self.subscribed.insert(chair.clone());
                if screen {
                    let applied = subscribe("control", "applied", &[Topic::DriveApplied]);
                    if let Err(err) =
                        self.subscriptions
                            .open(ctx, Protocol::Subscribe, applied, chair.clone())
                    {
                        tracing::warn!(chair, error = %err, "could not subscribe to drive-applied");
                    }
                }
            }
        }
        for (conversation, chair, place) in pending {
            let request = WheelchairContent::Request {
                actor: AgentId::new(chair),
                action: WheelchairAction::GoTo { place },
            }
            .fill(
                AclMessage::new(Performative::Request)
                    .with_receiver(self.assistant.clone())
                    .with_conversation_id(conversation.clone()),
            );
            if self
                .goals
                .open(ctx, Protocol::Request, request, ())
                .is_err()
            {
                let me = ctx.name().to_string();
                self.record(
                    ctx,
                    conversation,
                    me,
                    Performative::Failure,
                    Some("the request could not be sent".into()),
                );
            }
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_millis(50))
    }
}

impl Console {
    /// Asks `chair`'s cognitive agent for the goal it carries out (answered by
    /// [`GOAL_QUERY_WAIT`]); the answer goes to [`Desk::current_goals`].
    fn ask_goal(&mut self, ctx: &mut Context<'_>, chair: String) {
        let cognitive = AgentId::new(format!("cognitive@{chair}"));
        let by_ms = ctx.now().as_ns() / 1_000_000 + GOAL_QUERY_WAIT.as_millis() as u64;
        let query = WheelchairContent::GoalQuery {
            agent: cognitive.clone(),
        }
        .fill(
            AclMessage::new(Performative::QueryRef)
                .with_receiver(cognitive)
                .with_conversation_id(format!("goal-query-{chair}-{}-{by_ms}", ctx.name()))
                .with_reply_by(FipaDateTime::from_unix_ms(
                    i64::try_from(by_ms).unwrap_or(i64::MAX),
                )),
        );
        if let Err(err) = self
            .queries
            .open(ctx, Protocol::Query, query, chair.clone())
        {
            let why = format!("the query could not be sent: {err}");
            desk(&self.desk)
                .current_goals
                .push((chair, GoalAnswer::Unusable(why)));
        }
    }

    /// A subscription's INFORM: a chair's pose, sonar reading or what its control applied.
    fn on_notification(&self, ctx: &Context<'_>, message: &AclMessage) {
        match WheelchairContent::from_message(message) {
            Ok(WheelchairContent::Inform(Fact::AtPose { agent, pose })) => {
                let pose = [pose.x_m, pose.y_m, pose.theta_rad];
                desk(&self.desk).poses.insert(agent.name, pose);
            }
            Ok(WheelchairContent::Inform(Fact::Reading {
                agent,
                reading: SensorReading::Sonar { ranges_m },
            })) => {
                desk(&self.desk).sonar.insert(agent.name, ranges_m);
            }
            Ok(WheelchairContent::Inform(Fact::Applied {
                agent,
                linear_mps,
                angular_radps,
            })) => {
                // the control agent of the chair that is its container
                if let Some((_, chair)) = agent.name.split_once('@') {
                    let at_s = ctx.now().0 as f64 * 1e-9;
                    desk(&self.desk)
                        .applied
                        .insert(chair.to_string(), ([linear_mps, angular_radps], at_s));
                }
            }
            Ok(other) => tracing::debug!(?other, "a notification of another kind"),
            Err(err) => tracing::debug!(error = %err, "an unreadable notification"),
        }
    }

    /// Sends `chair`'s interface agent one `drive` of the hold in progress (a new conversation
    /// for a new hold); a stop ends the hold.
    fn drive(&mut self, ctx: &mut Context<'_>, chair: &str, linear_mps: f64, angular_radps: f64) {
        let stop = linear_mps == 0.0 && angular_radps == 0.0;
        let interface = AgentId::new(format!("interface@{chair}"));
        let request = WheelchairContent::Request {
            actor: interface.clone(),
            action: WheelchairAction::Drive {
                linear_mps,
                angular_radps,
            },
        }
        .fill(AclMessage::new(Performative::Request).with_receiver(interface));
        let sent = match self.driving.get(chair).cloned() {
            Some(id) => {
                let sent = self.streams.stream(ctx, &id, &request).map(|_| ());
                if stop {
                    // the hold is over here; the interface agent answers no more
                    self.driving.remove(chair);
                    self.streams.forget(&id);
                }
                sent
            }
            // a stop outside a hold has nothing to end
            None if stop => return,
            None => {
                self.holds += 1;
                let id = format!("drive-{chair}-{}-{}", ctx.name(), self.holds);
                self.driving.insert(chair.to_string(), id.clone());
                let request = request.with_conversation_id(id);
                self.streams
                    .open(ctx, Protocol::Request, request, chair.to_string())
                    .map(|_| ())
            }
        };
        if let Err(err) = sent {
            tracing::warn!(chair, error = %err, "could not relay a drive command");
        }
    }
}
