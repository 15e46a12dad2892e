//! Communication layer (thesis 3.3.3, lowest layer): de-duplication by message id,
//! retransmission until acknowledged, and the receiving agent's size limit.
//!
//! # Organization
//! - [`CommLayer`]: the [`Layer`]; [`CommConfig`]: its settings; [`CommStats`]: what it did.
//!
//! # Guarantees
//! With this layer at both ends of a datagram link that loses, duplicates and reorders frames:
//! - **no loss** (EN 50159 *deletion*): every non-acknowledgement frame is kept and sent again
//!   with exponential backoff (`initial_rto`, doubling, capped at `max_rto`) until the receiver
//!   acknowledges it, or counted [`Reason::Undeliverable`] after `max_attempts` sends;
//! - **no double delivery** (EN 50159 *repetition*): a receiver passes each `(sender, message
//!   id)` once within a bounded window of recent ids per sender (`dedup_window`), and
//!   re-acknowledges repeats (the first acknowledgement may have been lost);
//! - **size limit**: a message whose payload exceeds the limit configured for its receiving agent
//!   is never delivered ([`Reason::TooLarge`]).
//!
//! Frames a layer above refuses as not authentic ([`Reason::is_authenticity_failure`]: a
//! corrupted or forged copy) are forgotten again and not acknowledged, so the sender retransmits
//! and the genuine frame is delivered; with the security layer on, corruption therefore costs a
//! retransmission, never a message.
//!
//! Not covered here: ordering (temporal layer), authenticity (security layer). An
//! acknowledgement echoes the last 16 payload bytes of the frame it acknowledges; with the
//! security layer on these are AEAD tag bytes, so only someone who saw the frame can forge its
//! acknowledgement (and such an attacker could drop the frame anyway).
//!
//! # Acknowledgement frames
//! Acknowledgements waiting to go out to the same agent from the same agent share one frame
//! (up to [`ACKS_PER_FRAME`] of them): a burst of messages costs one acknowledgement frame, not
//! one each. Its payload is a run of entries, each the acknowledged message id (8 bytes, big
//! endian) and the echo (16 bytes; a payload shorter than that is echoed right-aligned after
//! zeros).
//! Ids older than the window are no longer recognised: the temporal layer's age limit and
//! sequence window reject such late replays.
#![warn(missing_docs)]

use std::collections::hash_map::Entry;
use std::collections::{HashMap, HashSet, VecDeque};
use std::time::Duration;

use iw_bus::{Counters, Envelope, Flags, IdGen, Layer, MsgId, Reason, Time, Verdict};
use rustc_hash::FxHashMap;

/// Bytes of the acknowledged frame's payload an acknowledgement echoes.
const ECHO_LEN: usize = 16;

/// Bytes of one acknowledgement entry: the message id and the echo.
const ACK_ENTRY_LEN: usize = 8 + ECHO_LEN;

/// Acknowledgements one frame carries at most: 1152 payload bytes, so a frame of them still fits
/// an Ethernet datagram unfragmented.
pub const ACKS_PER_FRAME: usize = 48;

/// Settings of the communication layer. Durations are simulated or real time alike.
#[derive(Debug, Clone, PartialEq)]
pub struct CommConfig {
    /// Recent message ids remembered per sender for de-duplication (default 4096).
    pub dedup_window: usize,
    /// Senders tracked at once; beyond it the window of an arbitrary sender is forgotten
    /// (default 4096).
    pub max_senders: usize,
    /// First retransmission timeout (default 20 ms).
    pub initial_rto: Duration,
    /// Largest retransmission timeout after doubling (default 1 s).
    pub max_rto: Duration,
    /// Sends of one frame before it is given up as undeliverable (default 16).
    pub max_attempts: u32,
    /// Payload limit for receiving agents without their own entry, bytes (default 64 KiB).
    pub default_max_payload: usize,
    /// Payload limit per receiving agent name, bytes.
    pub max_payload: HashMap<String, usize>,
}

impl Default for CommConfig {
    fn default() -> Self {
        CommConfig {
            dedup_window: 4096,
            max_senders: 4096,
            initial_rto: Duration::from_millis(20),
            max_rto: Duration::from_secs(1),
            max_attempts: 16,
            default_max_payload: 64 * 1024,
            max_payload: HashMap::new(),
        }
    }
}

