//! The assistant agent: staff give a global goal to any chair; the assistant forwards it to that
//! chair's cognitive agent and relays the outcome.
//!
//! Organization: [`AssistantConfig`] (chair name to its cognitive agent, who counts as staff)
//! and [`AssistantAgent::new`].
//!
//! # Messages
//! All `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`, `:protocol fipa-request`, both
//! conversations run by the protocol's state machine (`iw-interaction`).
//! - From staff: REQUEST `((action (agent-identifier :name CHAIR) (go-to :place P)))`, the actor
//!   being the chair's name. REFUSE `((error-message "..."))` when the chair is unknown or the
//!   sender is not staff; otherwise AGREE, then the cognitive agent's final INFORM (done) or
//!   FAILURE relayed in the staff's conversation. Non go-to actions are refused.
//! - To the cognitive agent: REQUEST `((action COGNITIVE (go-to :place P)))` in a fresh
//!   conversation; its AGREE is absorbed, and its REFUSE relayed to staff as a FAILURE with the
//!   same reason (the assistant has already agreed, so fipa-request allows no REFUSE). The id
//!   (`ME-T-N`) carries the time the assistant started, so the answer to a goal forwarded by an
//!   earlier life of the assistant (its container restarted) is never taken for one of its own.
//! - To the cognitive agent, for a forwarded goal it has not answered for [`GOAL_CHECK`]:
//!   QUERY-REF `((current-goal COGNITIVE ?goal))` (`fipa-query`), again every [`GOAL_CHECK`]
//!   while it stays unanswered. The chair's answer says whether the goal is still under way
//!   (nothing to do), ended in the forward's conversation (its outcome is relayed to staff as if
//!   the chair's INFORM or FAILURE had come: that answer was lost on the way, e.g. a send that
//!   failed for want of a route, or a frame given up after its last retransmission), or is
//!   unknown to it
//!   (relayed as a FAILURE that says so). So a goal the assistant agreed to ends, for staff, in
//!   an INFORM or a FAILURE with a reason within a bounded time after the chair's own end,
//!   whichever hop lost the chair's answer. A chair that does not answer the query is asked
//!   again; one that is gone is the services' matter (its agents `left`).
//! - At setup, to its platform's DF (`df@PLATFORM`, `:ontology FIPA-Agent-Management`): a
//!   registration of service [`SERVICE_NAME`] of type [`SERVICE_TYPE`], so other platforms'
//!   agents (JADE's) find it with a DF search; the DF's answers are absorbed.
#![warn(missing_docs)]

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, FipaDateTime, Performative};
use iw_agent::conversation::answers_a_conversation;
use iw_agent::{Agent, Context, EventKind, Initiated, Progress, Protocol, Responder};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{Fact, GoalInFlight, WheelchairAction, WheelchairContent};

/// How long a forwarded goal may go without a word from its chair before the assistant asks
/// the chair about it (and the period of those queries, each given as long to be answered).
/// A goal runs for minutes; a query every 10 s per unanswered goal costs next to nothing.
pub const GOAL_CHECK: Duration = Duration::from_secs(10);

/// The service the assistant registers with its platform's DF.
pub const SERVICE_NAME: &str = "wheelchair-assistant";
/// The type of [`SERVICE_NAME`]: giving chairs go-to goals.
pub const SERVICE_TYPE: &str = "wheelchair-goals";

/// Which chairs exist and who may direct them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssistantConfig {
    /// Chair name to its cognitive agent.
    pub chairs: BTreeMap<String, AgentId>,
    /// Agent names allowed to give goals; empty means anyone.
    pub staff: BTreeSet<String>,
}

