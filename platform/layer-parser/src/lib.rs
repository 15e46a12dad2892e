//! Parser layer (thesis 3.3.3, top layer): builds FIPA-ACL envelopes and lets through only
//! well-formed FIPA-ACL from registered, authenticated senders.
//!
//! # Organization
//! - [`ParserLayer`], [`ParserConfig`]: the [`Layer`].
//! - [`AgentRegistry`], [`Registry`]: who is on the platform (fed by the Local and Global Agent
//!   Lists).
//! - [`envelope`]: prints an [`AclMessage`] into an envelope addressed to one receiver.
//!
//! # Guarantees
//! An envelope reaches an agent only if its payload parses as FIPA-ACL (SC00070, via `iw-acl`'s
//! `check_with`, the parser's verdict without building the message),
//! names a sender, and
//! - the sender is registered on the platform ([`Reason::Unregistered`]; EN 50159 *insertion*:
//!   an unknown application gets nothing through);
//! - the security layer authenticated that same sender, unless the deployment runs without it
//!   and sets `require_authenticated = false` ([`Reason::Unauthenticated`]);
//! - the ACL `:sender` is the authenticated envelope sender and the ACL `:receiver` set contains
//!   the envelope receiver ([`Reason::Mismatch`]; EN 50159 *masquerade*: an authenticated agent
//!   cannot speak in another's name inside the content).
//!
//! Malformed text is [`Reason::Malformed`]. Outbound, [`envelope`] builds only consistent
//! envelopes, and `check_outbound` applies the syntax and sender checks to hand-written text.
#![warn(missing_docs)]

use std::sync::{Arc, PoisonError, RwLock};

use iw_acl::AclMessage;
use iw_acl::codec::{ParseOptions, PrintOptions};
use iw_bus::{Envelope, Layer, MsgId, Reason, Time, Verdict};
use rustc_hash::FxHashSet;

/// Who is on the platform.
pub trait AgentRegistry: Send + Sync {
    /// True if `agent` is registered (in the local or the global agent list).
    fn is_registered(&self, agent: &str) -> bool;
}

/// A shared, updatable [`AgentRegistry`] (clones share one set).
///
/// Names are put in by the platform only (outsiders merely look theirs up), so the set uses a
/// fast unkeyed hash.
#[derive(Debug, Clone, Default)]
pub struct Registry(Arc<RwLock<FxHashSet<String>>>);

impl Registry {
    /// An empty registry.
    pub fn new() -> Registry {
        Registry::default()
    }
    /// Registers `agent`.
    pub fn insert(&self, agent: &str) {
        self.0
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(agent.to_string());
    }
    /// Deregisters `agent`.
    pub fn remove(&self, agent: &str) {
        self.0
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(agent);
    }
}

impl AgentRegistry for Registry {
    fn is_registered(&self, agent: &str) -> bool {
        self.0
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .contains(agent)
    }
}

/// Settings of the parser layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParserConfig {
    /// Refuse senders the security layer did not authenticate (default true; turn off only in
    /// deployments without the security layer).
    pub require_authenticated: bool,
    /// Parse and check outgoing messages too (default false: messages built with [`envelope`]
    /// are well-formed and sender-consistent by construction, and the receiving parser checks
    /// everything again; turn on for agents that write ACL text by hand).
    pub check_outbound: bool,
    /// ACL parser options (escaping, size and nesting limits).
    pub parse: ParseOptions,
}

impl Default for ParserConfig {
    fn default() -> Self {
        ParserConfig {
            require_authenticated: true,
            check_outbound: false,
            parse: ParseOptions::default(),
        }
    }
}

/// Why an envelope could not be built.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ParserError {
    /// The message has no `:sender`, so it cannot be routed or answered.
    #[error("ACL message ({performative}) has no :sender; set one with `with_sender`")]
    NoSender {
        /// Its performative.
        performative: String,
    },
    /// The envelope's receiver is not among the message's receivers.
    #[error(
        "`{receiver}` is not among the :receiver set of the ACL message; add it with `with_receiver`"
    )]
    NotAReceiver {
        /// The receiver asked for.
        receiver: String,
    },
    /// The ACL printer refused the message.
    #[error("cannot print ACL message: {0}")]
    Print(#[from] iw_acl::Error),
}

/// Prints `msg` into an envelope to `receiver` (one of its receivers) with id `id`.
pub fn envelope(id: MsgId, msg: &AclMessage, receiver: &str) -> Result<Envelope, ParserError> {
    let sender = msg.sender.as_ref().ok_or_else(|| ParserError::NoSender {
        performative: msg.performative.to_string(),
    })?;
    if !msg.receivers.iter().any(|r| r.name == receiver) {
        return Err(ParserError::NotAReceiver {
            receiver: receiver.to_string(),
        });
    }
    let text = iw_acl::codec::print_with(msg, &PrintOptions::default())?;
    Ok(Envelope::new(
        id,
        sender.name.clone(),
        receiver,
        text.into_bytes(),
    ))
}

/// The parser layer.
pub struct ParserLayer {
    registry: Arc<dyn AgentRegistry>,
    config: ParserConfig,
}

impl ParserLayer {
    /// A layer checking senders against `registry`.
    pub fn new(registry: Arc<dyn AgentRegistry>, config: ParserConfig) -> ParserLayer {
        ParserLayer { registry, config }
    }