impl CommConfig {
    /// The payload limit of receiving agent `agent`, bytes.
    pub fn limit_for(&self, agent: &str) -> usize {
        self.max_payload
            .get(agent)
            .copied()
            .unwrap_or(self.default_max_payload)
    }
    /// Retransmission timeout before send number `attempt + 1` (attempt counts from 1).
    pub fn rto(&self, attempt: u32) -> Duration {
        let factor = 1u32
            .checked_shl(attempt.saturating_sub(1))
            .unwrap_or(u32::MAX);
        self.initial_rto.saturating_mul(factor).min(self.max_rto)
    }
}

/// What the layer did, for reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CommStats {
    /// Frames sent again after a timeout.
    pub retransmissions: u64,
    /// Acknowledgements sent (including repeats for duplicates).
    pub acks_sent: u64,
    /// Frames those acknowledgements went out in (several share a frame).
    pub ack_frames: u64,
    /// Acknowledgements that matched a frame in flight.
    pub acks_matched: u64,
    /// Acknowledgements for nothing in flight (late repeats, or forged).
    pub acks_stray: u64,
}

struct Pending {
    env: Envelope,
    next_at: Time,
    attempts: u32,
}

#[derive(Default)]
struct Window {
    order: VecDeque<MsgId>,
    ids: HashSet<MsgId>,
}

impl Window {
    /// Records `id`; false if it was already there.
    fn insert(&mut self, id: MsgId, cap: usize) -> bool {
        if !self.ids.insert(id) {
            return false;
        }
        self.order.push_back(id);
        while self.order.len() > cap.max(1) {
            if let Some(old) = self.order.pop_front() {
                self.ids.remove(&old);
            }
        }
        true
    }

    fn remove(&mut self, id: MsgId) {
        if self.ids.remove(&id) {
            self.order.retain(|x| *x != id);
        }
    }
}

/// The communication layer. Put it lowest in the stack, right above the transport.
pub struct CommLayer {
    config: CommConfig,
    seen: HashMap<String, Window>,
    /// Keyed by our own message ids (acknowledgements only look up), hence the fast hash.
    in_flight: FxHashMap<MsgId, Pending>,
    /// No frame in flight is due before this (a lower bound; exact after a scan found none due).
    earliest: Time,
    acks: VecDeque<Envelope>,
    ids: IdGen,
    stats: CommStats,
    undeliverable: u64,
}

impl CommLayer {
    /// A layer with the given settings.
    pub fn new(config: CommConfig) -> CommLayer {
        CommLayer {
            config,
            seen: HashMap::new(),
            in_flight: FxHashMap::default(),
            earliest: Time::ZERO,
            acks: VecDeque::new(),
            ids: IdGen::new(),
            stats: CommStats::default(),
            undeliverable: 0,
        }
    }
    /// What the layer did so far.
    pub fn stats(&self) -> CommStats {
        self.stats
    }
    /// Frames sent and not yet acknowledged.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Queues the acknowledgement of `acked`, in a frame already waiting for the same pair of
    /// agents if one has room.
    fn queue_ack(&mut self, acked: &Envelope, now: Time) {
        let (from, to) = (&acked.header.receiver, &acked.header.sender);
        self.stats.acks_sent += 1;
        let room = self.acks.iter_mut().rev().find(|a| {
            a.payload.len() < ACKS_PER_FRAME * ACK_ENTRY_LEN
                && a.header.sender == *from
                && a.header.receiver == *to
        });
        if let Some(ack) = room {
            push_entry(&mut ack.payload, acked);
            return;
        }
        let mut payload = Vec::with_capacity(4 * ACK_ENTRY_LEN);
        push_entry(&mut payload, acked);
        let mut ack = Envelope::new(self.ids.next_id(), from.as_str(), to.as_str(), payload);
        ack.header.flags = Flags::ACK;
        ack.header.timestamp = now;
        self.acks.push_back(ack);
        self.stats.ack_frames += 1;
    }

