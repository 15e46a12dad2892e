//! A gateway agent: code outside the agent world (a test, the CLI, a web page) sends and receives
//! ACL messages as an ordinary agent, as JADE's `JadeGateway` does.
//!
//! The agent lives in an [`AgentHost`](crate::AgentHost) like any other; the [`GatewayHandle`]
//! stays with the outside code. Messages queued on the handle leave at the agent's next tick, so
//! they obey the same bus, layers and routing as every agent's messages.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use iw_acl::AclMessage;

use crate::{Agent, AgentError, Context};

#[derive(Default)]
struct Queues {
    inbox: Vec<AclMessage>,
    outbox: Vec<AclMessage>,
    send_errors: Vec<AgentError>,
}

/// The agent half: add it to a host under the name the outside code speaks as.
pub struct GatewayAgent {
    queues: Arc<Mutex<Queues>>,
    period: Duration,
}

/// The outside half: queue messages to send, take the messages received.
#[derive(Clone)]
pub struct GatewayHandle {
    queues: Arc<Mutex<Queues>>,
}

/// A gateway agent polling its outbox every `period`, and the handle that drives it.
pub fn gateway(period: Duration) -> (GatewayAgent, GatewayHandle) {
    let queues = Arc::new(Mutex::new(Queues::default()));
    (
        GatewayAgent {
            queues: Arc::clone(&queues),
            period,
        },
        GatewayHandle { queues },
    )
}

fn lock(queues: &Mutex<Queues>) -> std::sync::MutexGuard<'_, Queues> {
    // The queues hold plain data: a panic elsewhere cannot leave them half-updated.
    queues.lock().unwrap_or_else(PoisonError::into_inner)
}

impl GatewayHandle {
    /// Queues `message`; the gateway agent sends it (as itself) at its next tick.
    pub fn send(&self, message: AclMessage) {
        lock(&self.queues).outbox.push(message);
    }

    /// Every message received since the last call, in arrival order.
    pub fn take_received(&self) -> Vec<AclMessage> {
        std::mem::take(&mut lock(&self.queues).inbox)
    }

    /// Sends the platform refused since the last call (no route, no receiver, ...).
    pub fn take_send_errors(&self) -> Vec<AgentError> {
        std::mem::take(&mut lock(&self.queues).send_errors)
    }
}

impl Agent for GatewayAgent {
    fn handle(&mut self, _ctx: &mut Context<'_>, message: AclMessage) {
        lock(&self.queues).inbox.push(message);
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(self.period)
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let outbox = std::mem::take(&mut lock(&self.queues).outbox);
        for message in outbox {
            if let Err(error) = ctx.send(message) {
                lock(&self.queues).send_errors.push(error);
            }
        }
    }
}
