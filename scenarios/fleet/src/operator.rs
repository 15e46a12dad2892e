//! The operator agent of the service container: staff give a chair a goal (the assistant's
//! role), it sends the control agent a `fipa-request` with the planned action sequence and
//! records the answers.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::{AclMessage, Performative};
use iw_agent::{Agent, Context};

/// An answer the operator received about one goal.
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
}

/// What the fleet and the operator agent share.
#[derive(Debug, Default)]
pub struct Desk {
    /// Requests waiting for the operator's next tick.
    pub outbox: VecDeque<AclMessage>,
    /// Answers, in arrival order.
    pub events: Vec<GoalEvent>,
}

/// The shared desk handle.
pub type SharedDesk = Arc<Mutex<Desk>>;

pub(crate) fn desk(shared: &SharedDesk) -> std::sync::MutexGuard<'_, Desk> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Sends what the desk holds, every 50 ms.
pub struct Operator {
    desk: SharedDesk,
}

impl Operator {
    /// An operator working from `desk`.
    pub fn new(desk: SharedDesk) -> Self {
        Operator { desk }
    }
}

impl Agent for Operator {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let event = GoalEvent {
            conversation: message.conversation_id.clone().unwrap_or_default(),
            from: message.sender.as_ref().map(|s| s.name.clone()).unwrap_or_default(),
            performative: message.performative.to_string(),
            time_s: ctx.now().0 as f64 * 1e-9,
        };
        desk(&self.desk).events.push(event);
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let pending: Vec<AclMessage> = desk(&self.desk).outbox.drain(..).collect();
        for message in pending {
            if ctx.send(message.clone()).is_err() {
                let event = GoalEvent {
                    conversation: message.conversation_id.unwrap_or_default(),
                    from: ctx.name().to_string(),
                    performative: Performative::Failure.to_string(),
                    time_s: ctx.now().0 as f64 * 1e-9,
                };
                desk(&self.desk).events.push(event);
            }
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_millis(50))
    }
}
