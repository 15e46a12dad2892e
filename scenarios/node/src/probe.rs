//! The services' REQUEST/AGREE round trip to a chair, measured where it happens: the assistant
//! forwards a staff goal as a `fipa-request` to the chair's cognitive agent (seen by the host's
//! tap as it is sent) and the chair answers AGREE (seen as the assistant is handed it). The
//! times are real time, so the figure includes each end's wait for its next agent step.
//! `intellwheels bench fleet` reads it from the `agreed` events.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use iw_acl::{AclMessage, Performative};
use iw_agent::{Agent, Context};

/// Forwarded requests not answered after this long are forgotten (the chair is gone).
const FORGET_AFTER: Duration = Duration::from_secs(60);

/// Requests in flight and measured round trips, shared by the tap and the wrapped assistant.
#[derive(Debug, Default)]
pub(crate) struct AgreeProbe {
    /// Conversation of each forwarded request: the chair and when it was sent.
    in_flight: BTreeMap<String, (String, Instant)>,
    /// Round trips measured and not yet reported: chair, ms.
    measured: Vec<(String, f64)>,
}

/// The shared probe.
pub(crate) type SharedProbe = Arc<Mutex<AgreeProbe>>;

fn lock(probe: &SharedProbe) -> std::sync::MutexGuard<'_, AgreeProbe> {
    probe.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The chair a message's receiver names when it is a cognitive agent.
fn cognitive_chair(name: &str) -> Option<&str> {
    name.strip_prefix("cognitive@")
}

impl AgreeProbe {
    /// Notes a REQUEST sent to a chair's cognitive agent (called from the host's tap).
    pub(crate) fn on_sent(probe: &SharedProbe, message: &AclMessage) {
        if message.performative != Performative::Request {
            return;
        }
        let (Some(conversation), Some(chair)) = (
            message.conversation_id.as_ref(),
            message
                .receivers
                .first()
                .and_then(|r| cognitive_chair(&r.name)),
        ) else {
            return;
        };
        let now = Instant::now();
        let mut probe = lock(probe);
        probe
            .in_flight
            .retain(|_, (_, at)| now.duration_since(*at) < FORGET_AFTER);
        probe
            .in_flight
            .insert(conversation.clone(), (chair.to_string(), now));
    }

    /// Round trips measured since the last call: chair, ms.
    pub(crate) fn take(probe: &SharedProbe) -> Vec<(String, f64)> {
        std::mem::take(&mut lock(probe).measured)
    }
}

/// An agent whose incoming AGREEs to forwarded requests close a round trip; it is otherwise the
/// agent it wraps.
pub(crate) struct Timed {
    pub(crate) inner: Box<dyn Agent>,
    pub(crate) probe: SharedProbe,
}

impl Agent for Timed {
    fn setup(&mut self, ctx: &mut Context<'_>) {
        self.inner.setup(ctx);
    }

    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        if message.performative == Performative::Agree
            && let Some(conversation) = &message.conversation_id
        {
            let mut probe = lock(&self.probe);
            if let Some((chair, sent)) = probe.in_flight.remove(conversation) {
                let ms = sent.elapsed().as_secs_f64() * 1e3;
                probe.measured.push((chair, ms));
            }
        }
        self.inner.handle(ctx, message);
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        self.inner.tick(ctx);
    }

    fn tick_period(&self) -> Option<Duration> {
        self.inner.tick_period()
    }

    fn take_down(&mut self, ctx: &mut Context<'_>) {
        self.inner.take_down(ctx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_acl::AgentId;

    #[test]
    fn only_requests_to_a_cognitive_agent_are_timed() {
        let probe = SharedProbe::default();
        let message = |p: Performative, to: &str, conversation: &str| {
            AclMessage::new(p)
                .with_receiver(AgentId::new(to))
                .with_conversation_id(conversation)
        };
        AgreeProbe::on_sent(
            &probe,
            &message(Performative::Request, "cognitive@chair-1", "a-1"),
        );
        AgreeProbe::on_sent(
            &probe,
            &message(Performative::Request, "door@services", "a-2"),
        );
        AgreeProbe::on_sent(
            &probe,
            &message(Performative::Inform, "cognitive@chair-2", "a-3"),
        );
        let in_flight: Vec<(String, String)> = lock(&probe)
            .in_flight
            .iter()
            .map(|(c, (chair, _))| (c.clone(), chair.clone()))
            .collect();
        assert_eq!(in_flight, [("a-1".to_string(), "chair-1".to_string())]);
        assert!(AgreeProbe::take(&probe).is_empty());
    }
}
