//! A seeded UDP impairment proxy: the network faults of EN 50159 on real loopback sockets.
//!
//! The kernel here has network namespaces but no `netem` qdisc, so faults are injected by a relay
//! of our own. Two endpoints `a` and `b` both send to the proxy's address; each datagram from `a`
//! goes on to `b` and each from `b` to `a`, after [`Impairer`] has decided its fate:
//!
//! | fault (EN 50159 threat)      | what happens to a datagram                                     |
//! |------------------------------|----------------------------------------------------------------|
//! | `drop` (deletion)            | not forwarded                                                  |
//! | `duplicate` (repetition)     | forwarded twice                                                |
//! | `reorder` (resequencing)     | held back and released right after the next one (same way)    |
//! | `corrupt` (corruption)       | 1 to 3 bytes XOR-ed with random non-zero bytes                 |
//! | `delay` (delay)              | forwarded after `delay_min..=delay_max` (whole ms)              |
//! | `inject_forged` (insertion)  | a datagram of random bytes, same length, is sent first         |
//! | `inject_replay` (repetition) | an earlier datagram of the same direction is sent again first  |
//!
//! Each fault is drawn independently per datagram from a ChaCha8 stream seeded by
//! [`ImpairConfig::seed`]: the same seed and the same input sequence give the same decisions.
//! Counters for every fault are in [`ImpairStats`].
//!
//! Usage (both endpoints bound first, so the proxy knows where to forward):
//! ```
//! use iw_transport_net::{ImpairConfig, ImpairProxy, UdpTransport};
//! use iw_bus::transport::FrameTransport;
//! let a = UdpTransport::bind("127.0.0.1:0")?;
//! let b = UdpTransport::bind("127.0.0.1:0")?;
//! // Corrupt every datagram; a real test sets e.g. `drop: 0.2, duplicate: 0.1, reorder: 0.1`.
//! let config = ImpairConfig { seed: 7, corrupt: 1.0, ..Default::default() };
//! let proxy = ImpairProxy::start(a.socket_addr()?, b.socket_addr()?, config)?;
//! a.send(&proxy.peer_addr(), b"to b, altered")?; // b sees it coming from proxy.peer_addr()
//! let (_from, frame) = b.recv_timeout(std::time::Duration::from_secs(5))?.ok_or("nothing relayed")?;
//! assert_ne!(frame, b"to b, altered");
//! let stats = proxy.stop();
//! assert_eq!(stats.received, 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Guarantees: loopback only (a non-loopback address is refused); the relay loop is bounded (at
//! most [`ImpairConfig::max_pending`] datagrams wait, the stop flag is checked at least every 5 ms);
//! [`ImpairProxy::stop`] (or drop) ends the relay thread and joins it.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};
use std::io::ErrorKind;
use std::net::{IpAddr, SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use iw_bus::transport::PeerAddr;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::NetError;
use crate::udp::UDP_MAX_PAYLOAD;

/// How many past datagrams per direction are kept as replay material.
const REPLAY_HISTORY: usize = 64;
/// Longest the relay blocks in one receive, so it notices `stop` promptly.
const POLL_PERIOD: Duration = Duration::from_millis(5);

/// Fault probabilities (each in `0..=1`, drawn per datagram) and their parameters.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImpairConfig {
    /// Seed of the fault stream.
    pub seed: u64,
    /// Probability a datagram is lost.
    pub drop: f64,
    /// Probability a datagram is forwarded twice.
    pub duplicate: f64,
    /// Probability a datagram is held back and overtaken by the next one.
    pub reorder: f64,
    /// Probability 1 to 3 bytes of a datagram are flipped.
    pub corrupt: f64,
    /// Probability a datagram is delayed by `delay_min..=delay_max`.
    pub delay: f64,
    /// Shortest added delay (whole milliseconds; key `delay_min_ms`).
    #[serde(rename = "delay_min_ms", with = "iw_bus::millis")]
    pub delay_min: Duration,
    /// Longest added delay (whole milliseconds; key `delay_max_ms`).
    #[serde(rename = "delay_max_ms", with = "iw_bus::millis")]
    pub delay_max: Duration,
    /// Probability a forged datagram (random bytes) is inserted before a datagram.
    pub inject_forged: f64,
    /// Probability an earlier datagram is replayed before a datagram.
    pub inject_replay: f64,
    /// Longest a reordered datagram waits for a successor before it is released anyway (key
    /// `reorder_hold_ms`).
    #[serde(rename = "reorder_hold_ms", with = "iw_bus::millis")]
    pub reorder_hold: Duration,
    /// Most datagrams waiting (delayed or held); beyond it new ones are dropped and counted.
    pub max_pending: usize,
}

