//! [`ContainerNode`]: a [`Container`] driven over a real frame transport on its own thread.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use iw_bus::transport::FrameTransport;
use iw_bus::transport::PeerAddr;
use iw_bus::{Clock, WarnEvery};
use iw_layer_security::Identity;

use crate::machine::{Container, Outgoing};
use crate::{ContainerError, ControlChannel};

/// Most frames taken in one go before the container ticks (a flood cannot starve its own
/// heartbeats).
const MAX_BATCH: usize = 256;

/// A running container: receives control frames, ticks its state machine, sends what it says.
///
/// Transport errors (a lost network) are logged and retried, never fatal: the container and its
/// local agents carry on alone until peers are heard again.
#[derive(Debug)]
pub struct ContainerNode {
    state: Arc<Mutex<Container>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl ContainerNode {
    /// Runs `container` over `transport` (its own endpoint, not an agent bus), timed by `clock`,
    /// speaking in control sessions as `identity` (the container's own, whose key its agents'
    /// entries carry); the container's [`crate::ContainerConfig::key`] is set to that
    /// identity's key.
    /// Refused ([`ContainerError::Roster`]) when the container's roster pins another key for
    /// its id, or does not list it.
    pub fn start(
        mut container: Container,
        identity: Arc<Identity>,
        transport: Arc<dyn FrameTransport>,
        clock: Clock,
        tick: Duration,
    ) -> Result<Self, ContainerError> {
        container.set_key(identity.public_key());
        if let Some(roster) = container.roster() {
            roster.check_own(container.id(), None, &identity.public_key())?;
        }
        let channel = ControlChannel::new(Arc::clone(&identity))?;
        let state = Arc::new(Mutex::new(container));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (state, stop) = (Arc::clone(&state), Arc::clone(&stop));
            std::thread::Builder::new()
                .name("iw-container".into())
                .spawn(move || run(&state, channel, transport.as_ref(), &clock, tick, &stop))
                .map_err(|source| ContainerError::Spawn { source })?
        };
        Ok(Self {
            state,
            stop,
            thread: Some(thread),
        })
    }

