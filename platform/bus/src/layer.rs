//! The layer trait, the verdicts and rejection reasons, and the [`Stack`] that chains layers.
//!
//! A layer sees each envelope twice: on the way down ([`Layer::outbound`], agent to transport)
//! and on the way up ([`Layer::inbound`], transport to agent). It borrows the envelope, may
//! transform it in place, and answers with a [`Verdict`]: pass it on, drop it with a [`Reason`],
//! or consume it (acknowledgements, handshakes). The envelope stays its caller's, who forwards it
//! only on [`Verdict::Pass`]; a layer that keeps an envelope (held until a key is agreed) takes
//! it out with [`std::mem::take`], and one that needs a copy (for retransmission) clones it.
//!
//! On the way up a layer leaves the id and the sender as they arrived (the security layer binds
//! them to the payload, which it opens in place): after a drop, the layers below are told them
//! ([`Layer::rejected_above`]) and must recognise the frame they saw.
//!
//! Frames a layer originates itself (acknowledgements, retransmissions, held messages released
//! after a key agreement) wait in its outbox until [`Layer::poll_transmit`] hands them on; a
//! [`Stack`] sends them down through the layers below the one that made them.
//!
//! Order in the thesis' stack, top (agent) to bottom (transport): parser, temporal, security,
//! communication. Any of them may be left out per deployment (see [`LayerSet`]).

use std::str::FromStr;

use crate::BusError;
use crate::envelope::{Envelope, MsgId};
use crate::time::Time;
use crate::warn::WarnEvery;

/// What a layer decided about the envelope it was lent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[must_use]
pub enum Verdict {
    /// Hand the envelope, as the layer left it, to the next layer (or the transport, or the
    /// agent).
    Pass,
    /// Rejected: never delivered, counted under the reason. The envelope is left in place (its
    /// id and sender as they arrived, see [`Layer::rejected_above`]), for the caller to discard.
    Drop(Reason),
    /// Used by the layer itself (an acknowledgement, a handshake, a message held until a key is
    /// agreed): not a rejection, not counted. The layer may have taken the envelope, leaving a
    /// default one for the caller to discard.
    Consumed,
}

/// Why an envelope was rejected. Each has a counter in [`Counters`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum Reason {
    /// Communication: the message id was seen before (repetition).
    Duplicate,
    /// Communication: larger than the receiving agent's configured limit.
    TooLarge,
    /// Communication: never acknowledged after the last retransmission (the link is down).
    Undeliverable,
    /// Security: the frame is not sealed but the layer requires it (insertion of plaintext).
    NotSealed,
    /// Security: the AEAD tag does not verify (corruption or alteration).
    BadTag,
    /// Security: no key is known for the peer (unknown sender or receiver).
    UnknownPeer,
    /// Security: the frame names a key session this node does not hold.
    UnknownSession,
    /// Security: a signature (message or handshake) does not verify (masquerade).
    BadSignature,
    /// Security: a handshake frame is malformed or does not match a pending agreement.
    BadHandshake,
    /// Temporal: older than the configured maximum age (delay).
    Stale,
    /// Temporal: timestamped too far in the future for the allowed clock skew.
    FromFuture,
    /// Temporal: past its reply-by deadline.
    PastReplyBy,
    /// Temporal: this sender's sequence number was already accepted (replay).
    ReplayedSequence,
    /// Temporal: out of order (behind the newest accepted sequence number) in strict ordering,
    /// or too far behind to be checked at all.
    OutOfOrder,
    /// Parser: the payload is not a well-formed FIPA-ACL message.
    Malformed,
    /// Parser: the sender is not registered on the platform.
    Unregistered,
    /// Parser: no security layer authenticated the sender, and the parser requires it.
    Unauthenticated,
    /// Parser: the ACL sender or receiver differs from the authenticated envelope (masquerade).
    Mismatch,
    /// Bus: the frame does not decode.
    BadFrame,
    /// Bus: no local agent or route for the receiver.
    NoRoute,
    /// Bus: the receiving agent's mailbox is full or closed.
    MailboxFull,
}

