//! Temporal layer (thesis 3.3.3): every message carries its sender's timestamp and a per-sender
//! sequence number; stale, future, expired and replayed messages are dropped.
//!
//! # Organization
//! - [`TemporalLayer`]: the [`Layer`]; [`TemporalConfig`]: limits; [`Ordering`]: what to do
//!   with out-of-order messages; [`TemporalStats`]: what it saw.
//!
//! # Guarantees
//! On the way out it stamps `timestamp = now` and the sender's next sequence number. On the way
//! in, with `skew` the tolerated clock difference between hosts, it never delivers a message
//! - older than `max_age + skew` (EN 50159 *delay*: [`Reason::Stale`]);
//! - stamped more than `skew` in the future ([`Reason::FromFuture`]);
//! - received more than `skew` after its reply-by ([`Reason::PastReplyBy`]);
//! - whose sequence number from that sender was already accepted (EN 50159 *repetition*, even
//!   after the communication layer's id window has moved on: [`Reason::ReplayedSequence`]);
//! - more than `seq_window` behind the sender's newest (too old to check: [`Reason::OutOfOrder`]).
//!
//! EN 50159 *resequencing*: messages behind the newest accepted one are detected per sender and
//! counted ([`TemporalStats::reordered`]); [`Ordering::Strict`] drops them, [`Ordering::Detect`]
//! (default, for links where the communication layer retransmits) delivers them once.
//!
//! Sequence numbers of a sender start at the clock's nanosecond count when the layer first sends
//! for it, so a restarted sender continues above its old numbers without stored state (as long
//! as its clock moved on by more nanoseconds than it sent messages).
//! Timestamps are only as trustworthy as the header: run the security layer below this one so
//! they cannot be altered.
#![warn(missing_docs)]

use std::collections::HashMap;
use std::time::Duration;

use iw_bus::{Envelope, Layer, Reason, Time, Verdict};
use rustc_hash::FxHashMap;

/// What to do with a message behind the newest accepted one from its sender.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Ordering {
    /// Deliver it (once) and count it as reordered.
    #[default]
    Detect,
    /// Drop it ([`Reason::OutOfOrder`]).
    Strict,
}

/// Limits of the temporal layer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemporalConfig {
    /// Oldest acceptable message, by its timestamp (default 2 s).
    pub max_age: Duration,
    /// Tolerated clock difference between hosts, both ways (default 100 ms).
    pub max_skew: Duration,
    /// Sequence numbers tracked behind a sender's newest (default 4096).
    pub seq_window: u64,
    /// Out-of-order handling (default [`Ordering::Detect`]).
    pub ordering: Ordering,
}

impl Default for TemporalConfig {
    fn default() -> Self {
        TemporalConfig {
            max_age: Duration::from_secs(2),
            max_skew: Duration::from_millis(100),
            seq_window: 4096,
            ordering: Ordering::Detect,
        }
    }
}

/// Observations that are not rejections.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TemporalStats {
    /// Messages that arrived behind a newer one from the same sender.
    pub reordered: u64,
}

/// Sequence numbers accepted from one sender: a ring of `words * 64` bits ending at `newest`.
struct SeqWindow {
    newest: u64,
    bits: Vec<u64>,
}

impl SeqWindow {
    fn new(seq: u64, window: u64) -> SeqWindow {
        let words = usize::try_from(window.div_ceil(64)).unwrap_or(1).max(1);
        let mut w = SeqWindow {
            newest: seq,
            bits: vec![0; words],
        };
        w.set(seq);
        w
    }
    fn span(&self) -> u64 {
        self.bits.len() as u64 * 64
    }
    fn slot(&self, seq: u64) -> (usize, u64) {
        let i = seq % self.span();
        ((i / 64) as usize, 1 << (i % 64))
    }
    fn get(&self, seq: u64) -> bool {
        let (w, m) = self.slot(seq);
        self.bits[w] & m != 0
    }
    fn set(&mut self, seq: u64) {
        let (w, m) = self.slot(seq);
        self.bits[w] |= m;
    }
    /// Moves the newest number to `seq` (> newest), clearing the slots it passes.
    fn advance(&mut self, seq: u64) {
        if seq - self.newest >= self.span() {
            self.bits.iter_mut().for_each(|b| *b = 0);
        } else {
            for s in self.newest + 1..=seq {
                let (w, m) = self.slot(s);
                self.bits[w] &= !m;
            }
        }
        self.newest = seq;
        self.set(seq);
    }
}

