//! Internal: shared fixtures for the cross-crate integration tests in `tests/tests/`.
//!
//! # Organization
//! - [`Link`]: two layer stacks joined by seeded fault-injecting in-process transports and
//!   driven step by step in simulated time (a mock clock), for the EN 50159 unit-level tests.
//! - [`acl`]: a numbered FIPA-ACL message text; [`number_of`]: reads the number back.
//! - [`peer`]: the line protocol between an integration test and the `iw-peer` process.
//!
//! # Guarantees
//! A [`Link`] run is deterministic: the same seeds and inputs give the same frames, faults and
//! verdicts (no wall-clock time is read).
#![warn(missing_docs)]

use std::time::Duration;

use iw_bus::{
    Clock, Counters, Envelope, FaultyTransport, FrameCodec, Impairments, InProcNetwork,
    InProcTransport, Layer, MockController, MsgId, Stack, Time, Verdict, transport::FrameTransport,
};
use iw_stack::{Node, Platform, StackConfig};

pub mod peer;

/// A numbered ACL inform from `sender` to `receiver` (content `"n=<n>"`).
pub fn acl(sender: &str, receiver: &str, n: u64) -> Vec<u8> {
    format!(
        "(inform :sender (agent-identifier :name {sender}) :receiver (set (agent-identifier :name {receiver})) \
         :content \"n={n}\" :ontology intellwheels)"
    )
    .into_bytes()
}

/// The number in a payload built by [`acl`], if it is one.
pub fn number_of(payload: &[u8]) -> Option<u64> {
    let text = std::str::from_utf8(payload).ok()?;
    let start = text.find(":content \"n=")? + ":content \"n=".len();
    let end = text[start..].find('"')? + start;
    text[start..end].parse().ok()
}

/// One end of a [`Link`].
pub struct End {
    /// The agent at this end.
    pub agent: String,
    /// Its layers.
    pub stack: Stack,
    /// Its transport, impairing what it sends.
    pub transport: FaultyTransport<InProcTransport>,
    /// Envelopes that passed every layer inbound, in arrival order.
    pub delivered: Vec<Envelope>,
    next_id: u64,
}

/// Two agents `a` and `b`, each on its own node with its own stack, joined by in-process
/// transports that impair frames by seeded probabilities; time is a mock clock.
pub struct Link {
    /// Agent `a`'s end.
    pub a: End,
    /// Agent `b`'s end.
    pub b: End,
    /// The shared simulated clock.
    pub clock: Clock,
    /// Moves the clock.
    pub time: MockController,
    /// The platform (keys and registry) both ends trust.
    pub platform: Platform,
    /// The node hosting `a` (identity).
    pub node_a: Node,
    /// A third party (see [`Link::add_rogue`]), if any.
    pub rogue: Option<End>,
    net: InProcNetwork,
    codec: FrameCodec,
}

/// Which end of a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// Agent `a`.
    A,
    /// Agent `b`.
    B,
    /// The third party.
    Rogue,
}

impl Link {
    /// Start of simulated time: 2026-01-01T00:00:00Z.
    pub const T0: Time = Time::from_ns(1_767_225_600_000_000_000);

    /// A link with the same layers at both ends; `a_to_b` impairs what `a` sends, `b_to_a` what
    /// `b` sends.
    pub fn new(config: &StackConfig, a_to_b: Impairments, b_to_a: Impairments, seed: u64) -> Link {
        let platform = Platform::new();
        let node_a = platform.node(&["a"]).expect("system random generator");
        let node_b = platform.node(&["b"]).expect("system random generator");
        let net = InProcNetwork::new();
        let end = |agent: &str, node: &Node, faults, seed| End {
            agent: agent.to_string(),
            stack: platform.stack(node, config),
            transport: FaultyTransport::new(
                net.endpoint(agent).expect("fresh network"),
                faults,
                seed,
            ),
            delivered: Vec::new(),
            next_id: 0,
        };
        let a = end("a", &node_a, a_to_b, seed);
        let b = end("b", &node_b, b_to_a, seed.wrapping_add(1));
        let (clock, time) = Clock::mock(Link::T0);
        Link {
            a,
            b,
            clock,
            time,
            platform,
            node_a,
            rogue: None,
            net,
            codec: FrameCodec::new(),
        }
    }

    /// Adds a third party `agent` with its own identity and the given layers, on the same
    /// network; `registered` puts its key and name in the platform lists (a legitimate agent
    /// turned attacker) or not (an outsider).
    pub fn add_rogue(&mut self, agent: &str, config: &StackConfig, registered: bool) {
        let node = if registered {
            self.platform.node(&[agent])
        } else {
            Platform::new().node(&[agent])
        };
        let node = node.expect("system random generator");
        self.rogue = Some(End {
            agent: agent.to_string(),
            stack: self.platform.stack(&node, config),
            transport: FaultyTransport::new(
                self.net.endpoint(agent).expect("fresh name"),
                Impairments::default(),
                0,
            ),
            delivered: Vec::new(),
            next_id: 1 << 40,
        });
    }