    fn on_ack(&mut self, ack: &Envelope) {
        for entry in ack.payload.chunks(ACK_ENTRY_LEN) {
            let Some((id, echoed)) = split_entry(entry) else {
                self.stats.acks_stray += 1;
                continue;
            };
            match self.in_flight.entry(id) {
                Entry::Occupied(p)
                    if p.get().env.header.receiver == ack.header.sender
                        && echo(&p.get().env.payload) == echoed =>
                {
                    p.remove();
                    self.stats.acks_matched += 1;
                }
                _ => self.stats.acks_stray += 1,
            }
        }
    }

    /// Records `id` in `sender`'s window; false if it was already there. Looks the sender up
    /// once, and copies its name only for a sender not seen before.
    fn remember(&mut self, sender: &str, id: MsgId) -> bool {
        let cap = self.config.dedup_window;
        if let Some(w) = self.seen.get_mut(sender) {
            return w.insert(id, cap);
        }
        if self.seen.len() >= self.config.max_senders.max(1)
            && let Some(victim) = self.seen.keys().next().cloned()
        {
            self.seen.remove(&victim);
        }
        let mut w = Window::default();
        let fresh = w.insert(id, cap);
        self.seen.insert(sender.to_string(), w);
        fresh
    }

    /// The payload limit of `agent`, without hashing when no agent has its own limit.
    fn limit_for(&self, agent: &str) -> usize {
        if self.config.max_payload.is_empty() {
            self.config.default_max_payload
        } else {
            self.config.limit_for(agent)
        }
    }
}

/// The last [`ECHO_LEN`] bytes of `payload`, right-aligned after zeros if it is shorter.
fn echo(payload: &[u8]) -> [u8; ECHO_LEN] {
    let tail = &payload[payload.len().saturating_sub(ECHO_LEN)..];
    let mut out = [0u8; ECHO_LEN];
    out[ECHO_LEN - tail.len()..].copy_from_slice(tail);
    out
}

/// Appends the acknowledgement entry of `acked` to an acknowledgement payload.
fn push_entry(payload: &mut Vec<u8>, acked: &Envelope) {
    payload.extend_from_slice(&acked.header.id.0.to_be_bytes());
    payload.extend_from_slice(&echo(&acked.payload));
}

/// An entry's message id and echo; `None` for a short (malformed) entry.
fn split_entry(entry: &[u8]) -> Option<(MsgId, &[u8])> {
    let (id, echoed) = entry.split_first_chunk::<8>()?;
    (echoed.len() == ECHO_LEN).then_some((MsgId(u64::from_be_bytes(*id)), echoed))
}