impl Default for ImpairConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            drop: 0.0,
            duplicate: 0.0,
            reorder: 0.0,
            corrupt: 0.0,
            delay: 0.0,
            delay_min: Duration::from_millis(5),
            delay_max: Duration::from_millis(20),
            inject_forged: 0.0,
            inject_replay: 0.0,
            reorder_hold: Duration::from_millis(20),
            max_pending: 4096,
        }
    }
}

impl ImpairConfig {
    /// Checks every probability is in `0..=1` and the delay range is ordered.
    pub fn validate(&self) -> Result<(), NetError> {
        let probabilities = [
            ("drop", self.drop),
            ("duplicate", self.duplicate),
            ("reorder", self.reorder),
            ("corrupt", self.corrupt),
            ("delay", self.delay),
            ("inject_forged", self.inject_forged),
            ("inject_replay", self.inject_replay),
        ];
        for (name, value) in probabilities {
            if !(0.0..=1.0).contains(&value) {
                return Err(NetError::BadProbability { name, value });
            }
        }
        if self.delay_min > self.delay_max {
            return Err(NetError::BadDelayRange {
                min: self.delay_min,
                max: self.delay_max,
            });
        }
        Ok(())
    }
}

/// Counters of what the proxy did, one per fault and outcome.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ImpairStats {
    /// Datagrams received from `a` or `b`.
    pub received: u64,
    /// Datagrams sent on (duplicates, injections and released holds included).
    pub forwarded: u64,
    /// Datagrams lost on purpose.
    pub dropped: u64,
    /// Extra copies sent.
    pub duplicated: u64,
    /// Datagrams held back and overtaken.
    pub reordered: u64,
    /// Datagrams with flipped bytes.
    pub corrupted: u64,
    /// Datagrams delayed.
    pub delayed: u64,
    /// Forged datagrams inserted.
    pub forged: u64,
    /// Earlier datagrams replayed.
    pub replayed: u64,
    /// Datagrams from addresses other than `a` and `b`, ignored.
    pub strangers: u64,
    /// Datagrams dropped because `max_pending` were already waiting.
    pub overflowed: u64,
    /// Sends the operating system refused.
    pub send_errors: u64,
}

/// Which way a datagram travels through the proxy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// From endpoint `a` to endpoint `b`.
    AToB,
    /// From endpoint `b` to endpoint `a`.
    BToA,
}

impl Direction {
    fn index(self) -> usize {
        match self {
            Direction::AToB => 0,
            Direction::BToA => 1,
        }
    }
}

/// One datagram to send, after `delay`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Emit {
    /// Added delay (zero: now).
    pub delay: Duration,
    /// The bytes to send.
    pub bytes: Vec<u8>,
}

/// The pure fault decider: no sockets, no clock. Same seed and inputs, same outputs.
#[derive(Debug)]
pub struct Impairer {
    config: ImpairConfig,
    rng: ChaCha8Rng,
    history: [VecDeque<Vec<u8>>; 2],
    held: [Option<Vec<u8>>; 2],
    stats: ImpairStats,
}

impl Impairer {
    /// A decider for `config` (validated).
    pub fn new(config: ImpairConfig) -> Result<Self, NetError> {
        config.validate()?;
        Ok(Self {
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config,
            history: [VecDeque::new(), VecDeque::new()],
            held: [None, None],
            stats: ImpairStats::default(),
        })
    }

