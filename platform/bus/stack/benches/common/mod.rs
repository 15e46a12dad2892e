//! The per-message exchange the `layers` bench times and the `layers_profile` example profiles:
//! a 300-byte FIPA-ACL message sent by stack A and received by stack B, acknowledgement included.

use std::hint::black_box;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_bus::{Counters, Envelope, Layer, MsgId, Stack, Time, Verdict};
use iw_stack::{Platform, StackConfig};

/// A 300-byte ACL message from `a` to `b`.
pub fn message() -> Vec<u8> {
    let base = AclMessage::new(Performative::Inform)
        .with_sender(AgentId::new("a"))
        .with_receiver(AgentId::new("b"))
        .with_ontology("intellwheels")
        .with_conversation_id("c-1");
    let empty = iw_acl::codec::print(&base.clone().with_content("")).len();
    let text = iw_acl::codec::print(&base.with_content("x".repeat(300 - empty)));
    assert_eq!(text.len(), 300);
    text.into_bytes()
}

/// Two stacks with the same layer set, keys agreed on the first message.
pub struct Exchange {
    a: Stack,
    b: Stack,
    payload: Vec<u8>,
    id: u64,
    wire: Vec<Envelope>,
}

impl Exchange {
    /// Stacks of agents `a` and `b` with the layer set `set` (`all`, `none`, `comm`, ...).
    pub fn new(set: &str) -> Exchange {
        let platform = Platform::new();
        let na = platform.node(&["a"]).expect("identity");
        let nb = platform.node(&["b"]).expect("identity");
        let cfg = StackConfig::with_layers(set.parse().expect("layer set"));
        Exchange {
            a: platform.stack(&na, &cfg),
            b: platform.stack(&nb, &cfg),
            payload: message(),
            id: 0,
            wire: Vec::new(),
        }
    }

    /// One message from A to B and whatever the layers send back and forth for it; returns the
    /// payload bytes B delivered. The first message of a security run also carries the key
    /// agreement.
    pub fn one(&mut self) -> usize {
        let now = Time::from_ns(1_700_000_000_000_000_000);
        self.id += 1;
        let mut delivered = 0;
        let mut e = Envelope::new(MsgId(self.id), "a", "b", self.payload.clone());
        if let Verdict::Pass = self.a.outbound(&mut e, now) {
            self.wire.push(e);
        }
        loop {
            while let Some(e) = self.a.poll_transmit(now) {
                self.wire.push(e);
            }
            if self.wire.is_empty() {
                break;
            }
            for mut e in self.wire.drain(..) {
                if let Verdict::Pass = self.b.inbound(&mut e, now) {
                    delivered += black_box(e).payload.len();
                }
            }
            while let Some(mut back) = self.b.poll_transmit(now) {
                let _ = self.a.inbound(&mut back, now);
            }
        }
        delivered
    }

    /// What B rejected so far (nothing, in a correct run).
    pub fn rejected(&self) -> &Counters {
        self.b.counters()
    }
}