/// The temporal layer.
pub struct TemporalLayer {
    config: TemporalConfig,
    /// Next sequence number per local sender (only local names: a fast unkeyed hash is safe;
    /// `peers` is keyed by names from the network and keeps the keyed default).
    next_seq: FxHashMap<String, u64>,
    peers: HashMap<String, SeqWindow>,
    stats: TemporalStats,
}

impl TemporalLayer {
    /// A layer with the given limits.
    pub fn new(config: TemporalConfig) -> TemporalLayer {
        TemporalLayer {
            config,
            next_seq: FxHashMap::default(),
            peers: HashMap::new(),
            stats: TemporalStats::default(),
        }
    }
    /// What it saw so far.
    pub fn stats(&self) -> TemporalStats {
        self.stats
    }

    fn check_time(&self, env: &Envelope, now: Time) -> Result<(), Reason> {
        let h = &env.header;
        let skew = self.config.max_skew;
        if h.timestamp > now.plus(skew) {
            return Err(Reason::FromFuture);
        }
        if now.since(h.timestamp) > self.config.max_age.saturating_add(skew) {
            return Err(Reason::Stale);
        }
        if h.reply_by != Time::ZERO && now > h.reply_by.plus(skew) {
            return Err(Reason::PastReplyBy);
        }
        Ok(())
    }

    fn check_seq(&mut self, sender: &str, seq: u64) -> Result<(), Reason> {
        let window = self.config.seq_window.max(1);
        let strict = self.config.ordering == Ordering::Strict;
        let Some(w) = self.peers.get_mut(sender) else {
            self.peers
                .insert(sender.to_string(), SeqWindow::new(seq, window));
            return Ok(());
        };
        if seq > w.newest {
            w.advance(seq);
            return Ok(());
        }
        // Behind the newest: checkable only within the ring.
        if w.newest - seq >= w.span().min(window) {
            return Err(Reason::OutOfOrder);
        }
        if w.get(seq) {
            return Err(Reason::ReplayedSequence);
        }
        if strict {
            self.stats.reordered += 1;
            return Err(Reason::OutOfOrder);
        }
        self.stats.reordered += 1;
        w.set(seq);
        Ok(())
    }
}