    /// What to send, in order, for one datagram travelling `dir`. Empty when it is dropped or held.
    pub fn decide(&mut self, dir: Direction, datagram: &[u8]) -> Vec<Emit> {
        self.stats.received += 1;
        let mut out = Vec::new();
        let side = dir.index();
        if self.rng.random_bool(self.config.inject_forged) {
            let mut forged = vec![0u8; datagram.len().max(1)];
            self.rng.fill(forged.as_mut_slice());
            self.stats.forged += 1;
            out.push(Emit {
                delay: Duration::ZERO,
                bytes: forged,
            });
        }
        if self.rng.random_bool(self.config.inject_replay) && !self.history[side].is_empty() {
            let pick = self.rng.random_range(0..self.history[side].len());
            if let Some(old) = self.history[side].get(pick) {
                self.stats.replayed += 1;
                out.push(Emit {
                    delay: Duration::ZERO,
                    bytes: old.clone(),
                });
            }
        }
        if self.history[side].len() == REPLAY_HISTORY {
            self.history[side].pop_front();
        }
        self.history[side].push_back(datagram.to_vec());

        if self.rng.random_bool(self.config.drop) {
            self.stats.dropped += 1;
            return self.counted(out);
        }
        let mut bytes = datagram.to_vec();
        if self.rng.random_bool(self.config.corrupt) && !bytes.is_empty() {
            let flips = self.rng.random_range(1..=3usize);
            for _ in 0..flips {
                let at = self.rng.random_range(0..bytes.len());
                let mask = self.rng.random_range(1..=255u8);
                if let Some(b) = bytes.get_mut(at) {
                    *b ^= mask;
                }
            }
            self.stats.corrupted += 1;
        }
        let delay = if self.rng.random_bool(self.config.delay) {
            self.stats.delayed += 1;
            // drawn in whole milliseconds, so a seed gives the same faults as it always did
            let ms = |d: Duration| u64::try_from(d.as_millis()).unwrap_or(u64::MAX);
            Duration::from_millis(
                self.rng
                    .random_range(ms(self.config.delay_min)..=ms(self.config.delay_max)),
            )
        } else {
            Duration::ZERO
        };
        let copies = if self.rng.random_bool(self.config.duplicate) {
            self.stats.duplicated += 1;
            2
        } else {
            1
        };
        if self.held[side].is_none() && self.rng.random_bool(self.config.reorder) {
            // Held; a duplicate copy, if any, still goes now so repetition and resequencing mix.
            self.held[side] = Some(bytes.clone());
            if copies == 2 {
                out.push(Emit { delay, bytes });
            }
            return self.counted(out);
        }
        for _ in 1..copies {
            out.push(Emit {
                delay,
                bytes: bytes.clone(),
            });
        }
        out.push(Emit { delay, bytes });
        if let Some(held) = self.held[side].take() {
            self.stats.reordered += 1;
            out.push(Emit { delay, bytes: held });
        }
        self.counted(out)
    }

    /// Whether a reordered datagram waits in direction `dir`.
    pub fn is_holding(&self, dir: Direction) -> bool {
        self.held[dir.index()].is_some()
    }

    /// Releases the datagram held in `dir` when no successor came in time (not counted as reordered).
    pub fn release_held(&mut self, dir: Direction) -> Option<Vec<u8>> {
        let held = self.held[dir.index()].take();
        if held.is_some() {
            self.stats.forwarded += 1;
        }
        held
    }

    /// The counters so far.
    pub fn stats(&self) -> ImpairStats {
        self.stats
    }

    fn counted(&mut self, out: Vec<Emit>) -> Vec<Emit> {
        self.stats.forwarded += out.len() as u64;
        out
    }
}

/// A running relay between two loopback endpoints, on its own thread.
#[derive(Debug)]
pub struct ImpairProxy {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<ImpairStats>>,
    thread: Option<JoinHandle<()>>,
}

impl ImpairProxy {
    /// Binds a proxy on `127.0.0.1` (free port) relaying between `a` and `b`.
    pub fn start(a: SocketAddr, b: SocketAddr, config: ImpairConfig) -> Result<Self, NetError> {
        Self::start_on(SocketAddr::from(([127, 0, 0, 1], 0)), a, b, config)
    }