    /// The end `side`.
    pub fn end(&mut self, side: Side) -> &mut End {
        match side {
            Side::A => &mut self.a,
            Side::B => &mut self.b,
            Side::Rogue => self.rogue.as_mut().expect("add_rogue first"),
        }
    }

    fn end_ref(&self, side: Side) -> &End {
        match side {
            Side::A => &self.a,
            Side::B => &self.b,
            Side::Rogue => self.rogue.as_ref().expect("add_rogue first"),
        }
    }

    /// Sends ACL message number `n` from `side` to the other end (through its stack).
    pub fn send(&mut self, side: Side, n: u64) {
        let now = self.clock.now();
        let (from, to) = match side {
            Side::A => ("a", "b"),
            Side::B | Side::Rogue => ("b", "a"),
        };
        let env = Envelope::new(self.fresh_id(side), from, to, acl(from, to, n));
        self.send_envelope(side, env, now);
    }

    /// A message id `side` has not used.
    pub fn fresh_id(&mut self, side: Side) -> MsgId {
        let end = self.end(side);
        end.next_id += 1;
        MsgId(end.next_id)
    }

    /// Runs `env` down `side`'s stack at `now` and returns the frame it would send (not sent).
    pub fn seal(&mut self, side: Side, mut env: Envelope, now: Time) -> Option<Vec<u8>> {
        let codec = self.codec;
        match self.end(side).stack.outbound(&mut env, now) {
            Verdict::Pass => codec.encode_to_vec(&env).ok(),
            _ => None,
        }
    }

    /// Sends a prepared envelope from `side` through its stack.
    pub fn send_envelope(&mut self, side: Side, mut env: Envelope, now: Time) {
        let codec = self.codec;
        let end = self.end(side);
        if let Verdict::Pass = end.stack.outbound(&mut env, now) {
            let to = iw_bus::transport::PeerAddr(env.header.receiver.clone());
            let frame = codec
                .encode_to_vec(&env)
                .expect("layers make encodable envelopes");
            // A receiver without an endpoint is a lost frame, as on a real network.
            let _ = end.transport.send(&to, &frame);
        }
    }

    /// Hands a raw frame to `side`'s transport as if it came from the network (an attacker).
    pub fn inject(&mut self, side: Side, frame: &[u8]) {
        let from = if side == Side::A { &self.b } else { &self.a };
        let target = self.end_ref(side).transport.local_addr().clone();
        from.transport
            .inner()
            .send(&target, frame)
            .expect("in-process endpoint exists");
    }

    /// Delivers every frame waiting at either end and sends what the layers originate; true if
    /// anything moved.
    pub fn step(&mut self) -> bool {
        let now = self.clock.now();
        let mut moved = false;
        let sides: &[Side] = if self.rogue.is_some() {
            &[Side::A, Side::B, Side::Rogue]
        } else {
            &[Side::A, Side::B]
        };
        for &side in sides {
            let codec = self.codec;
            let end = self.end(side);
            while let Ok(Some((_, frame))) = end.transport.recv_timeout(Duration::ZERO) {
                moved = true;
                match codec.decode_datagram(&frame) {
                    Ok(mut env) => {
                        if let Verdict::Pass = end.stack.inbound(&mut env, now) {
                            end.delivered.push(env);
                        }
                    }
                    Err(_) => end.stack.record(iw_bus::Reason::BadFrame),
                }
            }
            while let Some(env) = end.stack.poll_transmit(now) {
                moved = true;
                let to = iw_bus::transport::PeerAddr(env.header.receiver.clone());
                let frame = codec
                    .encode_to_vec(&env)
                    .expect("layers make encodable envelopes");
                let _ = end.transport.send(&to, &frame);
            }
        }
        moved
    }

    /// Runs in 1 ms steps of simulated time until nothing is in flight, at most `limit`;
    /// returns the simulated time it took.
    pub fn run(&mut self, limit: Duration) -> Duration {
        let start = self.clock.now();
        while self.clock.now().since(start) < limit {
            while self.step() {}
            let _ = self.a.transport.flush();
            let _ = self.b.transport.flush();
            while self.step() {}
            if self.a.stack.next_deadline().is_none() && self.b.stack.next_deadline().is_none() {
                break;
            }
            self.time.advance(Duration::from_millis(1));
        }
        self.clock.now().since(start)
    }

    /// Numbers of the messages `side` received, in order.
    pub fn numbers(&self, side: Side) -> Vec<u64> {
        self.end_ref(side)
            .delivered
            .iter()
            .filter_map(|e| number_of(&e.payload))
            .collect()
    }

    /// Rejections at both ends.
    pub fn counters(&self) -> Counters {
        let mut c = self.a.stack.counters().clone();
        c.merge(self.b.stack.counters());
        c
    }
}
