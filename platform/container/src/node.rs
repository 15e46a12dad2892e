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
    mut channel: ControlChannel,
    transport: &dyn FrameTransport,
    clock: &Clock,
    tick: Duration,
    stop: &AtomicBool,
) {
    let lock = || state.lock().unwrap_or_else(PoisonError::into_inner);
    // Refused datagrams (garbage, a session this end lost) are one WARN per period, not one
    // per datagram.
    let mut warn = WarnEvery::new(iw_bus::WARN_PERIOD);
    let send = |to: &PeerAddr, datagrams: Vec<Vec<u8>>| {
        for d in datagrams {
            if let Err(e) = transport.send(to, &d) {
                tracing::debug!(%to, error = %e, "control datagram not sent");
            }
        }
    };
    while !stop.load(Ordering::Relaxed) {
        // Everything already queued is taken before the leases are judged: a process that was
        // not scheduled for a lease must not expire peers whose heartbeats wait in its socket.
        let mut out = Vec::new();
        let mut wait = tick;
        for _ in 0..MAX_BATCH {
            match transport.recv_timeout(wait) {
                Ok(Some((from, datagram))) => {
                    let now = clock.now();
                    let mut back = Vec::new();
                    let opened = channel.open(&from, &datagram, now, &mut back);
                    send(&from, back);
                    match opened {
                        Ok(Some(message)) => out.extend(lock().on_message(&from, message, now)),
                        Ok(None) => {}
                        Err(e) => {
                            lock().refused(match &e {
                                ContainerError::Refused { reason, .. } => *reason,
                                _ => iw_bus::Reason::Malformed,
                            });
                            match warn.admit((), now) {
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
        let ticked = lock().on_tick(now);
        // Each peer gets the message under its own session (one AEAD seal each), with a
        // sequence number of its own: a receiver takes a repeated heartbeat for a new one.
        for Outgoing { to, msg } in out.into_iter().chain(ticked) {
            match channel.seal(&to, &msg, now) {
                Ok(datagrams) => send(&to, datagrams),
                Err(e) => tracing::error!(error = %e, "control message not sealed"),
            }
        }
    }
}
