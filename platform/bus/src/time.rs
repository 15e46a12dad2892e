//! Time as nanoseconds since the UNIX epoch, and the [`Clock`] handle every layer reads.
//!
//! Logic never calls `Instant::now()`: it is handed a [`Clock`]. [`Clock::system`] reads the
//! wall clock (hosts compare timestamps, so it must be the epoch clock, not a monotonic one);
//! [`Clock::mock`] returns a clock plus a [`MockController`] that moves every clone of it, so
//! stale-message and retransmission logic is tested in simulated time.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// A point in time: nanoseconds since 1970-01-01T00:00:00Z. Arithmetic saturates (never wraps).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Default,
    serde::Serialize,
    serde::Deserialize,
)]
pub struct Time(pub u64);

impl Time {
    /// The epoch itself; used as "no time" on the wire where a field is optional.
    pub const ZERO: Time = Time(0);

    /// From nanoseconds since the epoch.
    pub const fn from_ns(ns: u64) -> Time {
        Time(ns)
    }
    /// Nanoseconds since the epoch.
    pub const fn as_ns(self) -> u64 {
        self.0
    }
    /// `self + d`, saturating at `u64::MAX` ns.
    pub fn plus(self, d: Duration) -> Time {
        Time(self.0.saturating_add(duration_ns(d)))
    }
    /// `self - d`, saturating at the epoch.
    pub fn minus(self, d: Duration) -> Time {
        Time(self.0.saturating_sub(duration_ns(d)))
    }
    /// How long after `earlier` this is; zero if `earlier` is later.
    pub fn since(self, earlier: Time) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl std::fmt::Display for Time {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}.{:09}s",
            self.0 / 1_000_000_000,
            self.0 % 1_000_000_000
        )
    }
}

/// A duration in whole nanoseconds, saturating at `u64::MAX` (584 years).
pub fn duration_ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// A cheap, cloneable time source: the system clock or a mock moved by a [`MockController`].
#[derive(Debug, Clone)]
pub struct Clock(Source);

#[derive(Debug, Clone)]
enum Source {
    System,
    Mock(Arc<AtomicU64>),
}

impl Clock {
    /// The host's wall clock (epoch-based, so timestamps compare across hosts up to clock skew).
    pub fn system() -> Clock {
        Clock(Source::System)
    }

    /// A mock clock starting at `start`, and the controller that moves it (and all its clones).
    pub fn mock(start: Time) -> (Clock, MockController) {
        let now = Arc::new(AtomicU64::new(start.0));
        (Clock(Source::Mock(now.clone())), MockController(now))
    }

    /// The current time.
    pub fn now(&self) -> Time {
        match &self.0 {
            Source::System => Time(
                SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map(duration_ns)
                    .unwrap_or(0),
            ),
            Source::Mock(now) => Time(now.load(Ordering::Acquire)),
        }
    }

    /// True for a mock clock (the bus then never sleeps waiting for time to pass).
    pub fn is_mock(&self) -> bool {
        matches!(self.0, Source::Mock(_))
    }
}

/// Moves a mock [`Clock`]: every clone sees the change at once.
#[derive(Debug, Clone)]
pub struct MockController(Arc<AtomicU64>);

impl MockController {
    /// Moves time forward by `d` (saturating).
    pub fn advance(&self, d: Duration) {
        let ns = duration_ns(d);
        // fetch_update never fails with a closure that always returns Some.
        let _ = self
            .0
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |t| {
                Some(t.saturating_add(ns))
            });
    }
    /// Sets the time (may move backwards, to test clock steps).
    pub fn set(&self, t: Time) {
        self.0.store(t.0, Ordering::Release);
    }
    /// The mock's current time.
    pub fn now(&self) -> Time {
        Time(self.0.load(Ordering::Acquire))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mock_moves_all_clones() {
        let (clock, ctl) = Clock::mock(Time::from_ns(5));
        let other = clock.clone();
        ctl.advance(Duration::from_millis(2));
        assert_eq!(clock.now(), Time::from_ns(2_000_005));
        assert_eq!(other.now(), clock.now());
        ctl.set(Time::ZERO);
        assert_eq!(other.now(), Time::ZERO);
    }

    #[test]
    fn arithmetic_saturates() {
        assert_eq!(
            Time(u64::MAX - 1).plus(Duration::from_secs(1)),
            Time(u64::MAX)
        );
        assert_eq!(Time(3).minus(Duration::from_secs(1)), Time::ZERO);
        assert_eq!(Time(3).since(Time(10)), Duration::ZERO);
    }

    #[test]
    fn system_clock_is_after_2020() {
        assert!(Clock::system().now() > Time::from_ns(1_577_836_800 * 1_000_000_000));
    }
}
