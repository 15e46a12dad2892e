//! The four bus layers assembled for a deployment: a [`LayerSet`] and a [`StackConfig`] become an
//! [`iw_bus::Stack`], and a [`Platform`] holds what the agent lists provide the layers (public
//! keys, registered agents).
//!
//! # Organization
//! - [`StackConfig`]: which layers and each layer's settings; [`build`] makes the stack.
//! - [`Platform`]: the key directory and agent registry shared by the stacks of one platform;
//!   [`Node`]: one container's identity and agents.
//! - [`GuardedTransport`]: a frame transport through the temporal and security layers under a
//!   group key, for traffic between containers rather than agents (join, heartbeat, election,
//!   GAL); [`write_group_key`] / [`read_group_key`]: the group key file it is keyed with.
//! - Re-exports of the layer crates' main types, so users need only this crate.
//!
//! # Guarantees
//! - Layers are always stacked in the thesis order: parser, temporal, security, comm (top to
//!   bottom); a layer switched off is simply absent.
//! - The parser requires the security layer's authentication exactly when the security layer is
//!   in the set (otherwise nothing could pass).
#![warn(missing_docs)]

use std::sync::Arc;

mod group_key;
mod guarded;

pub use group_key::{GroupKeyError, read_group_key, write_group_key};
pub use guarded::{GROUP, GuardedTransport};

pub use iw_bus::{LayerKind, LayerSet, Stack};
pub use iw_layer_comm::{CommConfig, CommLayer};
pub use iw_layer_parser::{AgentRegistry, ParserConfig, ParserLayer, Registry};
pub use iw_layer_security::{
    Directory, Identity, KeyDirectory, PreSharedKey, PublicKey, SecurityConfig, SecurityError,
    SecurityLayer,
};
pub use iw_layer_temporal::{Ordering, TemporalConfig, TemporalLayer};

/// Which layers, and the settings of each.
#[derive(Debug, Clone)]
pub struct StackConfig {
    /// Layers switched on (default all four).
    pub layers: LayerSet,
    /// Communication layer settings.
    pub comm: CommConfig,
    /// Security layer settings.
    pub security: SecurityConfig,
    /// Temporal layer settings.
    pub temporal: TemporalConfig,
    /// Parser layer settings.
    pub parser: ParserConfig,
}

impl Default for StackConfig {
    fn default() -> Self {
        StackConfig::with_layers(LayerSet::all())
    }
}

impl StackConfig {
    /// Default settings with the given layers.
    pub fn with_layers(layers: LayerSet) -> StackConfig {
        StackConfig {
            layers,
            comm: CommConfig::default(),
            security: SecurityConfig::default(),
            temporal: TemporalConfig::default(),
            parser: ParserConfig::default(),
        }
    }
}

/// What the agent lists give the layers: each agent's public key, and who is registered.
#[derive(Debug, Clone, Default)]
pub struct Platform {
    directory: Directory,
    registry: Registry,
}

impl Platform {
    /// An empty platform.
    pub fn new() -> Platform {
        Platform::default()
    }
    /// Registers `agent`, spoken for by the identity with public key `key`.
    pub fn register(&self, agent: &str, key: PublicKey) {
        self.directory.insert(agent, key);
        self.registry.insert(agent);
    }
    /// Deregisters `agent` (its key is forgotten too).
    pub fn deregister(&self, agent: &str) {
        self.directory.remove(agent);
        self.registry.remove(agent);
    }
    /// A new container identity hosting `agents`, all registered with its key.
    pub fn node(&self, agents: &[&str]) -> Result<Node, SecurityError> {
        let identity = Arc::new(Identity::generate()?);
        for a in agents {
            self.register(a, identity.public_key());
        }
        Ok(Node {
            identity,
            agents: agents.iter().map(|a| a.to_string()).collect(),
        })
    }
    /// The key directory (feed it from the Global Agent List).
    pub fn directory(&self) -> &Directory {
        &self.directory
    }
    /// The agent registry (feed it from the Local and Global Agent Lists).
    pub fn registry(&self) -> &Registry {
        &self.registry
    }
    /// The stack of `node` on this platform.
    pub fn stack(&self, node: &Node, config: &StackConfig) -> Stack {
        build(
            config,
            node.identity.clone(),
            Arc::new(self.directory.clone()),
            Arc::new(self.registry.clone()),
        )
    }
}

/// One container: its identity and the agents it hosts.
#[derive(Debug, Clone)]
pub struct Node {
    /// The Ed25519 identity the container's security layer speaks with.
    pub identity: Arc<Identity>,
    /// Names of its agents.
    pub agents: Vec<String>,
}

