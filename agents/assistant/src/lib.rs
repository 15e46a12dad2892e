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
//! - At setup, to its platform's DF (`df@PLATFORM`, `:ontology FIPA-Agent-Management`): a
//!   registration of service [`SERVICE_NAME`] of type [`SERVICE_TYPE`], so other platforms'
//!   agents (JADE's) find it with a DF search; the DF's answers are absorbed.
#![warn(missing_docs)]

use std::collections::{BTreeMap, BTreeSet};

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::conversation::answers_a_conversation;
use iw_agent::{Agent, Context, EventKind, Initiated, Progress, Protocol, Responder};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

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
}

impl AssistantAgent {
    /// An assistant for `config.chairs`.
    pub fn new(config: AssistantConfig) -> Self {
        AssistantAgent {
            config,
            forwarded: Initiated::new(),
            registration: Initiated::new(),
            life: (0, 0),
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
                .with_receiver(cognitive)
                .with_conversation_id(conversation),
        );
        let agreed = WheelchairContent::Request {
            actor: AgentId::new(chair),
            action: WheelchairAction::GoTo { place },
        };
        if let Err(err) = ctx.answer(&mut staff, Performative::Agree, &agreed) {
            tracing::warn!(error = %err, "could not agree to a staff goal");
            return;
        }
        if let Err(err) = self
            .forwarded
            .open(ctx, Protocol::Request, forward, staff.clone())
        {
            let why = format!("could not forward the goal: {err}");
            let _ = ctx.answer_error(&mut staff, Performative::Failure, &why);
        }
    }

    /// Relays the cognitive agent's outcome into the staff conversation: its result or failure
    /// as it came, and a refusal as a FAILURE (the assistant had already agreed).
    fn on_answer(&mut self, ctx: &mut Context<'_>, message: &AclMessage) -> bool {
        let Some(answer) = self.forwarded.handle(ctx, message) else {
            return false;
        };
        let (kind, mut staff) = match answer {
            Ok(Progress::Continues(_)) => return true,
            Ok(Progress::Ended(event, staff)) => (event.kind, staff),
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

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
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