impl Layer for TemporalLayer {
    fn name(&self) -> &'static str {
        "temporal"
    }

    fn outbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        // Look the sender up by reference: its name is copied only the first time.
        env.header.seq = match self.next_seq.get_mut(&env.header.sender) {
            Some(next) => {
                let seq = *next;
                *next = seq.wrapping_add(1);
                seq
            }
            None => {
                let seq = now.as_ns();
                self.next_seq
                    .insert(env.header.sender.clone(), seq.wrapping_add(1));
                seq
            }
        };
        env.header.timestamp = now;
        Verdict::Pass
    }

    fn inbound(&mut self, env: &mut Envelope, now: Time) -> Verdict {
        if let Err(r) = self.check_time(env, now) {
            tracing::debug!(sender = %env.header.sender, ts = %env.header.timestamp, %now, reason = %r, "temporal drop");
            return Verdict::Drop(r);
        }
        match self.check_seq(&env.header.sender, env.header.seq) {
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
    use iw_bus::MsgId;

    fn ms(m: u64) -> Time {
        Time::from_ns(1_000_000_000_000).plus(Duration::from_millis(m))
    }

    fn stamped(tx: &mut TemporalLayer, at: Time) -> Envelope {
        let mut e = Envelope::new(MsgId(1), "a", "b", b"x".to_vec());
        match tx.outbound(&mut e, at) {
            Verdict::Pass => e,
            v => panic!("{v:?}"),
        }
    }

    #[test]
    fn stamps_and_accepts_fresh() {
        let mut tx = TemporalLayer::new(TemporalConfig::default());
        let mut e1 = stamped(&mut tx, ms(0));
        let e2 = stamped(&mut tx, ms(1));
        assert_eq!(e1.header.timestamp, ms(0));
        assert_eq!(e2.header.seq, e1.header.seq + 1);
        let mut rx = TemporalLayer::new(TemporalConfig::default());
        assert_eq!(rx.inbound(&mut e1, ms(5)), Verdict::Pass);
    }

    #[test]
    fn age_future_and_reply_by_with_skew() {
        let cfg = TemporalConfig {
            max_age: Duration::from_millis(100),
            max_skew: Duration::from_millis(10),
            ..Default::default()
        };
        let mut tx = TemporalLayer::new(cfg);
        let mut rx = TemporalLayer::new(cfg);
        let mut old = stamped(&mut tx, ms(0));
        assert_eq!(
            rx.inbound(&mut old.clone(), ms(111)),
            Verdict::Drop(Reason::Stale)
        );
        assert_eq!(
            rx.inbound(&mut old, ms(110)),
            Verdict::Pass,
            "within age + skew"
        );
        let mut future = stamped(&mut tx, ms(500));
        assert_eq!(
            rx.inbound(&mut future.clone(), ms(489)),
            Verdict::Drop(Reason::FromFuture)
        );
        assert_eq!(
            rx.inbound(&mut future, ms(490)),
            Verdict::Pass,
            "skew tolerated"
        );
        let mut due = stamped(&mut tx, ms(600));
        due.header.reply_by = ms(620);
        assert_eq!(
            rx.inbound(&mut due.clone(), ms(631)),
            Verdict::Drop(Reason::PastReplyBy)
        );
        assert_eq!(rx.inbound(&mut due, ms(630)), Verdict::Pass);
    }

    #[test]
    fn replayed_and_reordered_sequences() {
        let mut tx = TemporalLayer::new(TemporalConfig::default());
        let e: Vec<_> = (0..3).map(|_| stamped(&mut tx, ms(0))).collect();
        let mut rx = TemporalLayer::new(TemporalConfig::default());
        assert_eq!(rx.inbound(&mut e[0].clone(), ms(1)), Verdict::Pass);
        assert_eq!(rx.inbound(&mut e[2].clone(), ms(1)), Verdict::Pass);
        assert_eq!(rx.inbound(&mut e[1].clone(), ms(1)), Verdict::Pass);
        assert_eq!(rx.stats().reordered, 1);
        assert_eq!(
            rx.inbound(&mut e[1].clone(), ms(1)),
            Verdict::Drop(Reason::ReplayedSequence)
        );
        let mut strict = TemporalLayer::new(TemporalConfig {
            ordering: Ordering::Strict,
            ..Default::default()
        });
        assert_eq!(strict.inbound(&mut e[2].clone(), ms(1)), Verdict::Pass);
        assert_eq!(
            strict.inbound(&mut e[1].clone(), ms(1)),
            Verdict::Drop(Reason::OutOfOrder)
        );
    }

    #[test]
    fn restarted_sender_continues_above_old_numbers() {
        let mut rx = TemporalLayer::new(TemporalConfig::default());
        let mut first = TemporalLayer::new(TemporalConfig::default());
        for _ in 0..10 {
            assert_eq!(
                rx.inbound(&mut stamped(&mut first, ms(0)), ms(0)),
                Verdict::Pass
            );
        }
        let mut restarted = TemporalLayer::new(TemporalConfig::default());
        assert_eq!(
            rx.inbound(&mut stamped(&mut restarted, ms(1)), ms(1)),
            Verdict::Pass
        );
    }

    #[test]
    fn far_behind_is_rejected() {
        let cfg = TemporalConfig {
            seq_window: 4,
            ..Default::default()
        };
        let mut tx = TemporalLayer::new(cfg);
        let e: Vec<_> = (0..10).map(|_| stamped(&mut tx, ms(0))).collect();
        let mut rx = TemporalLayer::new(cfg);
        assert_eq!(rx.inbound(&mut e[9].clone(), ms(0)), Verdict::Pass);
        assert_eq!(
            rx.inbound(&mut e[0].clone(), ms(0)),
            Verdict::Drop(Reason::OutOfOrder)
        );
    }
}