/// The assistant agent.
pub struct AssistantAgent {
    config: AssistantConfig,
    /// Goals forwarded to a cognitive agent, each with the staff conversation it serves.
    forwarded: Initiated<Responder>,
    /// The registration with the platform's DF.
    registration: Initiated<()>,
    /// When this life of the assistant started (ms of the bus clock), and the goals forwarded
    /// since: the forwards' conversation ids.
    life: (u64, u64),
    /// Per forwarded goal not answered for good (by the forward's conversation): its chair's
    /// cognitive agent, its place, and when it is to be asked about it (bus ns).
    checks: BTreeMap<String, Check>,
    /// Queries about forwarded goals under way, each with the forward's conversation.
    queries: Initiated<String>,
}

/// A forwarded goal the assistant asks its chair about when it goes unanswered.
struct Check {
    cognitive: AgentId,
    place: String,
    due_ns: u64,
    /// The chair has been asked about it before: told at the first check, not at every one.
    asked: bool,
    /// The chair could not be asked last time (a killed chair until it is back): warned once,
    /// not at every check.
    unreachable: bool,
}

impl AssistantAgent {
    /// An assistant for `config.chairs`.
    pub fn new(config: AssistantConfig) -> Self {
        AssistantAgent {
            config,
            forwarded: Initiated::new(),
            registration: Initiated::new(),
            life: (0, 0),
            checks: BTreeMap::new(),
            queries: Initiated::new(),
        }
    }