impl Reason {
    /// Every reason, in counter order.
    pub const ALL: [Reason; 21] = [
        Reason::Duplicate,
        Reason::TooLarge,
        Reason::Undeliverable,
        Reason::NotSealed,
        Reason::BadTag,
        Reason::UnknownPeer,
        Reason::UnknownSession,
        Reason::BadSignature,
        Reason::BadHandshake,
        Reason::Stale,
        Reason::FromFuture,
        Reason::PastReplyBy,
        Reason::ReplayedSequence,
        Reason::OutOfOrder,
        Reason::Malformed,
        Reason::Unregistered,
        Reason::Unauthenticated,
        Reason::Mismatch,
        Reason::BadFrame,
        Reason::NoRoute,
        Reason::MailboxFull,
    ];

    /// A short snake_case name, as printed in counters.
    pub fn name(self) -> &'static str {
        match self {
            Reason::Duplicate => "duplicate",
            Reason::TooLarge => "too_large",
            Reason::Undeliverable => "undeliverable",
            Reason::NotSealed => "not_sealed",
            Reason::BadTag => "bad_tag",
            Reason::UnknownPeer => "unknown_peer",
            Reason::UnknownSession => "unknown_session",
            Reason::BadSignature => "bad_signature",
            Reason::BadHandshake => "bad_handshake",
            Reason::Stale => "stale",
            Reason::FromFuture => "from_future",
            Reason::PastReplyBy => "past_reply_by",
            Reason::ReplayedSequence => "replayed_sequence",
            Reason::OutOfOrder => "out_of_order",
            Reason::Malformed => "malformed",
            Reason::Unregistered => "unregistered",
            Reason::Unauthenticated => "unauthenticated",
            Reason::Mismatch => "mismatch",
            Reason::BadFrame => "bad_frame",
            Reason::NoRoute => "no_route",
            Reason::MailboxFull => "mailbox_full",
        }
    }

    /// True if the frame was refused as not authentic (it may not be what its sender sent):
    /// layers below must then forget it, so the genuine frame still gets through.
    pub fn is_authenticity_failure(self) -> bool {
        matches!(
            self,
            Reason::NotSealed
                | Reason::BadTag
                | Reason::UnknownPeer
                | Reason::UnknownSession
                | Reason::BadSignature
                | Reason::BadHandshake
                | Reason::BadFrame
        )
    }

    fn index(self) -> usize {
        Reason::ALL.iter().position(|r| *r == self).unwrap_or(0)
    }
}

impl std::fmt::Display for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Rejections per [`Reason`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Counters {
    counts: [u64; Reason::ALL.len()],
}

impl Counters {
    /// Counts one rejection.
    pub fn record(&mut self, reason: Reason) {
        let c = &mut self.counts[reason.index()];
        *c = c.saturating_add(1);
    }
    /// Rejections for `reason`.
    pub fn get(&self, reason: Reason) -> u64 {
        self.counts[reason.index()]
    }
    /// All rejections.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }
    /// Adds `other`'s counts to these.
    pub fn merge(&mut self, other: &Counters) {
        for (a, b) in self.counts.iter_mut().zip(other.counts.iter()) {
            *a = a.saturating_add(*b);
        }
    }
    /// `(reason, count)` for every reason with a non-zero count.
    pub fn nonzero(&self) -> impl Iterator<Item = (Reason, u64)> + '_ {
        Reason::ALL
            .iter()
            .map(|r| (*r, self.get(*r)))
            .filter(|(_, n)| *n > 0)
    }
}

impl std::fmt::Display for Counters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut first = true;
        for (r, n) in self.nonzero() {
            write!(f, "{}{}={}", if first { "" } else { " " }, r, n)?;
            first = false;
        }
        if first {
            f.write_str("(no rejections)")?;
        }
        Ok(())
    }
}