    /// Runs `f` on the container (register agents, resolve, read the lists).
    pub fn with<R>(&self, f: impl FnOnce(&mut Container) -> R) -> R {
        f(&mut self.state.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// Stops the thread (peers see the lease expire) and waits for it.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take()
            && thread.join().is_err()
        {
            tracing::error!("container thread panicked");
        }
    }
}

impl Drop for ContainerNode {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn run(
    state: &Mutex<Container>,
    channel: ControlChannel,
    transport: &dyn FrameTransport,
    clock: &Clock,
    tick: Duration,
    stop: &AtomicBool,
) {
    let mut driver = Driver::new(state, channel, transport, clock, tick);
    while !stop.load(Ordering::Relaxed) {
        driver.round();
    }
}

/// What the container thread keeps between its rounds.
struct Driver<'a> {
    state: &'a Mutex<Container>,
    channel: ControlChannel,
    transport: &'a dyn FrameTransport,
    clock: &'a Clock,
    tick: Duration,
    /// Refused datagrams (garbage, a session this end lost) are one WARN per period, not one
    /// per datagram.
    warn: WarnEvery<()>,
}

impl<'a> Driver<'a> {
    fn new(
        state: &'a Mutex<Container>,
        channel: ControlChannel,
        transport: &'a dyn FrameTransport,
        clock: &'a Clock,
        tick: Duration,
    ) -> Self {
        Driver {
            state,
            channel,
            transport,
            clock,
            tick,
            warn: WarnEvery::new(iw_bus::WARN_PERIOD),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'a, Container> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn send(&self, to: &PeerAddr, datagrams: Vec<Vec<u8>>) {
        for d in datagrams {
            if let Err(e) = self.transport.send(to, &d) {
                tracing::debug!(%to, error = %e, "control datagram not sent");
            }
        }
    }

    /// One round: waits up to a tick for a frame, takes what is queued, ticks, sends.
    fn round(&mut self) {
        let (transport, clock, tick) = (self.transport, self.clock, self.tick);
        // Everything already queued is taken before the leases are judged: a process that was
        // not scheduled for a lease must not expire peers whose heartbeats wait in its socket.
        let mut out = Vec::new();
        // No sooner than something is due (a heartbeat, a lease): an idle container wakes a
        // few times a second, not every tick; `tick` bounds the wait for changes made through
        // `with` meanwhile
        let mut wait = self.lock().next_due().since(clock.now()).min(tick);
        for _ in 0..MAX_BATCH {
            match transport.recv_timeout(wait) {
                Ok(Some((from, datagram))) => {
                    let now = clock.now();
                    let mut back = Vec::new();
                    let opened = self.channel.open(&from, &datagram, now, &mut back);
                    self.send(&from, back);
                    match opened {
                        Ok(Some(message)) => {
                            out.extend(self.lock().on_message(&from, message, now))
                        }
                        Ok(None) => {}
                        Err(e) => {
                            self.lock().refused(match &e {
                                ContainerError::Refused { reason, .. } => *reason,
                                _ => iw_bus::Reason::Malformed,
                            });
                            match self.warn.admit((), now) {
                                Some(held_back) => {
                                    tracing::warn!(%from, error = %e, held_back, "ignoring a control datagram (one warning per 10 s)")
                                }
                                None => {
                                    tracing::debug!(%from, error = %e, "ignoring a control datagram")
                                }
                            }
                        }
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    tracing::warn!(error = %e, "container transport failed; carrying on alone");
                    std::thread::sleep(tick);
                    break;
                }
            }
            wait = Duration::ZERO;
        }
        let now = clock.now();
        let ticked = self.lock().on_tick(now);
        // Each peer gets the message under its own session (one AEAD seal each), with a
        // sequence number of its own: a receiver takes a repeated heartbeat for a new one.
        for Outgoing { to, msg } in out.into_iter().chain(ticked) {
            match self.channel.seal(&to, &msg, now) {
                Ok(datagrams) => self.send(&to, datagrams),
                Err(e) => tracing::error!(error = %e, "control message not sealed"),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{AgentEntry, ContainerConfig, ContainerId};
    use iw_bus::Time;
    use iw_bus::transport::PeerAddr;
    use iw_transport_net::UdpTransport;
    use std::collections::BTreeSet;

    /// One container over a real loopback socket, its rounds run by the test on a shared mock
    /// clock, so when it runs and how much time passes in between is decided here. (Its parts
    /// live as long as the test process.)
    struct Hand {
        driver: Driver<'static>,
        state: &'static Mutex<Container>,
        addr: PeerAddr,
    }

    impl Hand {
        fn new(id: u64, lease_ms: u64, seeds: &[PeerAddr], clock: &Clock) -> Hand {
            let transport = UdpTransport::bind("127.0.0.1:0").unwrap();
            let addr = transport.local_addr().clone();
            let identity = Identity::generate().unwrap();
            let mut config = ContainerConfig::new(ContainerId(id), addr.clone(), seeds.to_vec());
            config.heartbeat = Duration::from_millis(50);
            config.lease = Duration::from_millis(lease_ms);
            let mut container = Container::new(config);
            container.set_key(identity.public_key());
            container.register(AgentEntry {
                name: format!("agent@{id}"),
                public_key: identity.public_key().to_vec(),
                addr: addr.clone(),
            });
            let state: &'static Mutex<Container> = Box::leak(Box::new(Mutex::new(container)));
            let channel = ControlChannel::new(Arc::new(identity)).unwrap();
            let driver = Driver::new(
                state,
                channel,
                Box::leak(Box::new(transport)),
                Box::leak(Box::new(clock.clone())),
                Duration::from_millis(1),
            );
            Hand {
                driver,
                state,
                addr,
            }
        }

        fn round(&mut self) {
            self.driver.round();
        }

        fn gal_len(&self) -> usize {
            self.state.lock().unwrap().gal().len()
        }

        fn live_peers(&self) -> BTreeSet<u64> {
            self.state
                .lock()
                .unwrap()
                .live_peers()
                .iter()
                .map(|c| c.0)
                .collect()
        }
    }

    /// The services' container (the leader, lease 1 s) is not scheduled for 1.2 s while three
    /// chairs' containers run: two of them heartbeat into its socket, the third is really gone.
    /// Its first round afterwards takes the queued heartbeats before it judges the leases, so it
    /// expires only the one it has not heard from. Taking one frame and then judging (the
    /// earlier loop) expired every live chair but the one whose heartbeat came first, and they
    /// came back a round later: one `left` and one `joined` per chair per stall.
    #[test]
    fn a_stalled_leader_takes_queued_heartbeats_before_it_judges_leases() {
        let (clock, time) = Clock::mock(Time(1_000_000_000_000));
        let mut leader = Hand::new(1, 1000, &[], &clock);
        // The chairs' leases outlast the stall, so they keep heartbeating the leader they chose.
        let mut chairs: Vec<Hand> = (1000..1003)
            .map(|id| Hand::new(id, 2000, &[leader.addr.clone()], &clock))
            .collect();
        let all: BTreeSet<u64> = [1000, 1001, 1002].into();
        let mut rounds = 0;
        while leader.live_peers() != all
            || leader.gal_len() != 4
            || chairs.iter().any(|c| c.gal_len() != 4)
        {
            rounds += 1;
            assert!(
                rounds < 200,
                "no convergence: leader sees {:?}",
                leader.live_peers()
            );
            time.advance(Duration::from_millis(10));
            leader.round();
            for chair in &mut chairs {
                chair.round();
            }
        }
        // settle into idle heartbeats
        for _ in 0..50 {
            time.advance(Duration::from_millis(10));
            leader.round();
            for chair in &mut chairs {
                chair.round();
            }
        }
        leader.round(); // nothing of before the stall waits in its socket

        // The stall: 1.2 s, past the leader's lease; chair 1002 runs no more.
        for _ in 0..24 {
            time.advance(Duration::from_millis(50));
            for chair in &mut chairs[..2] {
                chair.round();
            }
        }
        leader.round();
        let live = leader.live_peers();
        assert_eq!(
            live,
            BTreeSet::from([1000, 1001]),
            "after the stall the leader holds {live:?}: 1000 and 1001 heartbeated into its \
             socket meanwhile (expired when the leases were judged before their queued frames \
             were read); 1002 did not (kept when leases are not judged at all)"
        );
    }
}
