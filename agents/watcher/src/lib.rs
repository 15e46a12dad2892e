//! The watcher agent: traffic control at doors and narrow passages. Chairs ask to pass a named
//! passage in a direction; the watcher lets chairs through one direction at a time (several
//! chairs may follow each other the same way, never meet head-on inside), first come first
//! served, and takes a grant back when its lease runs out, so a chair that never releases cannot
//! block the others.
//!
//! Organization: [`WatcherConfig`] (passages and lease), [`WatcherAgent::new`], [`WatcherError`].
//!
//! # Messages
//! All `:ontology IntellWheels-Wheelchair`, `:language fipa-sl0`, `:protocol fipa-request`.
//! - REQUEST `((action (agent-identifier :name W) (pass :passage P :direction D)))`: AGREE at
//!   once (queued), then INFORM `((done (action W (pass :passage P :direction D))))` in the same
//!   conversation when granted. REFUSE for an unknown passage or a chair already holding or
//!   queued for it; NOT-UNDERSTOOD for any other content.
//! - CANCEL in the request's conversation: releases the grant (or leaves the queue).
//! - When a lease expires the holder gets FAILURE `((error-message "lease expired"))` and the
//!   queue moves on.
//!
//! Guarantees: the chairs holding a passage at any time all cross it in the same direction
//! (property-tested); grants follow request order, so a chair waiting to go one way is never
//! overtaken by later chairs going the other way; every queued request is granted within
//! (queue length x lease).
#![warn(missing_docs)]

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context};
use iw_ontology::OntologyContent;
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

/// A `pass` request: the message (for the reply) and what it asks.
struct Ask {
    request: AclMessage,
    actor: AgentId,
    passage: String,
    direction: String,
}

struct Grant {
    ask: Ask,
    since_ns: u64,
}

#[derive(Default)]
struct Passage {
    /// Chairs inside, all going one direction.
    holders: Vec<Grant>,
    queue: VecDeque<Ask>,
}

impl Passage {
    fn involves(&self, chair: &Option<AgentId>) -> bool {
        self.holders.iter().any(|g| &g.ask.request.sender == chair)
            || self.queue.iter().any(|q| &q.request.sender == chair)
    }
}

/// The watcher agent.
pub struct WatcherAgent {
    config: WatcherConfig,
    passages: BTreeMap<String, Passage>,
}

fn same_asker(a: &AclMessage, b: &AclMessage) -> bool {
    a.sender == b.sender && a.conversation_id == b.conversation_id
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
            while let Some(head) = passage.queue.front() {
                if passage
                    .holders
                    .first()
                    .is_some_and(|g| g.ask.direction != head.direction)
                {
                    break;
                }
                let Some(ask) = passage.queue.pop_front() else {
                    break;
                };
                tracing::debug!(passage = %name, direction = %ask.direction, chair = ?ask.request.sender.as_ref().map(|s| &s.name), "granted");
                let done = WheelchairContent::Done {
                    actor: ask.actor.clone(),
                    action: WheelchairAction::Pass {
                        passage: ask.passage.clone(),
                        direction: ask.direction.clone(),
                    },
                };
                let _ = ctx.send(
                    done.fill(
                        ask.request
                            .create_reply()
                            .with_performative(Performative::Inform),
                    ),
                );
                passage.holders.push(Grant {
                    ask,
                    since_ns: now_ns,
                });
            }
        }
    }

    fn on_request(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let Some((actor, passage, direction)) = ctx.understand(
            &message,
            "the watcher takes (pass :passage P :direction D) requests",
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
        let ask = Ask {
            request: message,
            actor,
            passage,
            direction,
        };
        let refuse = |ctx: &mut Context<'_>, why: &str| {
            let _ = ctx.refuse(&ask.request, why);
        };
        let Some(passage) = self.passages.get_mut(&ask.passage) else {
            refuse(ctx, "unknown passage");
            return;
        };
        if passage.involves(&ask.request.sender) {
            refuse(ctx, "already holding or queued for this passage");
            return;
        }
        let agree = ask
            .request
            .create_reply()
            .with_performative(Performative::Agree);
        let _ = ctx
            .send(agree.with_content(ask.request.content_text().unwrap_or_default().to_string()));
        passage.queue.push_back(ask);
        self.grant(ctx);
    }

    fn on_cancel(&mut self, ctx: &mut Context<'_>, message: &AclMessage) {
        for passage in self.passages.values_mut() {
            passage
                .holders
                .retain(|g| !same_asker(&g.ask.request, message));
            passage.queue.retain(|q| !same_asker(&q.request, message));
        }
        self.grant(ctx);
    }
}

impl Agent for WatcherAgent {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Request => self.on_request(ctx, message),
            Performative::Cancel => self.on_cancel(ctx, &message),
            _ => {
                let _ = ctx.not_understood(&message, "the watcher takes pass requests and cancels");
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
            let (expired, live): (Vec<Grant>, Vec<Grant>) = passage
                .holders
                .drain(..)
                .partition(|g| now_ns.saturating_sub(g.since_ns) >= lease_ns);
            passage.holders = live;
            for grant in expired {
                tracing::warn!(passage = %name, "lease expired; the queue moves on");
                let _ = ctx.failure(&grant.ask.request, "lease expired");
            }
        }
        self.grant(ctx);
    }
}
