//! The watcher agent: traffic control at doors and narrow passages. Chairs ask to pass a named
//! passage in a direction; the watcher lets chairs through one direction at a time (several
//! chairs may follow each other the same way, never meet head-on inside), first come first
//! served, and takes a grant back when its lease runs out, so a chair that never releases cannot
//! block the others.
//!
//! Organization: [`WatcherConfig`] (passages and lease), [`WatcherAgent::new`], [`WatcherError`].
//!
//! # Protocol: a grant is a subscription
//! A grant has a life after it is given (held, then released or taken back), and fipa-request
//! ends at its INFORM: a FAILURE "lease expired" after an INFORM done, as this agent once sent,
//! is outside the protocol. So a chair asks with **fipa-subscribe**, whose subscription is the
//! grant: the participant may notify with INFORM, the initiator may CANCEL (confirmed by
//! INFORM, FIPA's cancel meta-protocol), and the participant may end it with FAILURE at any
//! time. Each passage asked is
//! its own conversation, answered through `iw_agent::Responder`, so no act leaves this agent
//! that the protocol does not allow.
//!
//! # Messages
//! All `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`, `:protocol fipa-subscribe`.
//! - SUBSCRIBE `((action (agent-identifier :name W) (pass :passage P :direction D)))` (SL0 has
//!   no referential expressions, so the subscription names the action it waits for): AGREE at
//!   once, restating it (queued).
//! - INFORM `((done (action W (pass :passage P :direction D))))`: the notification that the
//!   passage is granted.
//! - CANCEL `((action W (pass :passage P :direction D)))` in that conversation (the chair is
//!   out, or gives up waiting): releases the grant or leaves the queue; confirmed with INFORM
//!   `((done (action W (cancel (action W (pass :passage P :direction D))))))` (the cancel
//!   meta-protocol's inform-done), which ends the subscription. A grant and a cancel can cross
//!   on the wire; the content tells the chair which INFORM it got.
//! - FAILURE `((error-message "lease expired"))`: the grant was held past the lease; it ends
//!   the subscription and the queue moves on.
//! - REFUSE for an unknown passage or a chair already holding or queued for it; NOT-UNDERSTOOD
//!   for any other content or act (a REQUEST to pass included).
//!
//! Guarantees: the chairs holding a passage at any time all cross it in the same direction
//! (property-tested, with each chair checking every answer against fipa-subscribe's state
//! machine); grants follow request order, so a chair waiting to go one way is never overtaken
//! by later chairs going the other way; every queued request is granted within (queue length x
//! lease).
#![warn(missing_docs)]

use std::collections::BTreeMap;
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context, Responder};
use iw_ontology::wheelchair::{WheelchairAction, WheelchairContent};

/// A configuration that cannot work.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WatcherError {
    /// The lease must be longer than zero.
    #[error("lease of passage grants must be positive, got {lease_ms} ms")]
    ZeroLease {
        /// The lease given.
        lease_ms: u128,
    },
}

/// The passages and how long a grant lasts.
#[derive(Debug, Clone, PartialEq)]
pub struct WatcherConfig {
    /// Names of the doors and narrow passages watched.
    pub passages: Vec<String>,
    /// A grant not released within this is taken back.
    pub lease: Duration,
    /// How often leases are checked.
    pub period: Duration,
}

/// A `pass` subscription: its conversation and what it asks.
struct Ask {
    responder: Responder,
    /// The agent the chair named to act (this watcher), restated in the answers.
    actor: AgentId,
    passage: String,
    direction: String,
}

impl Ask {
    /// `((done (action W (pass ...))))`: the grant.
    fn done(&self) -> WheelchairContent {
        WheelchairContent::Done {
            actor: self.actor.clone(),
            action: self.action(),
        }
    }

    /// `((done (action W (cancel (action W (pass ...))))))`: the confirmation of its cancel.
    fn cancelled(&self) -> WheelchairContent {
        WheelchairContent::Cancelled {
            actor: self.actor.clone(),
            action: self.action(),
        }
    }

    fn action(&self) -> WheelchairAction {
        WheelchairAction::Pass {
            passage: self.passage.clone(),
            direction: self.direction.clone(),
        }
    }

    fn chair(&self) -> Option<&str> {
        self.responder.initiator().map(|a| a.name.as_str())
    }
}

struct Grant {
    ask: Ask,
    since_ns: u64,
}

#[derive(Default)]
struct Passage {
    /// Chairs inside, all going one direction.
    holders: Vec<Grant>,
    /// Chairs waiting, first come first served.
    queue: Vec<Ask>,
}

impl Passage {
    fn involves(&self, chair: Option<&str>) -> bool {
        self.holders.iter().any(|g| g.ask.chair() == chair)
            || self.queue.iter().any(|q| q.chair() == chair)
    }
}