impl Layer for CommLayer {
    fn name(&self) -> &'static str {
        "comm"
    }

    fn outbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        if env.header.flags.contains(Flags::ACK) {
            return Verdict::Pass;
        }
        let limit = self.limit_for(&env.header.receiver);
        if env.payload.len() > limit {
            tracing::debug!(receiver = %env.header.receiver, len = env.payload.len(), limit, "outbound too large");
            return Verdict::Drop(Reason::TooLarge);
        }
        let next_at = now.plus(self.config.rto(1));
        self.earliest = if self.in_flight.is_empty() {
            next_at
        } else {
            self.earliest.min(next_at)
        };
        self.in_flight.insert(
            env.header.id,
            Pending {
                env: env.clone(),
                next_at,
                attempts: 1,
            },
        );
        Verdict::Pass
    }

    fn inbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        if env.header.flags.contains(Flags::ACK) {
            self.on_ack(env);
            return Verdict::Consumed;
        }
        // Acknowledge first: the sender must stop retransmitting even what we then reject.
        self.queue_ack(env, now);
        if !self.remember(&env.header.sender, env.header.id) {
            return Verdict::Drop(Reason::Duplicate);
        }
        let limit = self.limit_for(&env.header.receiver);
        if env.payload.len() > limit {
            tracing::debug!(receiver = %env.header.receiver, len = env.payload.len(), limit, "inbound too large");
            return Verdict::Drop(Reason::TooLarge);
        }
        Verdict::Pass
    }

    fn poll_transmit(&mut self, now: Time) -> Option<Envelope> {
        if let Some(ack) = self.acks.pop_front() {
            return Some(ack);
        }
        // No frame is due before `earliest`: skip the scan (it grows with the frames in flight).
        if self.in_flight.is_empty() || now < self.earliest {
            return None;
        }
        let mut due = None;
        let mut earliest = None::<Time>;
        for (id, p) in &self.in_flight {
            if p.next_at <= now {
                due = Some(*id);
                break;
            }
            earliest = Some(earliest.map_or(p.next_at, |e| e.min(p.next_at)));
        }
        let Some(due) = due else {
            // Nothing due: every frame's time was seen, so this is the exact earliest.
            self.earliest = earliest.unwrap_or(self.earliest);
            return None;
        };
        let give_up = self
            .in_flight
            .get(&due)
            .is_some_and(|p| p.attempts >= self.config.max_attempts);
        if give_up {
            if let Some(p) = self.in_flight.remove(&due) {
                tracing::warn!(id = %due, receiver = %p.env.header.receiver, attempts = p.attempts, "undeliverable");
            }
            self.undeliverable += 1;
            return self.poll_transmit(now);
        }
        let rto = |a| self.config.rto(a);
        let p = self.in_flight.get_mut(&due)?;
        p.attempts += 1;
        p.next_at = now.plus(rto(p.attempts));
        self.stats.retransmissions += 1;
        Some(p.env.clone())
    }

    fn next_deadline(&self) -> Option<Time> {
        if !self.acks.is_empty() {
            return Some(Time::ZERO);
        }
        self.in_flight.values().map(|p| p.next_at).min()
    }

    fn withdraw(&mut self, peer: &str) -> Vec<Envelope> {
        let ids: Vec<MsgId> = self
            .in_flight
            .iter()
            .filter(|(_, p)| p.env.header.receiver == peer)
            .map(|(id, _)| *id)
            .collect();
        ids.into_iter()
            .filter_map(|id| self.in_flight.remove(&id))
            .map(|p| p.env)
            .collect()
    }

    fn rejected_above(&mut self, id: MsgId, sender: &str, reason: Reason) {
        if !reason.is_authenticity_failure() {
            return;
        }
        // Not what the sender sent (corrupted, forged): forget it, so that the genuine frame is
        // neither taken for a duplicate nor left unretransmitted.
        if let Some(w) = self.seen.get_mut(sender) {
            w.remove(id);
        }
        let entry_of = |a: &Envelope| {
            (a.header.receiver == sender)
                .then(|| {
                    a.payload
                        .chunks(ACK_ENTRY_LEN)
                        .rposition(|e| split_entry(e).is_some_and(|(acked, _)| acked == id))
                })
                .flatten()
        };
        if let Some((at, entry)) = self
            .acks
            .iter()
            .enumerate()
            .rev()
            .find_map(|(at, a)| entry_of(a).map(|e| (at, e)))
        {
            let ack = &mut self.acks[at];
            ack.payload
                .drain(entry * ACK_ENTRY_LEN..(entry + 1) * ACK_ENTRY_LEN);
            if ack.payload.is_empty() {
                self.acks.remove(at);
                self.stats.ack_frames -= 1;
            }
            self.stats.acks_sent -= 1;
        }
    }

    fn drain_rejections(&mut self, into: &mut Counters) {
        for _ in 0..std::mem::take(&mut self.undeliverable) {
            into.record(Reason::Undeliverable);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(id: u64, payload: &[u8]) -> Envelope {
        Envelope::new(MsgId(id), "a", "b", payload.to_vec())
    }

    /// `env` as `layer` passed it outbound.
    fn pass_out(layer: &mut CommLayer, mut env: Envelope, now: Time) -> Envelope {
        match layer.outbound(&mut env, now) {
            Verdict::Pass => env,
            other => panic!("expected pass, got {other:?}"),
        }
    }

    /// `env` as `layer` passed it inbound.
    fn pass_in(layer: &mut CommLayer, mut env: Envelope, now: Time) -> Envelope {
        match layer.inbound(&mut env, now) {
            Verdict::Pass => env,
            other => panic!("expected pass, got {other:?}"),
        }
    }

    #[test]
    fn duplicate_dropped_but_reacknowledged() {
        let mut rx = CommLayer::new(CommConfig::default());
        pass_in(&mut rx, data(1, b"hello"), Time::ZERO);
        assert_eq!(
            rx.inbound(&mut data(1, b"hello"), Time::ZERO),
            Verdict::Drop(Reason::Duplicate)
        );
        let ack = rx.poll_transmit(Time::ZERO).unwrap();
        assert!(ack.header.flags.contains(Flags::ACK));
        assert_eq!(
            ack.payload.len(),
            2 * ACK_ENTRY_LEN,
            "the repeat is acknowledged again"
        );
        assert!(rx.poll_transmit(Time::ZERO).is_none());
    }

    #[test]
    fn window_is_bounded() {
        let mut rx = CommLayer::new(CommConfig {
            dedup_window: 2,
            ..CommConfig::default()
        });
        for id in 1..=3 {
            pass_in(&mut rx, data(id, b"x"), Time::ZERO);
        }
        // Id 1 left the window: recognised no more (the temporal layer catches such replays).
        pass_in(&mut rx, data(1, b"x"), Time::ZERO);
        assert_eq!(
            rx.inbound(&mut data(3, b"x"), Time::ZERO),
            Verdict::Drop(Reason::Duplicate)
        );
    }

    #[test]
    fn retransmits_with_backoff_until_acked() {
        let cfg = CommConfig {
            initial_rto: Duration::from_millis(10),
            max_rto: Duration::from_millis(40),
            ..CommConfig::default()
        };
        let mut tx = CommLayer::new(cfg);
        let mut rx = CommLayer::new(CommConfig::default());
        let sent = pass_out(&mut tx, data(7, b"payload"), Time::ZERO);
        let ms = |m| Time::ZERO.plus(Duration::from_millis(m));
        assert!(tx.poll_transmit(ms(9)).is_none());
        assert_eq!(tx.next_deadline(), Some(ms(10)));
        assert_eq!(tx.poll_transmit(ms(10)).unwrap(), sent);
        assert!(
            tx.poll_transmit(ms(29)).is_none(),
            "second timeout doubles to 20 ms"
        );
        assert_eq!(tx.poll_transmit(ms(30)).unwrap(), sent);
        assert_eq!(
            tx.next_deadline(),
            Some(ms(70)),
            "third timeout capped at 40 ms"
        );
        pass_in(&mut rx, sent, ms(31));
        let mut ack = rx.poll_transmit(ms(31)).unwrap();
        assert_eq!(tx.inbound(&mut ack, ms(32)), Verdict::Consumed);
        assert_eq!(tx.in_flight(), 0);
        assert!(tx.poll_transmit(ms(1000)).is_none());
        assert_eq!(tx.stats().retransmissions, 2);
    }

    #[test]
    fn gives_up_and_counts_undeliverable() {
        let cfg = CommConfig {
            max_attempts: 3,
            initial_rto: Duration::from_millis(1),
            ..CommConfig::default()
        };
        let mut tx = CommLayer::new(cfg);
        pass_out(&mut tx, data(1, b"x"), Time::ZERO);
        let mut t = Time::ZERO;
        let mut sends = 1;
        for _ in 0..20 {
            t = t.plus(Duration::from_millis(100));
            while tx.poll_transmit(t).is_some() {
                sends += 1;
            }
        }
        assert_eq!(sends, 3);
        let mut c = Counters::default();
        tx.drain_rejections(&mut c);
        assert_eq!(c.get(Reason::Undeliverable), 1);
    }

    #[test]
    fn forged_ack_without_echo_is_ignored() {
        let mut tx = CommLayer::new(CommConfig::default());
        pass_out(&mut tx, data(5, b"secret tag bytes 0123456789"), Time::ZERO);
        let mut forged = Envelope::new(MsgId(99), "b", "a", 5u64.to_be_bytes().to_vec());
        forged.header.flags = Flags::ACK;
        assert_eq!(tx.inbound(&mut forged, Time::ZERO), Verdict::Consumed);
        assert_eq!(tx.in_flight(), 1);
        assert_eq!(tx.stats().acks_stray, 1);
    }

    #[test]
    fn inauthentic_frame_forgotten_and_not_acknowledged() {
        let mut rx = CommLayer::new(CommConfig::default());
        pass_in(&mut rx, data(1, b"altered"), Time::ZERO);
        rx.rejected_above(MsgId(1), "a", Reason::BadTag);
        assert!(
            rx.poll_transmit(Time::ZERO).is_none(),
            "acknowledgement withdrawn"
        );
        pass_in(&mut rx, data(1, b"genuine"), Time::ZERO);
        // A policy rejection of an authentic frame keeps it acknowledged.
        rx.rejected_above(MsgId(1), "a", Reason::Stale);
        assert!(rx.poll_transmit(Time::ZERO).is_some());
        assert_eq!(
            rx.inbound(&mut data(1, b"genuine"), Time::ZERO),
            Verdict::Drop(Reason::Duplicate)
        );
    }

    #[test]
    fn acknowledgements_of_a_burst_share_frames() {
        let mut tx = CommLayer::new(CommConfig::default());
        let mut rx = CommLayer::new(CommConfig::default());
        let n = ACKS_PER_FRAME as u64 + 2;
        for id in 0..n {
            // Payloads shorter and longer than the echo.
            let sent = pass_out(
                &mut tx,
                data(id, &b"0123456789abcdefghij"[..(id % 20) as usize + 1]),
                Time::ZERO,
            );
            pass_in(&mut rx, sent, Time::ZERO);
        }
        // Another sender's acknowledgement goes in its own frame.
        pass_in(
            &mut rx,
            Envelope::new(MsgId(1), "c", "b", b"x".to_vec()),
            Time::ZERO,
        );
        let frames: Vec<_> = std::iter::from_fn(|| rx.poll_transmit(Time::ZERO)).collect();
        let sizes: Vec<_> = frames
            .iter()
            .map(|f| (f.header.receiver.as_str(), f.payload.len() / ACK_ENTRY_LEN))
            .collect();
        assert_eq!(sizes, [("a", ACKS_PER_FRAME), ("a", 2), ("c", 1)]);
        assert_eq!((rx.stats().acks_sent, rx.stats().ack_frames), (n + 1, 3));
        for mut f in frames.into_iter().take(2) {
            assert_eq!(tx.inbound(&mut f, Time::ZERO), Verdict::Consumed);
        }
        assert_eq!(tx.in_flight(), 0);
        assert_eq!(tx.stats().acks_matched, n);
    }

    #[test]
    fn withdrawn_acknowledgement_leaves_the_others_in_its_frame() {
        let mut tx = CommLayer::new(CommConfig::default());
        let mut rx = CommLayer::new(CommConfig::default());
        for id in 1..=3 {
            pass_in(
                &mut rx,
                pass_out(&mut tx, data(id, b"payload"), Time::ZERO),
                Time::ZERO,
            );
        }
        rx.rejected_above(MsgId(2), "a", Reason::BadTag);
        let mut ack = rx.poll_transmit(Time::ZERO).unwrap();
        assert!(rx.poll_transmit(Time::ZERO).is_none());
        assert_eq!(tx.inbound(&mut ack, Time::ZERO), Verdict::Consumed);
        assert_eq!(tx.in_flight(), 1, "message 2 is still unacknowledged");
        assert_eq!(tx.stats().acks_matched, 2);
    }

    #[test]
    fn ack_with_a_wrong_echo_in_a_shared_frame_matches_only_the_others() {
        let mut tx = CommLayer::new(CommConfig::default());
        let mut rx = CommLayer::new(CommConfig::default());
        pass_in(
            &mut rx,
            pass_out(&mut tx, data(1, b"first"), Time::ZERO),
            Time::ZERO,
        );
        pass_in(
            &mut rx,
            pass_out(&mut tx, data(2, b"second"), Time::ZERO),
            Time::ZERO,
        );
        let mut ack = rx.poll_transmit(Time::ZERO).unwrap();
        let last = ack.payload.len() - 1;
        ack.payload[last] ^= 1;
        ack.payload.push(0);
        assert_eq!(tx.inbound(&mut ack, Time::ZERO), Verdict::Consumed);
        assert_eq!(tx.in_flight(), 1);
        assert_eq!(
            (tx.stats().acks_matched, tx.stats().acks_stray),
            (1, 2),
            "a wrong echo, a short entry"
        );
    }

    #[test]
    fn receiver_size_limit() {
        let mut cfg = CommConfig::default();
        cfg.max_payload.insert("b".into(), 4);
        let mut rx = CommLayer::new(cfg.clone());
        assert_eq!(
            rx.inbound(&mut data(1, b"12345"), Time::ZERO),
            Verdict::Drop(Reason::TooLarge)
        );
        pass_in(&mut rx, data(2, b"1234"), Time::ZERO);
        let mut tx = CommLayer::new(cfg);
        assert_eq!(
            tx.outbound(&mut data(3, b"12345"), Time::ZERO),
            Verdict::Drop(Reason::TooLarge)
        );
    }

    mod shared_ack_frames {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            /// However messages from several senders interleave, and whichever of them prove
            /// inauthentic above: every other message is acknowledged exactly once, no frame mixes
            /// pairs of agents or exceeds its limit, and the withdrawn ones stay in flight.
            #[test]
            fn every_message_acknowledged_once(ops in prop::collection::vec((0usize..3, 0usize..40, any::<bool>()), 0..200)) {
                let names = ["s0", "s1", "s2"];
                let mut tx: Vec<_> = names.iter().map(|_| CommLayer::new(CommConfig::default())).collect();
                let mut rx = CommLayer::new(CommConfig::default());
                let mut withdrawn = [0usize; 3];
                for (n, (s, len, inauthentic)) in ops.iter().copied().enumerate() {
                    let payload: Vec<u8> = (0..len).map(|i| (i * 7 + n) as u8).collect();
                    let env = Envelope::new(MsgId(n as u64), names[s], "r", payload);
                    let sent = pass_out(&mut tx[s], env, Time::ZERO);
                    pass_in(&mut rx, sent, Time::ZERO);
                    if inauthentic {
                        rx.rejected_above(MsgId(n as u64), names[s], Reason::BadTag);
                        withdrawn[s] += 1;
                    }
                }
                while let Some(mut ack) = rx.poll_transmit(Time::ZERO) {
                    prop_assert!(ack.payload.len() <= ACKS_PER_FRAME * ACK_ENTRY_LEN);
                    prop_assert!(!ack.payload.is_empty() && ack.payload.len() % ACK_ENTRY_LEN == 0);
                    let s = names.iter().position(|n| *n == ack.header.receiver).expect("acknowledges a sender");
                    prop_assert_eq!(tx[s].inbound(&mut ack, Time::ZERO), Verdict::Consumed);
                }
                for s in 0..3 {
                    prop_assert_eq!(tx[s].in_flight(), withdrawn[s]);
                    prop_assert_eq!(tx[s].stats().acks_stray, 0);
                }
                let sent = ops.len() - withdrawn.iter().sum::<usize>();
                prop_assert_eq!(rx.stats().acks_sent as usize, sent);
            }

            /// Any acknowledgement payload: no panic, and it releases exactly the messages in
            /// flight whose id and echo one of its whole entries names.
            #[test]
            fn arbitrary_ack_payload_releases_only_matching_entries(
                lens in prop::collection::vec(0usize..40, 1..6),
                noise in prop::collection::vec(any::<u8>(), 0..120),
                genuine in prop::collection::vec(any::<bool>(), 6),
            ) {
                let mut tx = CommLayer::new(CommConfig::default());
                let mut payload = Vec::new();
                let mut expected = 0;
                for (id, len) in lens.iter().enumerate() {
                    let env = pass_out(&mut tx, data(id as u64, &vec![id as u8 + 1; *len]), Time::ZERO);
                    if genuine[id] {
                        push_entry(&mut payload, &env);
                        expected += 1;
                    }
                }
                payload.extend_from_slice(&noise);
                let mut ack = Envelope::new(MsgId(1000), "b", "a", payload);
                ack.header.flags = Flags::ACK;
                prop_assert_eq!(tx.inbound(&mut ack, Time::ZERO), Verdict::Consumed);
                // Noise names a message in flight with its echo only by a 2^-128 accident.
                prop_assert_eq!(tx.stats().acks_matched, expected as u64);
                prop_assert_eq!(tx.in_flight(), lens.len() - expected);
            }
        }
    }
}
