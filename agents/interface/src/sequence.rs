//! User-defined input sequences (thesis 3.3.4): a sequence of symbols from one device
//! (homogeneous) or several (mixed) is bound to an action only after the user repeated it
//! reliably, and is then recognised in the stream of input events.

use std::collections::VecDeque;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::InterfaceError;
use crate::input::{Device, InputEvent};

/// One element of a sequence: a symbol of one device.
pub type Step = (Device, String);

/// A user-defined input sequence.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct InputSequence(pub Vec<Step>);

impl InputSequence {
    /// Whether the sequence mixes devices.
    pub fn is_mixed(&self) -> bool {
        self.0.windows(2).any(|w| w[0].0 != w[1].0)
    }

    fn matches(&self, events: &[InputEvent]) -> bool {
        self.0.len() == events.len()
            && self
                .0
                .iter()
                .zip(events)
                .all(|((d, s), e)| *d == e.device && *s == e.symbol)
    }

    /// Whether `self` appears as a contiguous run inside `other` (then one would fire while the
    /// user enters the other).
    fn occurs_in(&self, other: &InputSequence) -> bool {
        self.0.len() <= other.0.len()
            && other
                .0
                .windows(self.0.len())
                .any(|w| w == self.0.as_slice())
    }
}

/// Longest pause between two events of one sequence by default.
pub const DEFAULT_MAX_GAP: Duration = Duration::from_millis(1500);

/// Whether `later` follows `earlier` (event times, ms) by at most `max_gap`.
fn follows(earlier: u64, later: u64, max_gap: Duration) -> bool {
    later >= earlier && Duration::from_millis(later - earlier) <= max_gap
}

/// Whether no two neighbours of `events` are more than `max_gap` apart.
fn within_gap(events: &[InputEvent], max_gap: Duration) -> bool {
    events
        .windows(2)
        .all(|w| follows(w[0].t_ms, w[1].t_ms, max_gap))
}

/// Where a reliability test stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Verdict {
    /// More attempts are needed.
    Pending,
    /// Recognised in at least the required number of attempts.
    Accepted,
    /// Too many attempts failed for the required number to be reachable.
    Rejected,
}

/// The reliability test: the user enters the sequence `repetitions` times; it is accepted when
/// at least `required` attempts are recognised exactly (same symbols, same devices, no pause
/// longer than the gap).
#[derive(Debug, Clone)]
pub struct ReliabilityTest {
    sequence: InputSequence,
    repetitions: u32,
    required: u32,
    max_gap: Duration,
    successes: u32,
    attempts: u32,
}

impl ReliabilityTest {
    /// A test of `sequence`; `required` of `repetitions` attempts must succeed.
    pub fn new(
        sequence: InputSequence,
        repetitions: u32,
        required: u32,
        max_gap: Duration,
    ) -> Result<Self, InterfaceError> {
        if sequence.0.is_empty() || required == 0 || required > repetitions {
            return Err(InterfaceError::BadTest {
                length: sequence.0.len(),
                repetitions,
                required,
            });
        }
        Ok(ReliabilityTest {
            sequence,
            repetitions,
            required,
            max_gap,
            successes: 0,
            attempts: 0,
        })
    }

    /// Records one attempt; returns whether it was recognised. Attempts after the verdict are
    /// ignored (and return false).
    pub fn attempt(&mut self, events: &[InputEvent]) -> bool {
        if self.verdict() != Verdict::Pending {
            return false;
        }
        self.attempts += 1;
        let ok = self.sequence.matches(events) && within_gap(events, self.max_gap);
        self.successes += u32::from(ok);
        ok
    }

    /// The verdict so far.
    pub fn verdict(&self) -> Verdict {
        if self.successes >= self.required {
            Verdict::Accepted
        } else if self.successes + (self.repetitions - self.attempts) < self.required {
            Verdict::Rejected
        } else {
            Verdict::Pending
        }
    }

    /// Recognised attempts / attempts so far.
    pub fn recognition_rate(&self) -> f64 {
        if self.attempts == 0 {
            0.0
        } else {
            f64::from(self.successes) / f64::from(self.attempts)
        }
    }
}

/// Recognises bound sequences in a stream of events.
#[derive(Debug, Clone)]
pub struct Recognizer<A> {
    bindings: Vec<(InputSequence, A)>,
    buffer: VecDeque<InputEvent>,
    max_gap: Duration,
}

impl<A: Clone> Recognizer<A> {
    /// An empty recognizer; a pause longer than `max_gap` starts a new sequence.
    pub fn new(max_gap: Duration) -> Self {
        Recognizer {
            bindings: Vec::new(),
            buffer: VecDeque::new(),
            max_gap,
        }
    }

    /// Binds the sequence of an accepted `test` to `action`. Refused when the test is not
    /// accepted, or when the sequence occurs inside a bound one (or one inside it): one of the
    /// two would fire while the user enters the other.
    pub fn bind(&mut self, test: &ReliabilityTest, action: A) -> Result<(), InterfaceError> {
        if test.verdict() != Verdict::Accepted {
            return Err(InterfaceError::NotReliable {
                rate: test.recognition_rate(),
            });
        }
        let sequence = &test.sequence;
        if let Some((other, _)) = self
            .bindings
            .iter()
            .find(|(s, _)| s.occurs_in(sequence) || sequence.occurs_in(s))
        {
            return Err(InterfaceError::Ambiguous {
                sequence: format!("{:?}", sequence.0),
                other: format!("{:?}", other.0),
            });
        }
        self.bindings.push((sequence.clone(), action));
        Ok(())
    }