/// One layer of the bus. Layers are plain state machines: time comes in as `now`, never from a
/// clock they read themselves.
pub trait Layer: Send {
    /// A short name for logs ("comm", "security", ...).
    fn name(&self) -> &'static str;
    /// An envelope on its way from an agent to the transport, transformed in place.
    fn outbound(&mut self, env: &mut Envelope, now: Time) -> Verdict;
    /// An envelope on its way from the transport to an agent, transformed in place (payload,
    /// flags, signature, `authenticated`; never the id or the sender).
    fn inbound(&mut self, env: &mut Envelope, now: Time) -> Verdict;
    /// The next frame this layer originates (acknowledgement, retransmission, released message),
    /// due at or before `now`; `None` when there is nothing to send now.
    fn poll_transmit(&mut self, _now: Time) -> Option<Envelope> {
        None
    }
    /// When `poll_transmit` will next have something without any new input (a retransmission
    /// timer); `None` if never.
    fn next_deadline(&self) -> Option<Time> {
        None
    }
    /// Told to the layers below the one that dropped an inbound envelope (`id` from `sender`), so
    /// they can undo what they recorded for it (the communication layer forgets the id and
    /// withdraws its acknowledgement when the frame was not authentic).
    fn rejected_above(&mut self, _id: MsgId, _sender: &str, _reason: Reason) {}
    /// Moves rejections the layer decided on its own (not as a verdict, e.g. a message given up
    /// after its last retransmission) into `into`.
    fn drain_rejections(&mut self, _into: &mut Counters) {}
    /// A peer this layer found to have lost the state its frames depend on (the security layer:
    /// a receiver that restarted and asked for a new key). A [`Stack`] then takes back the
    /// frames the layers below still hold for that peer ([`Layer::withdraw`]) and hands each to
    /// this layer again ([`Layer::reclaim`]), so none is retransmitted in a form the peer can no
    /// longer accept.
    fn poll_lost_peer(&mut self) -> Option<String> {
        None
    }
    /// Gives up the frames held for `peer` (copies kept for retransmission), for a layer above
    /// to send again.
    fn withdraw(&mut self, _peer: &str) -> Vec<Envelope> {
        Vec::new()
    }
    /// A frame this layer passed down earlier, withdrawn from below because its peer lost
    /// state: [`Verdict::Pass`] sends it down again as it is, [`Verdict::Consumed`] means the
    /// layer took it back (to send it again later through [`Layer::poll_transmit`]),
    /// [`Verdict::Drop`] counts and discards it.
    fn reclaim(&mut self, _env: &mut Envelope, _now: Time) -> Verdict {
        Verdict::Pass
    }
    /// False if the layer never originates frames (`poll_transmit` is always `None`) nor decides
    /// rejections on its own (`drain_rejections` adds nothing): a [`Stack`] then does not ask
    /// it for either. Default true.
    fn originates(&self) -> bool {
        true
    }
}

/// The no-op layer: passes everything both ways. Use it where a layer is switched off.
#[derive(Debug, Clone, Copy, Default)]
pub struct PassThrough;

impl Layer for PassThrough {
    fn name(&self) -> &'static str {
        "pass-through"
    }
    fn outbound(&mut self, _env: &mut Envelope, _now: Time) -> Verdict {
        Verdict::Pass
    }
    fn inbound(&mut self, _env: &mut Envelope, _now: Time) -> Verdict {
        Verdict::Pass
    }
    fn originates(&self) -> bool {
        false
    }
}

/// Layers in order, top (agent side) first; itself a [`Layer`]. Counts every rejection.
pub struct Stack {
    layers: Vec<Box<dyn Layer>>,
    /// Indexes of the layers that may originate frames or rejections ([`Layer::originates`]).
    originating: Vec<usize>,
    counters: Counters,
    outbox: std::collections::VecDeque<Envelope>,
    /// One WARN per rejection reason per [`WARN_PERIOD`]: an attack shows at the default log
    /// level without one line per frame.
    warn: WarnEvery<Reason>,
}

/// Shortest interval between two warnings about inbound rejections of one reason.
pub const WARN_PERIOD: std::time::Duration = std::time::Duration::from_secs(10);

impl Default for Stack {
    fn default() -> Self {
        Stack {
            layers: Vec::new(),
            originating: Vec::new(),
            counters: Counters::default(),
            outbox: std::collections::VecDeque::new(),
            warn: WarnEvery::new(WARN_PERIOD),
        }
    }
}

