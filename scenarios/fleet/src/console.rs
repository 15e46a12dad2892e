//! The staff console of the service container (`staff@services`): what staff type at the desk
//! becomes a `fipa-request` to the assistant agent (`go-to` a place for a chair), and the
//! answers relayed back are recorded. It plans nothing: the chair's cognitive agent does.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_ontology::OntologyContent;
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

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

/// The text of `((error-message "..."))` content, as the platform's agents explain a FAILURE or
/// REFUSE.
fn error_message(message: &AclMessage) -> Option<String> {
    let content = iw_sl::parse(message.content_text()?, iw_sl::Level::Full).ok()?;
    content.expressions.into_iter().find_map(|e| match e {
        iw_sl::ContentExpression::Formula(iw_sl::Formula::Atomic {
            predicate,
            mut args,
        }) if predicate == "error-message" && args.len() == 1 => match args.pop() {
            Some(iw_sl::Term::Constant {
                value: iw_sl::Constant::String(text),
            }) => Some(text),
            _ => None,
        },
        _ => None,
    })
}

/// What the fleet and the console agent share.
#[derive(Debug, Default)]
pub struct Desk {
    /// Goals waiting for the console's next tick: conversation, chair, place.
    pub outbox: VecDeque<(String, String, String)>,
    /// Answers, in arrival order.
    pub events: Vec<GoalEvent>,
}

/// The shared desk handle.
pub type SharedDesk = Arc<Mutex<Desk>>;

pub(crate) fn desk(shared: &SharedDesk) -> std::sync::MutexGuard<'_, Desk> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Sends the desk's goals to the assistant every 50 ms and records the answers.
pub struct Console {
    desk: SharedDesk,
    assistant: AgentId,
}

impl Console {
    /// A console working from `desk`, talking to `assistant`.
    pub fn new(desk: SharedDesk, assistant: AgentId) -> Self {
        Console { desk, assistant }
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
        let pending: Vec<(String, String, String)> = desk(&self.desk).outbox.drain(..).collect();
        for (conversation, chair, place) in pending {
            let request = WheelchairContent::Request {
                actor: AgentId::new(chair),
                action: WheelchairAction::GoTo { place },
            }
            .fill(
                AclMessage::new(Performative::Request)
                    .with_receiver(self.assistant.clone())
                    .with_protocol("fipa-request")
                    .with_conversation_id(conversation.clone()),
            );
            if ctx.send(request).is_err() {
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