/// Builds the stack `config` asks for.
pub fn build(
    config: &StackConfig,
    identity: Arc<Identity>,
    keys: Arc<dyn KeyDirectory>,
    registry: Arc<dyn AgentRegistry>,
) -> Stack {
    let mut stack = Stack::new();
    let security_on = config.layers.contains(LayerKind::Security);
    for kind in config.layers.kinds() {
        match kind {
            LayerKind::Parser => {
                let parser = ParserConfig {
                    require_authenticated: security_on && config.parser.require_authenticated,
                    ..config.parser
                };
                stack.push_boxed(Box::new(ParserLayer::new(registry.clone(), parser)));
            }
            LayerKind::Temporal => stack.push_boxed(Box::new(TemporalLayer::new(config.temporal))),
            LayerKind::Security => {
                stack.push_boxed(Box::new(SecurityLayer::new(
                    identity.clone(),
                    keys.clone(),
                    config.security.clone(),
                )));
            }
            LayerKind::Comm => stack.push_boxed(Box::new(CommLayer::new(config.comm.clone()))),
        }
    }
    stack
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_bus::{Envelope, Layer, MsgId, Time, Verdict};

    fn acl(n: u64) -> Vec<u8> {
        format!("(inform :sender (agent-identifier :name a) :receiver (set (agent-identifier :name b)) :content \"{n}\")").into_bytes()
    }

    /// Shuttles frames between two stacks until both are quiet; returns what `b` delivered.
    fn run(a: &mut Stack, b: &mut Stack, out: Vec<Envelope>, now: Time) -> Vec<Envelope> {
        let mut got = Vec::new();
        let mut to_b = out;
        loop {
            while let Some(e) = a.poll_transmit(now) {
                to_b.push(e);
            }
            let mut busy = !to_b.is_empty();
            for mut e in to_b.drain(..) {
                if let Verdict::Pass = b.inbound(&mut e, now) {
                    got.push(e);
                }
            }
            while let Some(mut e) = b.poll_transmit(now) {
                busy = true;
                let _ = a.inbound(&mut e, now);
            }
            if !busy {
                return got;
            }
        }
    }

    #[test]
    fn every_layer_set_delivers() {
        for set in [
            "all",
            "none",
            "comm",
            "security,parser",
            "temporal,comm",
            "parser",
        ] {
            let platform = Platform::new();
            let na = platform.node(&["a"]).unwrap();
            let nb = platform.node(&["b"]).unwrap();
            let cfg = StackConfig::with_layers(set.parse().unwrap());
            let (mut a, mut b) = (platform.stack(&na, &cfg), platform.stack(&nb, &cfg));
            let now = Time::from_ns(1_000_000_000);
            let mut out = Vec::new();
            for n in 0..5 {
                let mut e = Envelope::new(MsgId(n), "a", "b", acl(n));
                if let Verdict::Pass = a.outbound(&mut e, now) {
                    out.push(e);
                }
            }
            let got = run(&mut a, &mut b, out, now);
            assert_eq!(got.len(), 5, "layers {set}: {:?}", b.counters());
            assert_eq!(got[4].payload, acl(4));
            assert_eq!(b.layer_names().len(), cfg.layers.kinds().len());
        }
    }

    /// Issue 20 item 3: a receiver restarted (its sessions lost) still gets the next message,
    /// whose frame was sealed under the old session: the re-key request makes the sender take
    /// the frame back from the communication layer and seal it again under a new key.
    #[test]
    fn a_restarted_receiver_gets_the_frame_sealed_under_its_lost_session() {
        for signed in [false, true] {
            let platform = Platform::new();
            let na = platform.node(&["a"]).unwrap();
            let nb = platform.node(&["b"]).unwrap();
            let mut cfg = StackConfig::default();
            cfg.security.sign_all = signed;
            let (mut a, mut b) = (platform.stack(&na, &cfg), platform.stack(&nb, &cfg));
            let now = Time::from_ns(1_000_000_000);
            let send = |a: &mut Stack, n: u64| {
                let mut e = Envelope::new(MsgId(n), "a", "b", acl(n));
                match a.outbound(&mut e, now) {
                    Verdict::Pass => vec![e],
                    _ => Vec::new(),
                }
            };
            let out = send(&mut a, 1);
            assert_eq!(run(&mut a, &mut b, out, now).len(), 1);
            let mut reborn = platform.stack(&nb, &cfg); // b restarts: same key, no sessions
            let out = send(&mut a, 2);
            let got = run(&mut a, &mut reborn, out, now);
            assert_eq!(got.len(), 1, "signed {signed}: {:?}", reborn.counters());
            assert_eq!(got[0].payload, acl(2));
            assert_eq!(reborn.counters().get(iw_bus::Reason::UnknownSession), 1);
        }
    }
}
