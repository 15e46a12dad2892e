//! [`WarnEvery`]: at most one warning per period per kind, so a flood of hostile or broken
//! input shows in the log without filling it (issue 20: one WARN per datagram is a denial of
//! service on the log).

use std::collections::HashMap;
use std::hash::Hash;
use std::time::Duration;

use crate::time::Time;

/// Admits one warning per `period` per key and counts the ones held back meanwhile. Keys are
/// few and fixed (a rejection reason, a channel), never names from the network.
#[derive(Debug, Clone)]
pub struct WarnEvery<K> {
    period: Duration,
    /// Per key: when a warning was last admitted, and how many were held back since.
    last: HashMap<K, (Time, u64)>,
}

impl<K: Eq + Hash> WarnEvery<K> {
    /// At most one warning per `period` per key.
    pub fn new(period: Duration) -> Self {
        Self {
            period,
            last: HashMap::new(),
        }
    }

    /// `Some(held_back)` when a warning about `key` may be logged at `now` (with how many were
    /// held back since the last one), `None` when it is to be held back.
    pub fn admit(&mut self, key: K, now: Time) -> Option<u64> {
        match self.last.get_mut(&key) {
            Some((at, held)) if now.since(*at) < self.period => {
                *held = held.saturating_add(1);
                None
            }
            Some((at, held)) => {
                *at = now;
                Some(std::mem::take(held))
            }
            None => {
                self.last.insert(key, (now, 0));
                Some(0)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_warning_per_period_per_key_with_the_count_held_back() {
        let mut w = WarnEvery::new(Duration::from_secs(10));
        let t = |s: u64| Time::from_ns(s * 1_000_000_000);
        assert_eq!(w.admit("a", t(1)), Some(0));
        assert_eq!(w.admit("b", t(1)), Some(0));
        for s in 1..11 {
            assert_eq!(w.admit("a", t(s)), None);
        }
        assert_eq!(w.admit("a", t(11)), Some(10));
        assert_eq!(w.admit("a", t(12)), None);
    }
}