    /// Well-formed ACL whose `:sender` is the envelope's sender and whose `:receiver` set holds
    /// the envelope's receiver. Only checks (`check_with`): the message itself is not built.
    fn check_syntax(&self, env: &Envelope) -> Result<(), Reason> {
        let text = env.payload_str().ok_or(Reason::Malformed)?;
        let summary = iw_acl::codec::check_with(text, &self.config.parse).map_err(|e| {
            tracing::debug!(sender = %env.header.sender, error = %e, "malformed ACL");
            Reason::Malformed
        })?;
        let sender = summary.sender().ok_or(Reason::Malformed)?;
        if sender != env.header.sender || !summary.has_receiver(&env.header.receiver) {
            return Err(Reason::Mismatch);
        }
        Ok(())
    }

    fn check_inbound(&self, env: &Envelope) -> Result<(), Reason> {
        if self.config.require_authenticated
            && env.authenticated.as_deref() != Some(env.header.sender.as_str())
        {
            return Err(Reason::Unauthenticated);
        }
        if !self.registry.is_registered(&env.header.sender) {
            return Err(Reason::Unregistered);
        }
        self.check_syntax(env)
    }
}

impl Layer for ParserLayer {
    fn name(&self) -> &'static str {
        "parser"
    }

    fn outbound(&mut self, env: &mut Envelope, _now: Time) -> Verdict {
        if self.config.check_outbound
            && let Err(r) = self.check_syntax(env)
        {
            return Verdict::Drop(r);
        }
        Verdict::Pass
    }

    fn inbound(&mut self, env: &mut Envelope, _now: Time) -> Verdict {
        match self.check_inbound(env) {
            Ok(()) => Verdict::Pass,
            Err(r) => Verdict::Drop(r),
        }
    }

    fn originates(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_acl::{AgentId, Performative};

    fn layer(agents: &[&str]) -> ParserLayer {
        let reg = Registry::new();
        for a in agents {
            reg.insert(a);
        }
        ParserLayer::new(Arc::new(reg), ParserConfig::default())
    }

    fn acl(sender: &str, receiver: &str) -> AclMessage {
        AclMessage::new(Performative::Inform)
            .with_sender(AgentId::new(sender))
            .with_receiver(AgentId::new(receiver))
            .with_content("(at wheelchair kitchen)")
    }

    fn authed(mut env: Envelope) -> Envelope {
        env.authenticated = Some(env.header.sender.clone());
        env
    }

    #[test]
    fn registered_authenticated_well_formed_passes() {
        let mut p = layer(&["a", "b"]);
        let mut env = envelope(MsgId(1), &acl("a", "b"), "b").unwrap();
        assert_eq!(p.outbound(&mut env, Time::ZERO), Verdict::Pass);
        assert_eq!(p.inbound(&mut authed(env), Time::ZERO), Verdict::Pass);
    }

    #[test]
    fn rejections() {
        let mut p = layer(&["a", "b"]);
        p.config.check_outbound = true;
        let good = envelope(MsgId(1), &acl("a", "b"), "b").unwrap();
        assert_eq!(
            p.inbound(&mut good.clone(), Time::ZERO),
            Verdict::Drop(Reason::Unauthenticated)
        );
        let mut garbage = good.clone();
        garbage.payload = b"(inform :sender".to_vec();
        assert_eq!(
            p.inbound(&mut authed(garbage), Time::ZERO),
            Verdict::Drop(Reason::Malformed)
        );
        let mut binary = good.clone();
        binary.payload = vec![0xff, 0xfe];
        assert_eq!(
            p.inbound(&mut authed(binary), Time::ZERO),
            Verdict::Drop(Reason::Malformed)
        );
        let stranger = envelope(MsgId(2), &acl("x", "b"), "b").unwrap();
        assert_eq!(
            p.inbound(&mut authed(stranger), Time::ZERO),
            Verdict::Drop(Reason::Unregistered)
        );
        // `a` authenticated, but the content claims to be from `b`.
        let mut masked = envelope(MsgId(3), &acl("b", "b"), "b").unwrap();
        masked.header.sender = "a".into();
        assert_eq!(
            p.inbound(&mut authed(masked), Time::ZERO),
            Verdict::Drop(Reason::Mismatch)
        );
        assert!(matches!(
            envelope(MsgId(4), &acl("a", "c"), "b"),
            Err(ParserError::NotAReceiver { .. })
        ));
        let mut misaddressed = envelope(MsgId(4), &acl("a", "c"), "c").unwrap();
        misaddressed.header.receiver = "b".into();
        assert_eq!(
            p.inbound(&mut authed(misaddressed.clone()), Time::ZERO),
            Verdict::Drop(Reason::Mismatch)
        );
        assert_eq!(
            p.outbound(&mut misaddressed, Time::ZERO),
            Verdict::Drop(Reason::Mismatch)
        );
    }

    #[test]
    fn authentication_optional_when_configured() {
        let reg = Registry::new();
        reg.insert("a");
        let mut p = ParserLayer::new(
            Arc::new(reg),
            ParserConfig {
                require_authenticated: false,
                ..Default::default()
            },
        );
        let mut env = envelope(MsgId(1), &acl("a", "b"), "b").unwrap();
        assert_eq!(p.inbound(&mut env, Time::ZERO), Verdict::Pass);
    }

    #[test]
    fn envelope_needs_a_sender() {
        let msg = AclMessage::new(Performative::Inform);
        assert!(matches!(
            envelope(MsgId(1), &msg, "b"),
            Err(ParserError::NoSender { .. })
        ));
    }
}
