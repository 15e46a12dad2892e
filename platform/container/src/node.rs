//! [`ContainerNode`]: a [`Container`] driven over a real frame transport on its own thread.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use iw_bus::transport::FrameTransport;
use iw_bus::{Clock, WarnEvery};
use iw_layer_security::Identity;

use crate::machine::{Container, Outgoing};
use crate::{ContainerError, Signed};

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
    /// signing what it says as `identity` (the container's own, whose key its agents' entries
    /// carry); the container's [`crate::ContainerConfig::key`] is set to that identity's key.
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
        let state = Arc::new(Mutex::new(container));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (state, stop) = (Arc::clone(&state), Arc::clone(&stop));
            std::thread::Builder::new()
                .name("iw-container".into())
                .spawn(move || run(&state, &identity, transport.as_ref(), &clock, tick, &stop))
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
    identity: &Identity,
    transport: &dyn FrameTransport,
    clock: &Clock,
    tick: Duration,
    stop: &AtomicBool,
) {
    let lock = || state.lock().unwrap_or_else(PoisonError::into_inner);
    // Garbage on the control port is one WARN per period, not one per datagram.
    let mut warn = WarnEvery::new(iw_bus::WARN_PERIOD);
    let mut seq = 0u64;
    while !stop.load(Ordering::Relaxed) {
        // Everything already queued is taken before the leases are judged: a process that was
        // not scheduled for a lease must not expire peers whose heartbeats wait in its socket.
        let mut out = Vec::new();
        // no sooner than something is due (a heartbeat, a lease): an idle container wakes a
        // few times a second, not every tick; `tick` bounds the wait for changes made through
        // `with` meanwhile
        let mut wait = lock().next_due().since(clock.now()).min(tick);
        for _ in 0..MAX_BATCH {
            match transport.recv_timeout(wait) {
                Ok(Some((from, frame))) => match Signed::open(&frame) {
                    Ok(signed) => out.extend(lock().on_message(&from, signed, clock.now())),
                    Err(e) => match warn.admit((), clock.now()) {
                        Some(held_back) => {
                            tracing::warn!(%from, error = %e, held_back, "ignoring a control frame (one warning per 10 s)")
                        }
                        None => tracing::debug!(%from, error = %e, "ignoring a control frame"),
                    },
                },
                Ok(None) => break,
                Err(e) => {
                    tracing::warn!(error = %e, "container transport failed; carrying on alone");
                    std::thread::sleep(tick);
                    break;
                }
            }
            wait = Duration::ZERO;
        }
        let ticked = lock().on_tick(clock.now());
        // A message sent to several peers at once (a heartbeat) is signed once; each batch gets
        // new sequence numbers, or a receiver would take a repeated heartbeat for a replay.
        let mut last: Option<(crate::ContainerMsg, Vec<u8>)> = None;
        for Outgoing { to, msg } in out.into_iter().chain(ticked) {
            if last.as_ref().is_none_or(|(m, _)| *m != msg) {
                seq += 1;
                match Signed::seal(identity, seq, &msg) {
                    Ok(frame) => last = Some((msg, frame)),
                    Err(e) => {
                        tracing::error!(error = %e, "control message does not encode");
                        continue;
                    }
                }
            }
            if let Some((_, frame)) = &last
                && let Err(e) = transport.send(&to, frame)
            {
                tracing::debug!(%to, error = %e, "control frame not sent");
            }
        }
    }
}