    /// Binds a proxy on `listen` relaying between `a` and `b`; all three must be loopback.
    pub fn start_on(
        listen: SocketAddr,
        a: SocketAddr,
        b: SocketAddr,
        config: ImpairConfig,
    ) -> Result<Self, NetError> {
        for addr in [listen, a, b] {
            if !is_loopback(addr.ip()) {
                return Err(NetError::NotLoopback { addr });
            }
        }
        let mut impairer = Impairer::new(config)?;
        let socket = UdpSocket::bind(listen).map_err(|source| NetError::Io {
            context: format!("binding the proxy to {listen}"),
            source,
        })?;
        let addr = socket.local_addr().map_err(|source| NetError::Io {
            context: "reading the proxy address".into(),
            source,
        })?;
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(ImpairStats::default()));
        let thread = {
            let stop = Arc::clone(&stop);
            let stats = Arc::clone(&stats);
            std::thread::Builder::new()
                .name("iw-impair".into())
                .spawn(move || {
                    let mut relay = Relay {
                        socket,
                        a,
                        b,
                        pending: BinaryHeap::new(),
                        next_seq: 0,
                        held_since: [None, None],
                    };
                    if let Err(e) = relay.run(&mut impairer, &stop, &stats) {
                        tracing::error!(error = %e, "impairment proxy stopped");
                    }
                })
                .map_err(|source| NetError::Io {
                    context: "spawning the proxy thread".into(),
                    source,
                })?
        };
        Ok(Self {
            addr,
            stop,
            stats,
            thread: Some(thread),
        })
    }

    /// The proxy's socket address: `a` and `b` send here.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The proxy's address as a transport peer address.
    pub fn peer_addr(&self) -> PeerAddr {
        PeerAddr(self.addr.to_string())
    }

    /// The counters so far.
    pub fn stats(&self) -> ImpairStats {
        *self.stats.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Stops the relay (datagrams still waiting are discarded) and returns the final counters.
    pub fn stop(mut self) -> ImpairStats {
        self.shutdown();
        self.stats()
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take()
            && thread.join().is_err()
        {
            tracing::error!("impairment proxy thread panicked");
        }
    }
}