    fn on_staff_request(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let Some(mut staff) = ctx.accept(&message) else {
            return;
        };
        let mut refuse = |ctx: &mut Context<'_>, why: &str| {
            let _ = ctx.answer_error(&mut staff, Performative::Refuse, why);
        };
        let sender = message
            .sender
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default();
        if !self.config.staff.is_empty() && !self.config.staff.contains(&sender) {
            refuse(ctx, &format!("`{sender}` is not staff"));
            return;
        }
        let (chair, place) = match WheelchairContent::from_message(&message) {
            Ok(WheelchairContent::Request {
                actor,
                action: WheelchairAction::GoTo { place },
            }) => (actor.name, place),
            Ok(_) => {
                refuse(ctx, "the assistant forwards go-to goals only");
                return;
            }
            Err(err) => {
                let _ = ctx.not_understood(&message, &err.to_string());
                return;
            }
        };
        let Some(cognitive) = self.config.chairs.get(&chair).cloned() else {
            refuse(ctx, &format!("unknown chair `{chair}`"));
            return;
        };
        let goal = WheelchairContent::Request {
            actor: cognitive.clone(),
            action: WheelchairAction::GoTo {
                place: place.clone(),
            },
        };
        self.life.1 += 1;
        let conversation = format!("{}-{}-{}", ctx.name(), self.life.0, self.life.1);
        let forward = goal.fill(
            AclMessage::new(Performative::Request)
                .with_receiver(cognitive.clone())
                .with_conversation_id(conversation),
        );
        let agreed = WheelchairContent::Request {
            actor: AgentId::new(chair),
            action: WheelchairAction::GoTo {
                place: place.clone(),
            },
        };
        if let Err(err) = ctx.answer(&mut staff, Performative::Agree, &agreed) {
            tracing::warn!(error = %err, "could not agree to a staff goal");
            return;
        }
        match self
            .forwarded
            .open(ctx, Protocol::Request, forward, staff.clone())
        {
            Ok(conversation) => {
                let check = Check {
                    cognitive,
                    place,
                    due_ns: due(ctx),
                    asked: false,
                    unreachable: false,
                };
                self.checks.insert(conversation, check);
            }
            Err(err) => {
                let why = format!("could not forward the goal: {err}");
                let _ = ctx.answer_error(&mut staff, Performative::Failure, &why);
            }
        }
    }

    /// Relays the cognitive agent's outcome into the staff conversation: its result or failure
    /// as it came, and a refusal as a FAILURE (the assistant had already agreed).
    fn on_answer(&mut self, ctx: &mut Context<'_>, message: &AclMessage) -> bool {
        let Some(answer) = self.forwarded.handle(ctx, message) else {
            return false;
        };
        let conversation = message.conversation_id.as_deref().unwrap_or_default();
        if let Some(check) = self.checks.get_mut(conversation) {
            // the chair is heard from: the next check counts from now
            check.due_ns = due(ctx);
        }
        let (kind, mut staff) = match answer {
            Ok(Progress::Continues(_)) => return true,
            Ok(Progress::Ended(event, staff)) => {
                self.checks.remove(conversation);
                (event.kind, staff)
            }
            Err(err) => {
                tracing::debug!(error = %err, "out-of-protocol answer to a forwarded goal");
                return true;
            }
        };
        let relayed = match (kind, WheelchairContent::from_message(message)) {
            (EventKind::Informed, Ok(content)) => {
                ctx.answer(&mut staff, Performative::Inform, &content)
            }
            (EventKind::Failed | EventKind::Refused, Ok(content)) => {
                ctx.answer(&mut staff, Performative::Failure, &content)
            }
            (_, Ok(_)) | (_, Err(_)) => ctx.answer_error(
                &mut staff,
                Performative::Failure,
                &format!("the chair answered {}", message.performative),
            ),
        };
        if let Err(err) = relayed {
            tracing::warn!(error = %err, "could not relay a goal's outcome to staff");
        }
        true
    }

    /// Asks the chair about each forwarded goal unanswered for [`GOAL_CHECK`].
    fn check_goals(&mut self, ctx: &mut Context<'_>) {
        for (_, conversation) in self.queries.expire(ctx.now()) {
            tracing::debug!(%conversation, "a chair did not answer the query for its goal; asked again");
        }
        let now = ctx.now().as_ns();
        // each goal asked about now is asked again, or its query expires, at `next_ns`
        let next_ns = due(ctx);
        let asking: BTreeSet<String> = self.queries.iter().map(|(_, c)| c.clone()).collect();
        let due_now: Vec<(String, AgentId, (bool, bool))> = self
            .checks
            .iter()
            .filter(|(c, check)| now >= check.due_ns && !asking.contains(*c))
            .map(|(c, check)| {
                let state = (check.asked, check.unreachable);
                (c.clone(), check.cognitive.clone(), state)
            })
            .collect();
        for (conversation, cognitive, (asked, was_unreachable)) in due_now {
            let by_ms = next_ns / 1_000_000;
            let query = WheelchairContent::GoalQuery {
                agent: cognitive.clone(),
            }
            .fill(
                AclMessage::new(Performative::QueryRef)
                    .with_receiver(cognitive.clone())
                    .with_conversation_id(format!("{conversation}-check-{now}"))
                    .with_reply_by(FipaDateTime::from_unix_ms(
                        i64::try_from(by_ms).unwrap_or(i64::MAX),
                    )),
            );
            if asked {
                tracing::debug!(%conversation, chair = %cognitive.name, "still no answer to a forwarded goal: asking the chair again");
            } else {
                tracing::info!(%conversation, chair = %cognitive.name, "no answer to a forwarded goal for a while: asking the chair about it, again every check until it ends");
            }
            let unreachable = match self.queries.open(
                ctx,
                Protocol::Query,
                query,
                conversation.clone(),
            ) {
                Ok(_) if was_unreachable => {
                    tracing::info!(%conversation, chair = %cognitive.name, "the chair can be asked about its goal again");
                    false
                }
                Ok(_) => false,
                Err(err) if was_unreachable => {
                    tracing::debug!(%conversation, error = %err, "still cannot ask the chair about its goal");
                    true
                }
                Err(err) => {
                    tracing::warn!(%conversation, error = %err, "could not ask the chair about its goal; asking again every check, quietly until it can be asked");
                    true
                }
            };
            if let Some(check) = self.checks.get_mut(&conversation) {
                check.due_ns = next_ns;
                check.asked = true;
                check.unreachable = unreachable;
            }
        }
    }

    /// The chair's answer to a query about the forwarded goal `conversation`: a goal that ended
    /// there, or that the chair does not know, is answered to staff now (its own answer was
    /// lost); one still under way waits.
    fn on_check_answer(&mut self, ctx: &mut Context<'_>, message: &AclMessage, conversation: &str) {
        let Ok(WheelchairContent::Inform(Fact::CurrentGoal { goal, ended, .. })) =
            WheelchairContent::from_message(message)
        else {
            tracing::debug!(%conversation, performative = %message.performative, "no usable answer about a forwarded goal; asked again later");
            return;
        };
        let ours = |g: &Option<Box<GoalInFlight>>| {
            g.as_deref()
                .filter(|g| g.conversation == conversation)
                .cloned()
        };
        if ours(&goal).is_some() {
            return;
        }
        let (Some(mut staff), Some(check)) = (
            self.forwarded.forget(conversation),
            self.checks.remove(conversation),
        ) else {
            return;
        };
        let chair = check.cognitive.name.clone();
        let relayed = match ours(&ended).and_then(|g| g.outcome) {
            Some(Ok(())) => {
                tracing::warn!(%conversation, %chair, "the chair's INFORM (goal done) was lost on the way; relayed from its answer to a query");
                let done = WheelchairContent::Done {
                    actor: check.cognitive,
                    action: WheelchairAction::GoTo { place: check.place },
                };
                ctx.answer(&mut staff, Performative::Inform, &done)
            }
            Some(Err(why)) => {
                tracing::warn!(%conversation, %chair, "the chair's FAILURE was lost on the way; relayed from its answer to a query");
                ctx.answer_error(&mut staff, Performative::Failure, &why)
            }
            None => {
                let under_way = goal.map_or_else(
                    || "no goal".to_string(),
                    |g| format!("a goal to {} for {}", g.place, g.requester.name),
                );
                let why = format!(
                    "{chair} has no record of this goal (conversation {conversation}) and carries out {under_way}: its answer was lost, or it restarted"
                );
                tracing::warn!(%conversation, %chair, %why, "a forwarded goal ended unheard");
                ctx.answer_error(&mut staff, Performative::Failure, &why)
            }
        };
        if let Err(err) = relayed {
            tracing::warn!(error = %err, "could not relay a goal's outcome to staff");
        }
    }
}

