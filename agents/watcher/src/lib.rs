//! The watcher agent: traffic control at doors and narrow passages. Chairs ask to pass a named
//! passage; the watcher grants it to one chair at a time, first come first served, and takes a
//! grant back when its lease runs out, so a chair that never releases cannot block the others
//! and no two chairs meet head-on inside a passage.
//!
//! Organization: [`WatcherConfig`] (passages and lease), [`WatcherAgent::new`], [`parse_pass`]
//! / [`pass_content`] for the `pass` action (not in the wheelchair ontology), [`WatcherError`].
//!
//! # Messages
//! - REQUEST (`fipa-request`) `((action (agent-identifier :name W) (pass :passage P :direction
//!   D)))`: AGREE at once (queued), then INFORM `((done (action ... (pass ...))))` in the same
//!   conversation when granted. REFUSE for an unknown passage or a chair already holding or
//!   queued for it.
//! - CANCEL in the request's conversation: releases the grant (or leaves the queue).
//! - When a lease expires the holder gets FAILURE `((error-message "lease expired"))` and the
//!   next chair is granted.
//!
//! Guarantees: at most one chair holds a passage at any time (property-tested); grants follow
//! request order; every queued request is granted within (queue length x lease).
#![warn(missing_docs)]

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use iw_acl::{AclMessage, Performative};
use iw_agent::{Agent, Context};
use iw_sl::{ActionExpression, ContentExpression, Level, Term};

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

struct Grant {
    request: AclMessage,
    since_ns: u64,
}

#[derive(Default)]
struct Passage {
    holder: Option<Grant>,
    queue: VecDeque<AclMessage>,
}

/// The watcher agent.
pub struct WatcherAgent {
    config: WatcherConfig,
    passages: BTreeMap<String, Passage>,
}

/// The `pass` request content for watcher `watcher`.
pub fn pass_content(watcher: &str, passage: &str, direction: &str) -> String {
    format!(
        "((action (agent-identifier :name {}) (pass :passage {} :direction {})))",
        Term::string(watcher),
        Term::string(passage),
        Term::string(direction)
    )
}

/// The passage and direction of a `pass` request.
pub fn parse_pass(message: &AclMessage) -> Option<(String, String)> {
    let content = iw_sl::parse(message.content_text()?, Level::Sl0).ok()?;
    let [ContentExpression::Action(ActionExpression::Action { act, .. })] = content.expressions.as_slice() else {
        return None;
    };
    let Term::Functional { symbol, args } = act else { return None };
    if !symbol.eq_ignore_ascii_case("pass") {
        return None;
    }
    let text = |name: &str| match args.get(name)?.as_constant()? {
        iw_sl::Constant::String(s) => Some(s.clone()),
        _ => None,
    };
    Some((text("passage")?, text("direction").unwrap_or_default()))
}

fn same_asker(a: &AclMessage, b: &AclMessage) -> bool {
    a.sender == b.sender && a.conversation_id == b.conversation_id
}

impl WatcherAgent {
    /// A watcher over `config.passages`, all free.
    pub fn new(config: WatcherConfig) -> Result<Self, WatcherError> {
        if config.lease.is_zero() {
            return Err(WatcherError::ZeroLease { lease_ms: config.lease.as_millis() });
        }
        let passages = config.passages.iter().map(|p| (p.clone(), Passage::default())).collect();
        Ok(WatcherAgent { config, passages })
    }

    /// Grants free passages to the first in their queue.
    fn grant(&mut self, ctx: &mut Context<'_>) {
        let now_ns = ctx.now().0;
        for (name, passage) in &mut self.passages {
            if passage.holder.is_some() {
                continue;
            }
            let Some(request) = passage.queue.pop_front() else { continue };
            tracing::debug!(passage = %name, chair = ?request.sender.as_ref().map(|s| &s.name), "granted");
            // `((action ...))` -> `((done (action ...)))`: the request's one expression, done.
            let text = request.content_text().unwrap_or_default().trim();
            let action = text.strip_prefix('(').and_then(|t| t.strip_suffix(')')).unwrap_or(text);
            let content = format!("((done {action}))");
            let _ = ctx.send(request.create_reply().with_performative(Performative::Inform).with_content(content));
            passage.holder = Some(Grant { request, since_ns: now_ns });
        }
    }

    fn on_request(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        let Some((name, _direction)) = parse_pass(&message) else {
            let _ = ctx.not_understood(&message, "expected ((action watcher (pass :passage P :direction D)))");
            return;
        };
        let refuse = |ctx: &mut Context<'_>, why: &str| {
            let reply = message.create_reply().with_performative(Performative::Refuse);
            let _ = ctx.send(reply.with_content(format!("((error-message \"{why}\"))")));
        };
        let Some(passage) = self.passages.get_mut(&name) else {
            refuse(ctx, "unknown passage");
            return;
        };
        let sender = &message.sender;
        if passage.holder.as_ref().is_some_and(|g| &g.request.sender == sender) || passage.queue.iter().any(|q| &q.sender == sender) {
            refuse(ctx, "already holding or queued for this passage");
            return;
        }
        let agree = message.create_reply().with_performative(Performative::Agree);
        let _ = ctx.send(agree.with_content(message.content_text().unwrap_or_default().to_string()));
        passage.queue.push_back(message);
        self.grant(ctx);
    }

    fn on_cancel(&mut self, ctx: &mut Context<'_>, message: &AclMessage) {
        for passage in self.passages.values_mut() {
            if passage.holder.as_ref().is_some_and(|g| same_asker(&g.request, message)) {
                passage.holder = None;
            }
            passage.queue.retain(|q| !same_asker(q, message));
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
            if let Some(grant) = passage.holder.take_if(|g| now_ns.saturating_sub(g.since_ns) >= lease_ns) {
                tracing::warn!(passage = %name, "lease expired; granting the next chair");
                let reply = grant.request.create_reply().with_performative(Performative::Failure);
                let _ = ctx.send(reply.with_content("((error-message \"lease expired\"))"));
            }
        }
        self.grant(ctx);
    }
}
