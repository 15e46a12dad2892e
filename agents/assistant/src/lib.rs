//! The assistant agent: staff give a global goal to any chair; the assistant forwards it to that
//! chair's cognitive agent and relays the outcome.
//!
//! Organization: [`AssistantConfig`] (chair name to its cognitive agent, who counts as staff)
//! and [`AssistantAgent::new`].
//!
//! # Messages
//! All `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`, `:protocol fipa-request`.
//! - From staff: REQUEST `((action (agent-identifier :name CHAIR) (go-to :place P)))`, the actor
//!   being the chair's name. REFUSE `((error-message "..."))` when the chair is unknown or the
//!   sender is not staff; otherwise AGREE, then the cognitive agent's final INFORM (done) or
//!   FAILURE relayed in the staff's conversation. Non go-to actions are refused.
//! - To the cognitive agent: REQUEST `((action COGNITIVE (go-to :place P)))` in a fresh
//!   conversation `assist-N`; its AGREE is absorbed, its REFUSE relayed.
//! - At setup, to its platform's DF (`df@PLATFORM`, `:ontology FIPA-Agent-Management`): a
//!   registration of service [`SERVICE_NAME`] of type [`SERVICE_TYPE`], so other platforms'
//!   agents (JADE's) find it with a DF search; the DF's answers are absorbed.
#![warn(missing_docs)]

use std::collections::{BTreeMap, BTreeSet};

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_ontology::OntologyContent;
use iw_ontology::fipa::{
    AgentDescription, DfAgentDescription, ManagementAction, ManagementContent, ManagementRequest,
    ServiceDescription,
};
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
    /// Forwarded conversation id to the staff request it serves.
    forwarded: BTreeMap<String, AclMessage>,
    conversations: u64,
}

impl AssistantAgent {
    /// An assistant for `config.chairs`.
    pub fn new(config: AssistantConfig) -> Self {
        AssistantAgent {
            config,
            forwarded: BTreeMap::new(),
            conversations: 0,
        }
    }

    fn on_staff_request(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let refuse = |ctx: &mut Context<'_>, why: &str| {
            let _ = ctx.refuse(&message, why);
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
        self.conversations += 1;
        let conversation = format!("assist-{}", self.conversations);
        let goal = WheelchairContent::Request {
            actor: cognitive.clone(),
            action: WheelchairAction::GoTo { place },
        };
        let forward = goal.fill(
            AclMessage::new(Performative::Request)
                .with_receiver(cognitive)
                .with_protocol("fipa-request")
                .with_conversation_id(conversation.clone()),
        );
        let _ = ctx.send(forward);
        let agree = message
            .create_reply()
            .with_performative(Performative::Agree);
        let _ =
            ctx.send(agree.with_content(message.content_text().unwrap_or_default().to_string()));
        self.forwarded.insert(conversation, message);
    }

    fn on_answer(&mut self, ctx: &mut Context<'_>, message: &AclMessage) {
        let Some(conversation) = message.conversation_id.clone() else {
            return;
        };
        if message.performative == Performative::Agree {
            return;
        }
        let Some(staff) = self.forwarded.remove(&conversation) else {
            tracing::debug!(conversation, "answer for no forwarded goal");
            return;
        };
        let mut relay = staff.create_reply().with_performative(message.performative);
        if let Some(text) = message.content_text() {
            relay = relay.with_content(text.to_string());
        }
        let _ = ctx.send(relay);
    }
}

impl Agent for AssistantAgent {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        let Some(platform) = ctx.aid().platform().map(str::to_owned) else {
            return;
        };
        let df = AgentId::new(format!("df@{platform}"));
        let description = DfAgentDescription {
            name: Some(ctx.aid().clone()),
            services: vec![ServiceDescription {
                name: Some(SERVICE_NAME.into()),
                service_type: Some(SERVICE_TYPE.into()),
                ..ServiceDescription::default()
            }],
            ..DfAgentDescription::default()
        };
        let register = ManagementContent::Request(ManagementRequest {
            actor: df.clone(),
            action: ManagementAction::Register {
                description: AgentDescription::Df(description),
            },
        });
        let request = AclMessage::new(Performative::Request)
            .with_receiver(df)
            .with_protocol("fipa-request")
            .with_conversation_id(format!("df-register-{}", ctx.name()));
        // Without the DF the assistant still works; only foreign platforms cannot find it.
        if let Err(err) = ctx.send(register.fill(request)) {
            tracing::warn!(error = %err, "could not register with the DF");
        }
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Request => self.on_staff_request(ctx, message),
            Performative::Agree
            | Performative::Inform
            | Performative::Failure
            | Performative::Refuse
            | Performative::NotUnderstood => self.on_answer(ctx, &message),
            _ => {
                let _ =
                    ctx.not_understood(&message, "the assistant takes go-to requests from staff");
            }
        }
    }
}