/// When a forwarded goal heard from now is next asked about, bus ns.
fn due(ctx: &Context<'_>) -> u64 {
    ctx.now().plus(GOAL_CHECK).as_ns()
}

impl Agent for AssistantAgent {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        self.life.0 = ctx.now().as_ns() / 1_000_000;
        let Some(request) = ctx.df_registration(SERVICE_NAME, SERVICE_TYPE) else {
            return;
        };
        // Without the DF the assistant still works; only foreign platforms cannot find it.
        if let Err(err) = self.registration.open(ctx, Protocol::Request, request, ()) {
            tracing::warn!(error = %err, "could not register with the DF");
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_secs(1))
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        self.check_goals(ctx);
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if let Some(answer) = self.queries.handle(ctx, &message) {
            match answer {
                Ok(Progress::Ended(_, conversation)) => {
                    self.on_check_answer(ctx, &message, &conversation)
                }
                Ok(Progress::Continues(_)) => {}
                Err(err) => tracing::debug!(error = %err, "out-of-protocol answer to a goal query"),
            }
            return;
        }
        if let Some(answer) = self.registration.handle(ctx, &message) {
            match answer {
                Ok(Progress::Ended(event, ())) if event.kind != EventKind::Informed => {
                    tracing::warn!(kind = ?event.kind, "the DF did not register the assistant");
                }
                Ok(_) => {}
                Err(err) => tracing::debug!(error = %err, "out-of-protocol DF answer"),
            }
            return;
        }
        if self.on_answer(ctx, &message) {
            return;
        }
        match message.performative {
            Performative::Request => self.on_staff_request(ctx, message),
            act if answers_a_conversation(act) => {
                tracing::debug!(performative = %act, "answer in no conversation of ours");
            }
            _ => {
                let _ =
                    ctx.not_understood(&message, "the assistant takes go-to requests from staff");
            }
        }
    }
}