/// The watcher agent.
pub struct WatcherAgent {
    config: WatcherConfig,
    passages: BTreeMap<String, Passage>,
}

/// Takes out of `items` the subscriptions that `cancel` ends (its conversation and sender,
/// allowed now by fipa-subscribe), each confirmed with the INFORM done of the cancel.
fn cancelled<T>(
    ctx: &mut Context<'_>,
    items: &mut Vec<T>,
    ask: impl Fn(&mut T) -> &mut Ask,
    cancel: &AclMessage,
) {
    let ended: Vec<T> = items
        .extract_if(.., |item| ctx.continues(&mut ask(item).responder, cancel))
        .collect();
    for mut item in ended {
        let ask = ask(&mut item);
        let confirmation = ask.cancelled();
        let _ = ctx.answer(&mut ask.responder, Performative::Inform, &confirmation);
    }
}

impl WatcherAgent {
    /// A watcher over `config.passages`, all free.
    pub fn new(config: WatcherConfig) -> Result<Self, WatcherError> {
        if config.lease.is_zero() {
            return Err(WatcherError::ZeroLease {
                lease_ms: config.lease.as_millis(),
            });
        }
        let passages = config
            .passages
            .iter()
            .map(|p| (p.clone(), Passage::default()))
            .collect();
        Ok(WatcherAgent { config, passages })
    }

    /// Admits the head of each queue while it goes the way of the chairs already inside.
    fn grant(&mut self, ctx: &mut Context<'_>) {
        let now_ns = ctx.now().0;
        for (name, passage) in &mut self.passages {
            while let Some(head) = passage.queue.first() {
                if passage
                    .holders
                    .first()
                    .is_some_and(|g| g.ask.direction != head.direction)
                {
                    break;
                }
                let mut ask = passage.queue.remove(0);
                tracing::debug!(passage = %name, direction = %ask.direction, chair = ?ask.chair(), "granted");
                let done = ask.done();
                if let Err(err) = ctx.answer(&mut ask.responder, Performative::Inform, &done) {
                    tracing::warn!(passage = %name, error = %err, "grant not sent; the ask is dropped");
                    continue;
                }
                passage.holders.push(Grant {
                    ask,
                    since_ns: now_ns,
                });
            }
        }
    }

    fn on_subscribe(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let Some((actor, passage, direction)) = ctx.understand(
            &message,
            "the watcher takes subscriptions to ((action W (pass :passage P :direction D)))",
            |c| match c {
                WheelchairContent::Request {
                    actor,
                    action: WheelchairAction::Pass { passage, direction },
                } => Some((actor, passage, direction)),
                _ => None,
            },
        ) else {
            return;
        };
        let Some(responder) = ctx.accept(&message) else {
            return;
        };
        let mut ask = Ask {
            responder,
            actor,
            passage,
            direction,
        };
        let Some(passage) = self.passages.get_mut(&ask.passage) else {
            let _ = ctx.answer_error(&mut ask.responder, Performative::Refuse, "unknown passage");
            return;
        };
        if passage.involves(ask.chair()) {
            let _ = ctx.answer_error(
                &mut ask.responder,
                Performative::Refuse,
                "already holding or queued for this passage",
            );
            return;
        }
        let asked = WheelchairContent::Request {
            actor: ask.actor.clone(),
            action: ask.action(),
        };
        if ctx
            .answer(&mut ask.responder, Performative::Agree, &asked)
            .is_err()
        {
            return;
        }
        passage.queue.push(ask);
        self.grant(ctx);
    }

    fn on_cancel(&mut self, ctx: &mut Context<'_>, message: &AclMessage) {
        for passage in self.passages.values_mut() {
            cancelled(ctx, &mut passage.holders, |g| &mut g.ask, message);
            cancelled(ctx, &mut passage.queue, |q| q, message);
        }
        self.grant(ctx);
    }
}

impl Agent for WatcherAgent {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Subscribe => self.on_subscribe(ctx, message),
            Performative::Cancel => self.on_cancel(ctx, &message),
            _ => {
                let _ = ctx.not_understood(
                    &message,
                    "the watcher takes SUBSCRIBE (fipa-subscribe) to pass a passage, and CANCEL",
                );
            }
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(self.config.period)
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        let now_ns = ctx.now().0;
        let lease_ns = u64::try_from(self.config.lease.as_nanos()).unwrap_or(u64::MAX);
        for (name, passage) in &mut self.passages {
            let expired = passage
                .holders
                .extract_if(.., |g| now_ns.saturating_sub(g.since_ns) >= lease_ns);
            for mut grant in expired {
                tracing::warn!(passage = %name, chair = ?grant.ask.chair(), "lease expired; the queue moves on");
                let _ = ctx.answer_error(
                    &mut grant.ask.responder,
                    Performative::Failure,
                    "lease expired",
                );
            }
        }
        self.grant(ctx);
    }
}