    /// Feeds one event; returns the action whose sequence it completes.
    pub fn feed(&mut self, event: InputEvent) -> Option<A> {
        if let Some(last) = self.buffer.back()
            && !follows(last.t_ms, event.t_ms, self.max_gap)
        {
            self.buffer.clear();
        }
        self.buffer.push_back(event);
        let longest = self
            .bindings
            .iter()
            .map(|(s, _)| s.0.len())
            .max()
            .unwrap_or(0);
        while self.buffer.len() > longest {
            self.buffer.pop_front();
        }
        let events = self.buffer.make_contiguous();
        let found = self
            .bindings
            .iter()
            .find(|(s, _)| {
                s.0.len() <= events.len() && s.matches(&events[events.len() - s.0.len()..])
            })
            .map(|(_, a)| a.clone());
        if found.is_some() {
            self.buffer.clear();
        }
        found
    }

    /// Steps of the longest bound sequence the recent events have started, with its length
    /// (for the on-chair display).
    pub fn progress(&self) -> Option<(usize, usize)> {
        let events: Vec<&InputEvent> = self.buffer.iter().collect();
        (1..=events.len()).rev().find_map(|n| {
            let tail = &events[events.len() - n..];
            self.bindings.iter().find_map(|(s, _)| {
                let prefix =
                    s.0.iter()
                        .zip(tail)
                        .all(|((d, sym), e)| *d == e.device && *sym == e.symbol);
                (s.0.len() > n && prefix).then_some((n, s.0.len()))
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ev(device: Device, symbol: &str, t_ms: u64) -> InputEvent {
        InputEvent {
            device,
            symbol: symbol.into(),
            t_ms,
        }
    }

    fn accepted(seq: &InputSequence) -> ReliabilityTest {
        let mut test = ReliabilityTest::new(seq.clone(), 3, 3, DEFAULT_MAX_GAP).unwrap();
        for _ in 0..3 {
            let events: Vec<_> = seq
                .0
                .iter()
                .enumerate()
                .map(|(i, (d, s))| ev(*d, s, i as u64 * 100))
                .collect();
            assert!(test.attempt(&events));
        }
        test
    }

    #[test]
    fn unreliable_and_ambiguous_sequences_are_refused() {
        let seq = InputSequence(vec![
            (Device::Gamepad, "a".into()),
            (Device::Voice, "go".into()),
        ]);
        assert!(seq.is_mixed());
        let mut test =
            ReliabilityTest::new(seq.clone(), 3, 2, Duration::from_millis(1000)).unwrap();
        assert!(!test.attempt(&[ev(Device::Gamepad, "a", 0), ev(Device::Voice, "stop", 10)]));
        assert!(!test.attempt(&[ev(Device::Gamepad, "a", 0), ev(Device::Voice, "go", 5000)]));
        assert_eq!(test.verdict(), Verdict::Rejected);
        let mut r = Recognizer::new(Duration::from_millis(1000));
        assert!(matches!(
            r.bind(&test, 1),
            Err(InterfaceError::NotReliable { .. })
        ));
        r.bind(&accepted(&seq), 1).unwrap();
        let inner = InputSequence(vec![(Device::Voice, "go".into())]);
        assert!(matches!(
            r.bind(&accepted(&inner), 2),
            Err(InterfaceError::Ambiguous { .. })
        ));
    }

    fn step() -> impl Strategy<Value = Step> {
        (
            prop_oneof![
                Just(Device::Gamepad),
                Just(Device::Voice),
                Just(Device::Face)
            ],
            prop_oneof![Just("a"), Just("b"), Just("c")],
        )
            .prop_map(|(d, s)| (d, s.to_string()))
    }

    proptest! {
        /// A bound sequence entered without long pauses fires its action exactly at its last step.
        #[test]
        fn bound_sequence_fires_at_its_end(steps in prop::collection::vec(step(), 1..6), gaps in prop::collection::vec(0u64..1000, 6)) {
            let seq = InputSequence(steps);
            let mut r = Recognizer::new(Duration::from_millis(1000));
            r.bind(&accepted(&seq), 7u8).unwrap();
            let mut t = 0;
            for (i, (d, s)) in seq.0.iter().enumerate() {
                t += gaps[i];
                let fired = r.feed(ev(*d, s, t));
                prop_assert_eq!(fired, (i + 1 == seq.0.len()).then_some(7u8));
            }
        }

        /// A pause longer than the gap in the middle of a sequence prevents it from firing.
        #[test]
        fn long_pause_breaks_a_sequence(steps in prop::collection::vec(step(), 2..6), cut in 1usize..5) {
            let seq = InputSequence(steps);
            let cut = cut.min(seq.0.len() - 1);
            let mut r = Recognizer::new(Duration::from_millis(1000));
            r.bind(&accepted(&seq), 1u8).unwrap();
            let mut fired = None;
            for (i, (d, s)) in seq.0.iter().enumerate() {
                let t = i as u64 * 10 + if i >= cut { 5000 } else { 0 };
                fired = fired.or(r.feed(ev(*d, s, t)));
            }
            prop_assert_eq!(fired, None);
        }

        /// Any stream of events never panics, and whatever fires is bound.
        #[test]
        fn arbitrary_streams_fire_only_bound_actions(stream in prop::collection::vec((step(), 0u64..3000), 0..60)) {
            let mut r = Recognizer::new(Duration::from_millis(1000));
            let a = InputSequence(vec![(Device::Gamepad, "a".into()), (Device::Voice, "b".into())]);
            r.bind(&accepted(&a), 1u8).unwrap();
            let mut t = 0;
            for ((d, s), dt) in stream {
                t += dt;
                if let Some(x) = r.feed(ev(d, &s, t)) { prop_assert_eq!(x, 1); }
                if let Some((n, len)) = r.progress() { prop_assert!(n < len); }
            }
        }
    }
}