impl std::fmt::Debug for Stack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Stack")
            .field(
                "layers",
                &self.layers.iter().map(|l| l.name()).collect::<Vec<_>>(),
            )
            .field("counters", &self.counters)
            .finish()
    }
}

impl Stack {
    /// An empty stack (passes everything).
    pub fn new() -> Stack {
        Stack::default()
    }
    /// Adds `layer` below the ones already pushed (closer to the transport).
    #[must_use]
    pub fn push(mut self, layer: impl Layer + 'static) -> Stack {
        self.push_boxed(Box::new(layer));
        self
    }
    /// Adds a boxed layer below the ones already pushed.
    pub fn push_boxed(&mut self, layer: Box<dyn Layer>) {
        if layer.originates() {
            self.originating.push(self.layers.len());
        }
        self.layers.push(layer);
    }
    /// Names of the layers, top first.
    pub fn layer_names(&self) -> Vec<&'static str> {
        self.layers.iter().map(|l| l.name()).collect()
    }
    /// Rejections so far, per reason.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }
    /// Counts a rejection made outside the layers (by the bus: undecodable frame, no route).
    pub fn record(&mut self, reason: Reason) {
        self.counters.record(reason);
    }

    /// As [`Stack::record`], for a rejection that must show in the log: `Some(held_back)` when
    /// the caller is to warn about it at `now` (one warning per reason per [`WARN_PERIOD`], with
    /// how many were held back since the last one).
    pub fn record_and_admit(&mut self, reason: Reason, now: Time) -> Option<u64> {
        self.counters.record(reason);
        self.warn.admit(reason, now)
    }

    /// Runs `env` down the layers from `first`: true if it passed them all (a drop is counted).
    fn down_from(&mut self, first: usize, env: &mut Envelope, now: Time) -> bool {
        for i in first..self.layers.len() {
            match self.layers[i].outbound(env, now) {
                Verdict::Pass => {}
                Verdict::Drop(r) => {
                    tracing::debug!(layer = self.layers[i].name(), reason = %r, "outbound drop");
                    self.counters.record(r);
                    return false;
                }
                Verdict::Consumed => return false,
            }
        }
        true
    }

    /// Layer `i` dropped an inbound envelope (`id` from `sender`, as it arrived): count it and
    /// tell the layers below.
    #[cold]
    #[inline(never)]
    fn inbound_dropped(&mut self, i: usize, id: MsgId, sender: &str, r: Reason, now: Time) {
        tracing::debug!(layer = self.layers[i].name(), reason = %r, "inbound drop");
        self.counters.record(r);
        // Repeats are the communication layer's everyday work (a lost acknowledgement).
        if r != Reason::Duplicate
            && let Some(held_back) = self.warn.admit(r, now)
        {
            tracing::warn!(layer = self.layers[i].name(), reason = %r, %sender, held_back, total = self.counters.get(r), "inbound frame rejected (one warning per reason per 10 s)");
        }
        for below in &mut self.layers[i + 1..] {
            below.rejected_above(id, sender, r);
        }
    }

    /// Layer `i` found `peer` lost its state: the frames the layers below hold for it go back
    /// to layer `i`, and down again as it decides.
    #[cold]
    fn reclaim_for(&mut self, i: usize, peer: &str, now: Time) {
        let withdrawn: Vec<Envelope> = self.layers[i + 1..]
            .iter_mut()
            .flat_map(|below| below.withdraw(peer))
            .collect();
        tracing::debug!(layer = self.layers[i].name(), %peer, frames = withdrawn.len(), "peer lost its state; frames reclaimed");
        for mut env in withdrawn {
            match self.layers[i].reclaim(&mut env, now) {
                Verdict::Pass => {
                    if self.down_from(i + 1, &mut env, now) {
                        self.outbox.push_back(env);
                    }
                }
                Verdict::Drop(r) => self.counters.record(r),
                Verdict::Consumed => {}
            }
        }
    }

    fn collect_transmits(&mut self, now: Time) {
        for k in 0..self.originating.len() {
            let i = self.originating[k];
            while let Some(peer) = self.layers[i].poll_lost_peer() {
                self.reclaim_for(i, &peer, now);
            }
            while let Some(mut env) = self.layers[i].poll_transmit(now) {
                if self.down_from(i + 1, &mut env, now) {
                    self.outbox.push_back(env);
                }
            }
            self.layers[i].drain_rejections(&mut self.counters);
        }
    }
}