impl Drop for ImpairProxy {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn is_loopback(ip: IpAddr) -> bool {
    ip.is_loopback()
}

/// A datagram waiting: (due, sequence for stable order, destination, bytes).
type Pending = (Instant, u64, SocketAddr, Vec<u8>);

/// The socket side of the proxy: a queue of datagrams due at instants.
struct Relay {
    socket: UdpSocket,
    a: SocketAddr,
    b: SocketAddr,
    /// (due, sequence for stable order, destination, bytes), earliest first.
    pending: BinaryHeap<Reverse<Pending>>,
    next_seq: u64,
    held_since: [Option<Instant>; 2],
}

impl Relay {
    fn run(
        &mut self,
        impairer: &mut Impairer,
        stop: &AtomicBool,
        stats: &Mutex<ImpairStats>,
    ) -> Result<(), NetError> {
        let mut buf = vec![0u8; UDP_MAX_PAYLOAD + 1];
        let hold = impairer.config.reorder_hold;
        let max_pending = impairer.config.max_pending;
        let mut strangers = 0u64;
        let mut overflowed = 0u64;
        let mut send_errors = 0u64;
        let mut current_timeout = None;
        while !stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            send_errors += self.send_due(now);
            for dir in [Direction::AToB, Direction::BToA] {
                let since = self.held_since[dir.index()];
                if !impairer.is_holding(dir) {
                    self.held_since[dir.index()] = None;
                } else if since.is_some_and(|t| now.duration_since(t) >= hold)
                    && let Some(bytes) = impairer.release_held(dir)
                {
                    self.held_since[dir.index()] = None;
                    let to = self.destination(dir);
                    send_errors += u64::from(self.socket.send_to(&bytes, to).is_err());
                }
            }
            self.publish(impairer, stats, strangers, overflowed, send_errors);
            let mut timeout = POLL_PERIOD;
            if let Some(Reverse((due, ..))) = self.pending.peek() {
                timeout = timeout.min(due.saturating_duration_since(now));
            }
            let timeout = timeout.max(Duration::from_micros(50));
            if current_timeout != Some(timeout) {
                self.socket
                    .set_read_timeout(Some(timeout))
                    .map_err(|source| NetError::Io {
                        context: "setting the proxy read timeout".into(),
                        source,
                    })?;
                current_timeout = Some(timeout);
            }
            let (len, from) = match self.socket.recv_from(&mut buf) {
                Ok(got) => got,
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock
                            | ErrorKind::TimedOut
                            | ErrorKind::Interrupted
                            | ErrorKind::ConnectionRefused
                    ) =>
                {
                    continue;
                }
                Err(source) => {
                    return Err(NetError::Io {
                        context: "proxy receive".into(),
                        source,
                    });
                }
            };
            let dir = if from == self.a {
                Direction::AToB
            } else if from == self.b {
                Direction::BToA
            } else {
                strangers += 1;
                self.publish(impairer, stats, strangers, overflowed, send_errors);
                continue;
            };
            let datagram = buf.get(..len).unwrap_or_default();
            let emits = impairer.decide(dir, datagram);
            if impairer.is_holding(dir) && self.held_since[dir.index()].is_none() {
                self.held_since[dir.index()] = Some(Instant::now());
            }
            let to = self.destination(dir);
            for emit in emits {
                if emit.delay.is_zero() {
                    send_errors += u64::from(self.socket.send_to(&emit.bytes, to).is_err());
                } else if self.pending.len() >= max_pending {
                    overflowed += 1;
                } else {
                    let due = Instant::now() + emit.delay;
                    self.pending
                        .push(Reverse((due, self.next_seq, to, emit.bytes)));
                    self.next_seq += 1;
                }
            }
            send_errors += self.send_due(Instant::now());
            self.publish(impairer, stats, strangers, overflowed, send_errors);
        }
        Ok(())
    }

    fn destination(&self, dir: Direction) -> SocketAddr {
        match dir {
            Direction::AToB => self.b,
            Direction::BToA => self.a,
        }
    }

    /// Sends every datagram due by `now`; returns how many sends failed.
    fn send_due(&mut self, now: Instant) -> u64 {
        let mut failed = 0;
        while self
            .pending
            .peek()
            .is_some_and(|Reverse((due, ..))| *due <= now)
        {
            if let Some(Reverse((_, _, to, bytes))) = self.pending.pop() {
                failed += u64::from(self.socket.send_to(&bytes, to).is_err());
            }
        }
        failed
    }

    fn publish(
        &self,
        impairer: &Impairer,
        stats: &Mutex<ImpairStats>,
        strangers: u64,
        overflowed: u64,
        send_errors: u64,
    ) {
        let mut s = impairer.stats();
        s.strangers = strangers;
        s.overflowed = overflowed;
        s.send_errors = send_errors;
        *stats.lock().unwrap_or_else(PoisonError::into_inner) = s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(config: ImpairConfig, n: usize) -> (Vec<Vec<Emit>>, ImpairStats) {
        let mut imp = Impairer::new(config).unwrap();
        let out = (0..n)
            .map(|i| imp.decide(Direction::AToB, &(i as u32).to_le_bytes()))
            .collect();
        (out, imp.stats())
    }

    #[test]
    fn same_seed_same_decisions_and_other_seed_differs() {
        let config = ImpairConfig {
            seed: 3,
            drop: 0.3,
            duplicate: 0.2,
            reorder: 0.2,
            corrupt: 0.1,
            delay: 0.1,
            inject_forged: 0.05,
            inject_replay: 0.05,
            ..Default::default()
        };
        let (first, s1) = run(config.clone(), 500);
        let (second, s2) = run(config.clone(), 500);
        assert_eq!(first, second);
        assert_eq!(s1, s2);
        let (third, _) = run(ImpairConfig { seed: 4, ..config }, 500);
        assert_ne!(first, third);
    }

    #[test]
    fn no_faults_forwards_everything_in_order() {
        let (out, stats) = run(ImpairConfig::default(), 100);
        for (i, emits) in out.iter().enumerate() {
            assert_eq!(
                emits,
                &vec![Emit {
                    delay: Duration::ZERO,
                    bytes: (i as u32).to_le_bytes().to_vec()
                }]
            );
        }
        assert_eq!(stats.forwarded, 100);
        assert_eq!(stats.dropped + stats.duplicated + stats.corrupted, 0);
    }

    #[test]
    fn drop_rate_is_near_the_probability() {
        let (_, stats) = run(
            ImpairConfig {
                seed: 1,
                drop: 0.2,
                ..Default::default()
            },
            10_000,
        );
        assert!(
            (1_700..2_300).contains(&stats.dropped),
            "dropped {}",
            stats.dropped
        );
        assert_eq!(stats.forwarded, 10_000 - stats.dropped);
    }

    #[test]
    fn reorder_releases_the_held_datagram_after_its_successor() {
        let mut imp = Impairer::new(ImpairConfig {
            reorder: 1.0,
            ..Default::default()
        })
        .unwrap();
        assert!(imp.decide(Direction::AToB, b"first").is_empty());
        assert!(imp.is_holding(Direction::AToB));
        let out: Vec<_> = imp
            .decide(Direction::AToB, b"second")
            .into_iter()
            .map(|e| e.bytes)
            .collect();
        assert_eq!(out, vec![b"second".to_vec(), b"first".to_vec()]);
        assert_eq!(imp.stats().reordered, 1);
    }

    #[test]
    fn corruption_changes_bytes_but_not_length() {
        let mut imp = Impairer::new(ImpairConfig {
            corrupt: 1.0,
            ..Default::default()
        })
        .unwrap();
        let data = [0u8; 32];
        for _ in 0..50 {
            let out = imp.decide(Direction::BToA, &data);
            assert_eq!(out.len(), 1);
            assert_eq!(out[0].bytes.len(), 32);
            assert_ne!(out[0].bytes, data);
        }
    }

    #[test]
    fn replay_sends_an_earlier_datagram_of_the_same_direction() {
        let mut imp = Impairer::new(ImpairConfig {
            inject_replay: 1.0,
            ..Default::default()
        })
        .unwrap();
        imp.decide(Direction::AToB, b"old");
        imp.decide(Direction::BToA, b"other way");
        let out: Vec<_> = imp
            .decide(Direction::AToB, b"new")
            .into_iter()
            .map(|e| e.bytes)
            .collect();
        assert_eq!(out, vec![b"old".to_vec(), b"new".to_vec()]);
    }

    /// The configuration holds durations; its JSON keeps the `*_ms` integer keys.
    #[test]
    fn delays_are_durations_under_their_millisecond_keys() {
        let config: ImpairConfig = serde_json::from_str(
            r#"{"delay_min_ms": 7, "delay_max_ms": 9, "reorder_hold_ms": 11}"#,
        )
        .unwrap();
        let ms = Duration::from_millis;
        assert_eq!(
            (config.delay_min, config.delay_max, config.reorder_hold),
            (ms(7), ms(9), ms(11))
        );
        let written = serde_json::to_value(&config).unwrap();
        assert_eq!(written["delay_min_ms"], 7);
        assert_eq!(written["reorder_hold_ms"], 11);
        let err = serde_json::from_str::<ImpairConfig>(r#"{"delay_max_ms": -1}"#).unwrap_err();
        assert!(err.to_string().contains("invalid value"), "{err}");
    }

    #[test]
    fn bad_configs_are_refused_with_the_offending_value() {
        let err = Impairer::new(ImpairConfig {
            drop: 1.5,
            ..Default::default()
        })
        .unwrap_err();
        assert!(matches!(err, NetError::BadProbability { name: "drop", value } if value == 1.5));
        let err = Impairer::new(ImpairConfig {
            delay_min: Duration::from_millis(9),
            delay_max: Duration::from_millis(3),
            ..Default::default()
        })
        .unwrap_err();
        assert!(matches!(
            err,
            NetError::BadDelayRange { min, max }
                if min == Duration::from_millis(9) && max == Duration::from_millis(3)
        ));
        let lan: SocketAddr = "192.0.2.1:9".parse().unwrap();
        let lo: SocketAddr = "127.0.0.1:9".parse().unwrap();
        assert!(matches!(
            ImpairProxy::start(lan, lo, ImpairConfig::default()),
            Err(NetError::NotLoopback { .. })
        ));
    }
}
