//! The impairment relay of a run across processes: every datagram between the containers goes
//! through it, so a `link-loss` fault cuts one container off from the others on real sockets.
//!
//! - Agent bus: each container advertises a *front* address of the relay; whatever reaches the
//!   front goes on to the container's own bus socket. A container sends straight to the others'
//!   fronts, so every bus datagram crosses exactly one front, where its sender is known by its
//!   source address.
//! - Control channel (heartbeats, agent lists): a container answers the address it heard from,
//!   so each chair's (and the world's) control channel meets the services' through a *pair*: two
//!   endpoints that both send to the pair's address, each datagram going on to the other.
//!
//! A datagram from or to a container whose link is down is dropped and counted. Loopback only;
//! every socket wakes at least every 5 ms to notice the stop, and [`Relay`]'s drop joins its
//! threads.

use std::collections::{BTreeMap, BTreeSet};
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

/// Longest a relay thread blocks in one receive.
const POLL: Duration = Duration::from_millis(5);
/// Largest datagram relayed (the UDP payload limit).
const MAX_DATAGRAM: usize = 65_507;

#[derive(Default)]
struct State {
    /// Containers whose link is down.
    down: Mutex<BTreeSet<String>>,
    /// Bus sockets of the containers, by address.
    owners: Mutex<BTreeMap<SocketAddr, String>>,
    stop: AtomicBool,
    /// Bus datagrams forwarded and dropped.
    bus_forwarded: AtomicU64,
    bus_dropped: AtomicU64,
    /// Control datagrams dropped.
    control_dropped: AtomicU64,
}

impl State {
    fn cut(&self, a: &str, b: &str) -> bool {
        let down = self.down.lock().unwrap_or_else(PoisonError::into_inner);
        down.contains(a) || down.contains(b)
    }
}

/// What the relay did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RelayCounts {
    /// Agent bus datagrams forwarded.
    pub bus_forwarded: u64,
    /// Agent bus datagrams dropped by a link fault.
    pub bus_dropped: u64,
    /// Control datagrams dropped by a link fault.
    pub control_dropped: u64,
}

/// A running relay. See the module docs.
#[derive(Default)]
pub struct Relay {
    state: Arc<State>,
    threads: Vec<JoinHandle<()>>,
}

impl Relay {
    /// A relay with no endpoints yet.
    pub fn new() -> Relay {
        Relay::default()
    }

    /// Opens a front for `container`, whose bus socket is `bus`; returns the address the others
    /// are to reach it at.
    pub fn front(&mut self, container: &str, bus: SocketAddr) -> std::io::Result<SocketAddr> {
        let socket = bind_loopback()?;
        let addr = socket.local_addr()?;
        self.state
            .owners
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(bus, container.to_string());
        let state = self.state.clone();
        let container = container.to_string();
        self.spawn(format!("relay-front-{container}"), move || {
            relay_loop(&socket, &state, |from| {
                let sender = state
                    .owners
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .get(&from)
                    .cloned()
                    .unwrap_or_default();
                let cut = state.cut(&sender, &container);
                let counter = if cut {
                    &state.bus_dropped
                } else {
                    &state.bus_forwarded
                };
                counter.fetch_add(1, Ordering::Relaxed);
                (!cut).then_some(bus)
            })
        })?;
        Ok(addr)
    }

    /// Joins control sockets `a` (of container `a_name`) and `b` through a pair listening on
    /// `listen`: each sends to `listen`, and hears the other from it.
    pub fn pair(
        &mut self,
        (a_name, a): (&str, SocketAddr),
        (b_name, b): (&str, SocketAddr),
        listen: SocketAddr,
    ) -> std::io::Result<()> {
        if !listen.ip().is_loopback() {
            return Err(std::io::Error::other(format!("{listen} is not loopback")));
        }
        let socket = UdpSocket::bind(listen)?;
        socket.set_read_timeout(Some(POLL))?;
        let state = self.state.clone();
        let (a_name, b_name) = (a_name.to_string(), b_name.to_string());
        self.spawn(format!("relay-pair-{a_name}"), move || {
            relay_loop(&socket, &state, |from| {
                let to = if from == a {
                    b
                } else if from == b {
                    a
                } else {
                    return None;
                };
                if state.cut(&a_name, &b_name) {
                    state.control_dropped.fetch_add(1, Ordering::Relaxed);
                    return None;
                }
                Some(to)
            })
        })
    }

    /// Takes `container`'s link down (`up == false`) or restores it.
    pub fn set_link(&self, container: &str, up: bool) {
        let mut down = self
            .state
            .down
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if up {
            down.remove(container);
        } else {
            down.insert(container.to_string());
        }
    }

    /// The counts so far.
    pub fn counts(&self) -> RelayCounts {
        RelayCounts {
            bus_forwarded: self.state.bus_forwarded.load(Ordering::Relaxed),
            bus_dropped: self.state.bus_dropped.load(Ordering::Relaxed),
            control_dropped: self.state.control_dropped.load(Ordering::Relaxed),
        }
    }

    fn spawn(&mut self, name: String, f: impl FnOnce() + Send + 'static) -> std::io::Result<()> {
        self.threads
            .push(std::thread::Builder::new().name(name).spawn(f)?);
        Ok(())
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.state.stop.store(true, Ordering::Release);
        for thread in self.threads.drain(..) {
            let _ = thread.join();
        }
    }
}

fn bind_loopback() -> std::io::Result<UdpSocket> {
    let socket = UdpSocket::bind("127.0.0.1:0")?;
    socket.set_read_timeout(Some(POLL))?;
    Ok(socket)
}

/// Receives on `socket` until the stop, sending each datagram where `route(from)` says (nowhere
/// when it says `None`).
fn relay_loop(
    socket: &UdpSocket,
    state: &State,
    mut route: impl FnMut(SocketAddr) -> Option<SocketAddr>,
) {
    let mut buf = vec![0u8; MAX_DATAGRAM];
    while !state.stop.load(Ordering::Acquire) {
        match socket.recv_from(&mut buf) {
            Ok((len, from)) => {
                if let Some(to) = route(from) {
                    // a receiver that is gone (a killed container) is not the relay's fault
                    let _ = socket.send_to(&buf[..len], to);
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::ConnectionRefused
                ) => {}
            Err(e) => {
                tracing::warn!(error = %e, "relay socket failed; its link is cut");
                return;
            }
        }
    }
}