impl Layer for Stack {
    fn name(&self) -> &'static str {
        "stack"
    }
    /// A drop is counted here and reported as [`Verdict::Consumed`] (nothing to forward).
    fn outbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        if self.down_from(0, env, now) {
            Verdict::Pass
        } else {
            Verdict::Consumed
        }
    }
    fn inbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        for i in (0..self.layers.len()).rev() {
            match self.layers[i].inbound(env, now) {
                Verdict::Pass => {}
                Verdict::Drop(r) => {
                    // The layers leave the id and the sender as they arrived (see `Layer`):
                    // these are what the layers below saw.
                    self.inbound_dropped(i, env.header.id, &env.header.sender, r, now);
                    return Verdict::Drop(r);
                }
                Verdict::Consumed => return Verdict::Consumed,
            }
        }
        Verdict::Pass
    }
    fn poll_transmit(&mut self, now: Time) -> Option<Envelope> {
        if self.outbox.is_empty() {
            self.collect_transmits(now);
        }
        self.outbox.pop_front()
    }
    fn next_deadline(&self) -> Option<Time> {
        if !self.outbox.is_empty() {
            return Some(Time::ZERO);
        }
        self.layers.iter().filter_map(|l| l.next_deadline()).min()
    }
}

/// One of the four layers, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LayerKind {
    /// Syntax and sender registration (top).
    Parser,
    /// Timestamps, sequence numbers.
    Temporal,
    /// Confidentiality, integrity, authenticity.
    Security,
    /// De-duplication, retransmission, size limits (bottom).
    Comm,
}

impl LayerKind {
    /// All four, top to bottom.
    pub const ALL: [LayerKind; 4] = [
        LayerKind::Parser,
        LayerKind::Temporal,
        LayerKind::Security,
        LayerKind::Comm,
    ];

    /// Lower-case name, as in `--layers parser,comm`.
    pub fn name(self) -> &'static str {
        match self {
            LayerKind::Parser => "parser",
            LayerKind::Temporal => "temporal",
            LayerKind::Security => "security",
            LayerKind::Comm => "comm",
        }
    }
}

/// Which layers a deployment switches on. Parses from `all`, `none`, or a comma list such as
/// `comm,security`; always applied in the thesis order (parser, temporal, security, comm).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LayerSet(Vec<LayerKind>);

impl LayerSet {
    /// All four layers.
    pub fn all() -> LayerSet {
        LayerSet(LayerKind::ALL.to_vec())
    }
    /// No layer: frames go straight to the transport.
    pub fn none() -> LayerSet {
        LayerSet(Vec::new())
    }
    /// Exactly the given layers (any order, duplicates ignored).
    pub fn of(kinds: &[LayerKind]) -> LayerSet {
        LayerSet(
            LayerKind::ALL
                .iter()
                .copied()
                .filter(|k| kinds.contains(k))
                .collect(),
        )
    }
    /// True if `kind` is switched on.
    pub fn contains(&self, kind: LayerKind) -> bool {
        self.0.contains(&kind)
    }
    /// The layers switched on, top to bottom.
    pub fn kinds(&self) -> &[LayerKind] {
        &self.0
    }
}

impl std::fmt::Display for LayerSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_empty() {
            return f.write_str("none");
        }
        if self.0.len() == LayerKind::ALL.len() {
            return f.write_str("all");
        }
        let names: Vec<_> = self.0.iter().map(|k| k.name()).collect();
        f.write_str(&names.join(","))
    }
}

