//! A seeded fault-injecting [`FrameTransport`] wrapper for the EN 50159 unit-level tests: on
//! send it drops, duplicates, reorders, corrupts, replays and injects frames by probability.

use std::sync::{Mutex, PoisonError};
use std::time::Duration;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::transport::{FrameTransport, PeerAddr, TransportError};

/// Probabilities (0 to 1) of each fault, applied independently to every frame sent.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Impairments {
    /// The frame is lost (deletion).
    pub drop: f64,
    /// The frame is sent twice (repetition).
    pub duplicate: f64,
    /// The frame is held back and sent after the next one (resequencing).
    pub reorder: f64,
    /// One random bit of the frame is flipped (corruption).
    pub corrupt: f64,
    /// A frame sent earlier is sent again as well (replay).
    pub replay: f64,
    /// A random-byte frame is sent as well (insertion).
    pub inject: f64,
}

/// How many of each fault were injected.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FaultStats {
    /// Frames offered to `send`.
    pub offered: u64,
    /// Frames dropped.
    pub dropped: u64,
    /// Extra copies sent.
    pub duplicated: u64,
    /// Frames held back.
    pub reordered: u64,
    /// Frames with a flipped bit.
    pub corrupted: u64,
    /// Old frames sent again.
    pub replayed: u64,
    /// Random frames sent.
    pub injected: u64,
}

struct State {
    rng: ChaCha8Rng,
    held: Option<(PeerAddr, Vec<u8>)>,
    history: Vec<Vec<u8>>,
    stats: FaultStats,
}

/// Wraps a transport and impairs what it sends; receiving is untouched.
pub struct FaultyTransport<T> {
    inner: T,
    faults: Impairments,
    state: Mutex<State>,
}

impl<T: FrameTransport> FaultyTransport<T> {
    /// Frames kept for replay.
    const HISTORY: usize = 64;

    /// Wraps `inner`; the same `seed` gives the same faults for the same sends.
    pub fn new(inner: T, faults: Impairments, seed: u64) -> FaultyTransport<T> {
        let state = State {
            rng: ChaCha8Rng::seed_from_u64(seed),
            held: None,
            history: Vec::new(),
            stats: FaultStats::default(),
        };
        FaultyTransport {
            inner,
            faults,
            state: Mutex::new(state),
        }
    }
    /// Faults injected so far.
    pub fn stats(&self) -> FaultStats {
        self.state
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .stats
    }
    /// Sends the frame held back for reordering, if any.
    pub fn flush(&self) -> Result<(), TransportError> {
        let held = self
            .state
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .held
            .take();
        match held {
            Some((to, frame)) => self.inner.send(&to, &frame),
            None => Ok(()),
        }
    }
    /// The wrapped transport.
    pub fn inner(&self) -> &T {
        &self.inner
    }
}

impl<T: FrameTransport> FrameTransport for FaultyTransport<T> {
    fn local_addr(&self) -> &PeerAddr {
        self.inner.local_addr()
    }
    fn max_frame_len(&self) -> usize {
        self.inner.max_frame_len()
    }
    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError> {
        let mut out: Vec<(PeerAddr, Vec<u8>)> = Vec::new();
        {
            let mut guard = self.state.lock().unwrap_or_else(PoisonError::into_inner);
            let st = &mut *guard;
            let f = self.faults;
            st.stats.offered += 1;
            if st.history.len() == Self::HISTORY {
                st.history.remove(0);
            }
            st.history.push(frame.to_vec());
            if st.rng.random_bool(f.replay.clamp(0.0, 1.0)) {
                let n = st.history.len();
                let i = st.rng.random_range(0..n);
                let old = st.history[i].clone();
                st.stats.replayed += 1;
                out.push((to.clone(), old));
            }
            if st.rng.random_bool(f.inject.clamp(0.0, 1.0)) {
                let len = st.rng.random_range(1..=frame.len().max(1));
                let rng = &mut st.rng;
                let junk: Vec<u8> = (0..len).map(|_| rng.random()).collect();
                st.stats.injected += 1;
                out.push((to.clone(), junk));
            }
            if st.rng.random_bool(f.drop.clamp(0.0, 1.0)) {
                st.stats.dropped += 1;
            } else {
                let mut frame = frame.to_vec();
                if !frame.is_empty() && st.rng.random_bool(f.corrupt.clamp(0.0, 1.0)) {
                    let bits = frame.len() * 8;
                    let bit = st.rng.random_range(0..bits);
                    frame[bit / 8] ^= 1 << (bit % 8);
                    st.stats.corrupted += 1;
                }
                if st.held.is_none() && st.rng.random_bool(f.reorder.clamp(0.0, 1.0)) {
                    st.stats.reordered += 1;
                    st.held = Some((to.clone(), frame));
                } else {
                    out.push((to.clone(), frame.clone()));
                    if st.rng.random_bool(f.duplicate.clamp(0.0, 1.0)) {
                        st.stats.duplicated += 1;
                        out.push((to.clone(), frame));
                    }
                    if let Some(held) = st.held.take() {
                        out.push(held);
                    }
                }
            }
        }
        for (to, frame) in out {
            self.inner.send(&to, &frame)?;
        }
        Ok(())
    }
    fn recv_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError> {
        self.inner.recv_timeout(timeout)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inproc::InProcNetwork;

    fn run(faults: Impairments, seed: u64) -> (FaultStats, Vec<Vec<u8>>) {
        let net = InProcNetwork::new();
        let a = FaultyTransport::new(net.endpoint("a").unwrap(), faults, seed);
        let b = net.endpoint("b").unwrap();
        for i in 0..200u8 {
            a.send(b.local_addr(), &[i, i, i]).unwrap();
        }
        a.flush().unwrap();
        let mut got = Vec::new();
        while let Some((_, f)) = b.recv_timeout(Duration::ZERO).unwrap() {
            got.push(f);
        }
        (a.stats(), got)
    }

    #[test]
    fn seeded_and_every_fault_occurs() {
        let f = Impairments {
            drop: 0.2,
            duplicate: 0.1,
            reorder: 0.1,
            corrupt: 0.1,
            replay: 0.05,
            inject: 0.05,
        };
        let (s1, g1) = run(f, 3);
        let (s2, g2) = run(f, 3);
        assert_eq!((s1, &g1), (s2, &g2));
        assert!(s1.dropped > 0 && s1.duplicated > 0 && s1.reordered > 0);
        assert!(s1.corrupted > 0 && s1.replayed > 0 && s1.injected > 0);
        let expected = 200 - s1.dropped + s1.duplicated + s1.replayed + s1.injected;
        assert_eq!(g1.len() as u64, expected);
    }

    #[test]
    fn no_faults_is_transparent() {
        let (s, g) = run(Impairments::default(), 1);
        assert_eq!(s.offered, 200);
        assert_eq!(g, (0..200u8).map(|i| vec![i, i, i]).collect::<Vec<_>>());
    }
}