impl FromStr for LayerSet {
    type Err = BusError;
    fn from_str(s: &str) -> Result<LayerSet, BusError> {
        match s.trim() {
            "all" => return Ok(LayerSet::all()),
            "none" | "" => return Ok(LayerSet::none()),
            _ => {}
        }
        let mut kinds = Vec::new();
        for part in s.split(',') {
            let part = part.trim();
            let kind = LayerKind::ALL
                .iter()
                .find(|k| k.name() == part)
                .ok_or_else(|| BusError::UnknownLayer {
                    name: part.to_string(),
                })?;
            kinds.push(*kind);
        }
        Ok(LayerSet::of(&kinds))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Drops payloads starting with `x` inbound; on outbound, queues an extra copy for poll.
    struct Picky {
        echo: Option<Envelope>,
    }
    impl Layer for Picky {
        fn name(&self) -> &'static str {
            "picky"
        }
        fn outbound(&mut self, env: &mut Envelope, _now: Time) -> Verdict {
            self.echo = Some(env.clone());
            Verdict::Pass
        }
        fn inbound(&mut self, env: &mut Envelope, _now: Time) -> Verdict {
            if env.payload.first() == Some(&b'x') {
                Verdict::Drop(Reason::Malformed)
            } else {
                Verdict::Pass
            }
        }
        fn poll_transmit(&mut self, _now: Time) -> Option<Envelope> {
            self.echo.take()
        }
    }

    /// Appends a byte outbound, so the test sees which layers a frame went through.
    struct Mark(u8);
    impl Layer for Mark {
        fn name(&self) -> &'static str {
            "mark"
        }
        fn outbound(&mut self, env: &mut Envelope, _now: Time) -> Verdict {
            env.payload.push(self.0);
            Verdict::Pass
        }
        fn inbound(&mut self, _env: &mut Envelope, _now: Time) -> Verdict {
            Verdict::Pass
        }
    }

    fn env(p: &[u8]) -> Envelope {
        Envelope::new(MsgId(1), "a", "b", p.to_vec())
    }

    #[test]
    fn stack_orders_counts_and_forwards_transmits_below_origin() {
        let mut s = Stack::new()
            .push(Mark(b'1'))
            .push(Picky { echo: None })
            .push(Mark(b'2'));
        let mut out = env(b"m");
        assert_eq!(s.outbound(&mut out, Time::ZERO), Verdict::Pass);
        assert_eq!(out.payload, b"m12");
        // The echo was made by the middle layer: it passes only the layer below it.
        // (not "m112": it does not pass the layer above its origin again).
        assert_eq!(s.poll_transmit(Time::ZERO).unwrap().payload, b"m12");
        assert!(s.poll_transmit(Time::ZERO).is_none());
        assert_eq!(
            s.inbound(&mut env(b"x"), Time::ZERO),
            Verdict::Drop(Reason::Malformed)
        );
        assert_eq!(s.inbound(&mut env(b"ok"), Time::ZERO), Verdict::Pass);
        assert_eq!(s.counters().get(Reason::Malformed), 1);
        assert_eq!(s.counters().to_string(), "malformed=1");
    }

    #[test]
    fn pass_through_and_empty_stack_pass() {
        let mut p = PassThrough;
        let mut e = env(b"a");
        assert_eq!(p.inbound(&mut e, Time::ZERO), Verdict::Pass);
        assert_eq!(e, env(b"a"));
        let mut s = Stack::new();
        assert_eq!(s.outbound(&mut e, Time::ZERO), Verdict::Pass);
        assert_eq!(e, env(b"a"));
    }

    #[test]
    fn layer_sets_parse() {
        assert_eq!("all".parse::<LayerSet>().unwrap(), LayerSet::all());
        assert_eq!("none".parse::<LayerSet>().unwrap(), LayerSet::none());
        let s: LayerSet = "comm, parser".parse().unwrap();
        assert_eq!(s.kinds(), &[LayerKind::Parser, LayerKind::Comm]);
        assert_eq!(s.to_string(), "parser,comm");
        assert!(matches!(
            "comm,foo".parse::<LayerSet>(),
            Err(BusError::UnknownLayer { .. })
        ));
    }
}
