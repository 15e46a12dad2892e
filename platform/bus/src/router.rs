//! The [`Bus`]: agent mailboxes, routing by agent name to a local mailbox or a remote endpoint,
//! and the pump that moves frames between the layer [`Stack`] and a [`FrameTransport`].
//!
//! Sending runs the envelope down the stack (outbound), then either straight back up the same
//! stack (inbound) for a local receiver, or encodes it and hands the frame to the transport.
//!
//! # The pump
//! Receiving is done in rounds: wait for a frame, take every frame already waiting, run them up
//! the stack and collect what the layers originate (acknowledgements, retransmissions) under one
//! stack lock, then deliver and send after unlocking. Who runs the rounds:
//! - **An agent thread blocked in [`Mailbox::recv_timeout`] or [`Mailbox::blocking_recv`]
//!   leads**: it runs the rounds itself until its own envelope is in its mailbox, so a message
//!   reaches a waiting agent thread without a hand-off to another thread. While it leads it holds
//!   a short lease (real monotonic time, whatever the bus [`Clock`]) that keeps the pump thread
//!   away.
//! - **The pump thread** runs the rounds whenever no agent thread holds the lease: async agents
//!   (`recv().await`), polling agents (`try_recv`) and layer timers rely on it.
//! - Other blocked agent threads **follow**: they wait on their own mailbox, where the leader
//!   delivers their envelopes, and one of them takes over when the leader leaves.
//!
//! Guarantees: one thread at a time receives from the transport and runs the inbound stack (the
//! pump role), and it delivers a round's envelopes before giving the role up, so frames from one
//! sender reach a mailbox in the order the transport gave them. Every round, whoever runs it,
//! also sends what the layer timers make due, so retransmissions and acknowledgements go out
//! while agent threads lead. Nobody holds the pump role while waiting on a mailbox, nor the stack
//! lock while delivering or sending. A failed transport receive stops all receiving (logged);
//! local delivery still works.
//!
//! One thing is deliberately left for later: a round that hands the leading agent thread its own
//! envelope does not collect what the layers originate in answer (the envelope's
//! acknowledgement), so the agent gets it at once; that agent's next send collects and sends it
//! after the agent's own frame, or else the next round does, whoever runs it (the pump thread
//! at the latest when the lease runs out).

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError, RwLock, TryLockError, Weak};
use std::task::{Context, Poll, Wake, Waker};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use rustc_hash::FxHashMap;
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TryRecvError;

use crate::BusError;
use crate::codec::FrameCodec;
use crate::envelope::{Envelope, IdGen, MsgId};
use crate::layer::{Counters, Layer, Reason, Stack, Verdict};
use crate::time::{Clock, Time, duration_ns};
use crate::transport::{FrameTransport, PeerAddr, TransportError};

/// Bus settings.
#[derive(Debug, Clone, Copy)]
pub struct BusConfig {
    /// Envelopes a mailbox holds before further ones are dropped ([`Reason::MailboxFull`],
    /// warned of with the receiver's name; a local sender gets [`BusError::MailboxFull`]).
    pub mailbox_capacity: usize,
    /// Longest the pump waits for a frame before it checks the layers' timers (default 1 ms).
    pub tick: Duration,
    /// Frame codec (size limit).
    pub codec: FrameCodec,
}

impl Default for BusConfig {
    fn default() -> Self {
        BusConfig {
            mailbox_capacity: 1024,
            tick: Duration::from_millis(1),
            codec: FrameCodec::new(),
        }
    }
}

/// An agent's inbox: envelopes addressed to it that passed every layer.
///
/// A thread blocked in [`Mailbox::blocking_recv`] or [`Mailbox::recv_timeout`] receives from the
/// transport itself, one such thread per bus at a time (the others wait for it to deliver their
/// envelopes), and the bus's pump thread stands back meanwhile: a message reaches a waiting agent
/// thread without a hand-off between threads. Frames from one sender keep their order, and layer
/// timers (retransmissions, acknowledgements) run whoever receives.
#[derive(Debug)]
pub struct Mailbox {
    name: String,
    rx: mpsc::Receiver<Envelope>,
    /// The bus, so that a thread blocked here can run the pump itself; weak, so a forgotten
    /// mailbox does not keep the bus alive.
    bus: Weak<Inner>,
}

impl Mailbox {
    /// The agent's name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The next envelope; `None` once the bus is gone.
    pub async fn recv(&mut self) -> Option<Envelope> {
        self.rx.recv().await
    }
    /// The next envelope if one is waiting (delivered by the pump thread or a leading thread;
    /// this does not receive from the transport).
    pub fn try_recv(&mut self) -> Option<Envelope> {
        self.rx.try_recv().ok()
    }
    /// Blocks for the next envelope; `None` once the agent is deregistered or the bus is gone.
    /// The calling thread receives from the transport itself while it waits (see the module
    /// documentation). Not from inside an async runtime: it would block the runtime's thread.
    pub fn blocking_recv(&mut self) -> Option<Envelope> {
        self.recv_within(None)
    }

    /// As [`Mailbox::blocking_recv`], giving up after `timeout` (`None` then too).
    pub fn recv_timeout(&mut self, timeout: Duration) -> Option<Envelope> {
        self.recv_within(Some(timeout))
    }

    /// An envelope already waiting, without reading the clock (a busy agent's usual case); else
    /// [`Mailbox::recv_until`] the end of `timeout` (`None`: no timeout).
    fn recv_within(&mut self, timeout: Option<Duration>) -> Option<Envelope> {
        match self.rx.try_recv() {
            Ok(env) => Some(env),
            Err(TryRecvError::Disconnected) => None,
            // A timeout beyond what `Instant` can represent is no timeout.
            Err(TryRecvError::Empty) => {
                self.recv_until(timeout.and_then(|t| Instant::now().checked_add(t)))
            }
        }
    }

    /// Leads the pump, or follows, until an envelope is here, the stream ends or `deadline`.
    fn recv_until(&mut self, deadline: Option<Instant>) -> Option<Envelope> {
        let mut frames = Vec::new();
        let mut waker = None;
        let mut led = false;
        let mut spin_until = Instant::now() + SPIN;
        let got = loop {
            match self.rx.try_recv() {
                Ok(env) => break Some(env),
                Err(TryRecvError::Disconnected) => break None,
                Err(TryRecvError::Empty) => {}
            }
            let left = deadline.map_or(Duration::MAX, |d| {
                d.saturating_duration_since(Instant::now())
            });
            if left.is_zero() {
                break None;
            }
            // The bus is not kept while waiting (below): dropping it must end this stream.
            let mut following = false;
            if let Some(bus) = self
                .bus
                .upgrade()
                .filter(|bus| !bus.stop.load(Ordering::Acquire))
            {
                let mut lead = || match bus.try_lead(&self.name, left, spin_until, &mut frames) {
                    Some(received) => {
                        // Frames flowing (an acknowledgement before the reply): the next is near.
                        if received > 0 {
                            spin_until = Instant::now() + SPIN;
                        }
                        true
                    }
                    None => false,
                };
                if lead() {
                    led = true;
                    continue;
                }
                bus.follow(true);
                // The leader may have left between the failed attempt and the registration.
                if lead() {
                    bus.follow(false);
                    led = true;
                    continue;
                }
                following = true;
            }
            // Follow (or, with the bus stopped or gone, wait for a local delivery or the end of
            // the stream): a delivery, the leader leaving or the channel closing wakes this thread.
            let waker =
                waker.get_or_insert_with(|| Waker::from(Arc::new(Unpark(std::thread::current()))));
            let polled = self.rx.poll_recv(&mut Context::from_waker(waker));
            if polled.is_pending() {
                std::thread::park_timeout(left.min(MAX_FOLLOW));
            }
            if following && let Some(bus) = self.bus.upgrade() {
                bus.follow(false);
            }
            if let Poll::Ready(got) = polled {
                break got;
            }
        };
        if led && let Some(bus) = self.bus.upgrade() {
            bus.wake_followers();
        }
        got
    }
}

/// Wakes a thread parked on its mailbox when an envelope arrives or the channel closes.
struct Unpark(Thread);

impl Wake for Unpark {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        self.0.unpark();
    }
}

/// Longest a follower waits on its mailbox before it looks at the pump role again (it is
/// normally woken sooner: by a delivery, or by the leader leaving).
const MAX_FOLLOW: Duration = Duration::from_millis(1);

/// How long a leading agent thread polls the transport (yielding the core in between) before it
/// blocks in it, from the start of its wait or the last frame it took: a reply a few
/// microseconds away then costs no sleep and wake-up on either side. Bounded, so an agent thread
/// waiting long for a message costs this once, not all the time.
const SPIN: Duration = Duration::from_micros(50);

/// How long a leading agent thread keeps the pump thread away after its round would end: room
/// for the agent's own work between two receives, so the pump thread does not take the role (and
/// the next frame with it) in between.
const LEASE: Duration = Duration::from_micros(500);

/// No layer timer pending, in [`Inner::next_deadline`].
const NO_DEADLINE: u64 = u64::MAX;

struct Inner {
    stack: Mutex<Stack>,
    transport: Arc<dyn FrameTransport>,
    clock: Clock,
    config: BusConfig,
    /// Local agents' mailboxes. Names are put in by the platform only (frames merely look them
    /// up), so the map uses a fast unkeyed hash, as does `routes`.
    local: RwLock<FxHashMap<String, mpsc::Sender<Envelope>>>,
    /// Shared addresses: sending takes one without copying it.
    routes: RwLock<FxHashMap<String, Arc<PeerAddr>>>,
    ids: Mutex<IdGen>,
    /// Set by shutdown, or when a transport receive fails: nobody receives any more.
    stop: AtomicBool,
    /// Held by the one thread that receives from the transport and runs the inbound stack.
    pump_role: Mutex<()>,
    /// The layers' next timer as of the last round, ns since the epoch ([`NO_DEADLINE`] if none).
    next_deadline: AtomicU64,
    /// Until when agent threads lead, ns of real time since `started`: the pump thread stays away.
    lease_until: AtomicU64,
    /// Origin of `lease_until`: leases run in real time, also on a bus with a mock clock.
    started: Instant,
    /// Agent threads waiting on their mailbox while another thread holds the pump role.
    followers: Mutex<Vec<Thread>>,
}

/// The message bus of one container.
pub struct Bus {
    inner: Arc<Inner>,
    pump: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("addr", self.inner.transport.local_addr())
            .finish()
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Bus {
    /// Starts a bus over `transport` with the given layers; spawns its pump thread.
    pub fn start(
        stack: Stack,
        transport: Arc<dyn FrameTransport>,
        clock: Clock,
        config: BusConfig,
    ) -> Result<Bus, BusError> {
        let next_deadline = stack.next_deadline().map_or(NO_DEADLINE, Time::as_ns);
        let inner = Arc::new(Inner {
            stack: Mutex::new(stack),
            transport,
            clock,
            config,
            local: RwLock::default(),
            routes: RwLock::default(),
            ids: Mutex::new(IdGen::new()),
            stop: AtomicBool::new(false),
            pump_role: Mutex::new(()),
            next_deadline: AtomicU64::new(next_deadline),
            lease_until: AtomicU64::new(0),
            started: Instant::now(),
            followers: Mutex::new(Vec::new()),
        });
        let pump_inner = inner.clone();
        let pump = std::thread::Builder::new()
            .name(format!("bus-pump-{}", inner.transport.local_addr()))
            .spawn(move || pump_inner.pump())
            .map_err(|source| BusError::Spawn { source })?;
        Ok(Bus {
            inner,
            pump: Some(pump),
        })
    }

    /// Registers a local agent and returns its mailbox.
    pub fn register(&self, name: &str) -> Result<Mailbox, BusError> {
        let mut local = self
            .inner
            .local
            .write()
            .unwrap_or_else(PoisonError::into_inner);
        if local.contains_key(name) {
            return Err(BusError::AgentExists {
                name: name.to_string(),
            });
        }
        let (tx, rx) = mpsc::channel(self.inner.config.mailbox_capacity.max(1));
        local.insert(name.to_string(), tx);
        Ok(Mailbox {
            name: name.to_string(),
            rx,
            bus: Arc::downgrade(&self.inner),
        })
    }

    /// Removes a local agent; its mailbox sees the end of the stream.
    pub fn deregister(&self, name: &str) {
        self.inner
            .local
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(name);
    }

    /// Routes envelopes for the remote agent `agent` to the endpoint `addr`.
    pub fn add_route(&self, agent: &str, addr: PeerAddr) {
        self.inner
            .routes
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(agent.to_string(), Arc::new(addr));
    }

    /// Forgets the route to `agent`.
    pub fn remove_route(&self, agent: &str) {
        self.inner
            .routes
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(agent);
    }

    /// This bus's transport address.
    pub fn local_addr(&self) -> &PeerAddr {
        self.inner.transport.local_addr()
    }

    /// The clock the bus stamps and checks with.
    pub fn clock(&self) -> &Clock {
        &self.inner.clock
    }

    /// Sends `payload` (an ACL string) from `sender` to `receiver` with a fresh message id.
    pub fn send(&self, sender: &str, receiver: &str, payload: Vec<u8>) -> Result<MsgId, BusError> {
        let id = lock(&self.inner.ids).next_id();
        self.send_envelope(Envelope::new(id, sender, receiver, payload))?;
        Ok(id)
    }

    /// Sends a prepared envelope (its id must be fresh for its sender).
    pub fn send_envelope(&self, mut env: Envelope) -> Result<(), BusError> {
        let Some(destination) = self.inner.destination(&env.header.receiver) else {
            lock(&self.inner.stack).record(Reason::NoRoute);
            return Err(BusError::NoRoute {
                receiver: env.header.receiver,
            });
        };
        // One lock for the message: down the stack, back up for a local receiver, and whatever
        // the layers originate meanwhile; delivery and sending happen after it is released.
        let mut out = Outcome::default();
        let mut own = Vec::new();
        let remote = {
            let mut stack = lock(&self.inner.stack);
            let now = self.inner.clock.now();
            let remote = match stack.outbound(&mut env, now) {
                Verdict::Pass => Inner::route_locked(&mut stack, destination, env, now, &mut own),
                Verdict::Drop(_) | Verdict::Consumed => None,
            };
            self.inner.collect_locked(&mut stack, now, &mut out);
            remote
        };
        let sent = remote.map_or(Ok(()), |(addr, env)| self.inner.send_remote(&addr, &env));
        // A local receiver that cannot take the message: its sender is told (FIPA's ACC
        // returns an error to the sender), not only the counter.
        let delivered = own.into_iter().try_for_each(|env| self.inner.deliver(env));
        self.inner.finish(out);
        sent.and(delivered)
    }

    /// Rejections so far, per reason (all layers and the bus itself).
    pub fn counters(&self) -> Counters {
        lock(&self.inner.stack).counters().clone()
    }

    /// Stops receiving (the pump thread and leading agent threads) and waits for the pump thread.
    pub fn shutdown(mut self) {
        self.stop_pump();
    }

    fn stop_pump(&mut self) {
        self.inner.stop.store(true, Ordering::Release);
        if let Some(pump) = self.pump.take() {
            // A panicked pump has nothing left to clean up.
            let _ = pump.join();
        }
    }
}

impl Drop for Bus {
    fn drop(&mut self) {
        self.stop_pump();
    }
}

impl Inner {
    /// Where envelopes for `agent` go: its local mailbox, else its route; `None` without either.
    fn destination(&self, agent: &str) -> Option<Destination> {
        if self
            .local
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .contains_key(agent)
        {
            return Some(Destination::Local);
        }
        self.routes
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(agent)
            .cloned()
            .map(Destination::Remote)
    }

    /// An envelope that passed the stack outbound (the stack is locked): run it back up for a
    /// local receiver (queued in `deliver` if it passes), or hand it back with its address to be
    /// sent. `now` is the time read once for the whole locked pass (a clock read costs as much
    /// as a layer).
    fn route_locked(
        stack: &mut Stack,
        destination: Destination,
        mut env: Envelope,
        now: Time,
        deliver: &mut Vec<Envelope>,
    ) -> Option<(Arc<PeerAddr>, Envelope)> {
        match destination {
            Destination::Local => {
                if let Verdict::Pass = stack.inbound(&mut env, now) {
                    deliver.push(env);
                }
                None
            }
            Destination::Remote(addr) => Some((addr, env)),
        }
    }

    /// Takes everything the layers originated that is due at `now` (the stack is locked).
    fn collect_locked(&self, stack: &mut Stack, now: Time, out: &mut Outcome) {
        while let Some(env) = stack.poll_transmit(now) {
            let Some(destination) = self.destination(&env.header.receiver) else {
                tracing::debug!(receiver = %env.header.receiver, "layer-originated frame has no route");
                stack.record(Reason::NoRoute);
                continue;
            };
            if let Some(remote) = Self::route_locked(stack, destination, env, now, &mut out.deliver)
            {
                out.send.push(remote);
            }
        }
    }

    /// Delivers and sends what a locked pass through the stack produced.
    fn finish(&self, out: Outcome) {
        for env in out.deliver {
            // counted and logged by `deliver`; a remote sender has had its acknowledgement
            let _ = self.deliver(env);
        }
        for (addr, env) in out.send {
            if let Err(e) = self.send_remote(&addr, &env) {
                tracing::warn!(error = %e, "layer-originated frame not sent");
            }
        }
    }

    /// Encodes an envelope for a remote receiver and hands it to the transport.
    fn send_remote(&self, addr: &PeerAddr, env: &Envelope) -> Result<(), BusError> {
        // This thread's frame buffer; a fresh one while the thread is being torn down.
        FRAME
            .try_with(|frame| self.encode_and_send(addr, env, &mut frame.borrow_mut()))
            .unwrap_or_else(|_| self.encode_and_send(addr, env, &mut Vec::new()))
    }

    fn encode_and_send(
        &self,
        addr: &PeerAddr,
        env: &Envelope,
        frame: &mut Vec<u8>,
    ) -> Result<(), BusError> {
        frame.clear();
        self.config.codec.encode(env, frame)?;
        self.transport
            .send(addr, frame)
            .map_err(|source| BusError::Transport {
                context: format!("sending to {addr}"),
                source,
            })
    }

    /// Puts `env` in its receiver's mailbox. A full or closed mailbox (or a receiver gone since
    /// the route was chosen) drops it: counted, and warned of (one warning per
    /// [`crate::WARN_PERIOD`], naming the receiver, the sender and the mailbox's state), never
    /// silent.
    fn deliver(&self, env: Envelope) -> Result<(), BusError> {
        let local = self.local.read().unwrap_or_else(PoisonError::into_inner);
        let refused = match local.get(&env.header.receiver) {
            Some(tx) => tx.try_send(env).err().map(|e| match e {
                mpsc::error::TrySendError::Full(env) => (env, "full: the agent is behind"),
                mpsc::error::TrySendError::Closed(env) => (env, "closed"),
            }),
            // it left (deregistered) since the route was chosen, e.g. at a take-down
            None => Some((env, "gone: the agent left")),
        };
        drop(local);
        let Some((env, why)) = refused else {
            return Ok(());
        };
        let now = self.clock.now();
        let mut stack = lock(&self.stack);
        if let Some(held_back) = stack.record_and_admit(Reason::MailboxFull, now) {
            let total = stack.counters().get(Reason::MailboxFull);
            drop(stack);
            tracing::warn!(receiver = %env.header.receiver, sender = %env.header.sender, mailbox = why, held_back, total, "message dropped at its receiver's mailbox (one warning per 10 s)");
        }
        Err(BusError::MailboxFull {
            receiver: env.header.receiver,
        })
    }

    /// The pump thread: runs rounds while no agent thread leads.
    fn pump(&self) {
        let mut frames = Vec::new();
        while !self.stop.load(Ordering::Acquire) {
            let leased = self.lease_left();
            if !leased.is_zero() {
                std::thread::sleep(leased.min(self.config.tick));
                continue;
            }
            let role = lock(&self.pump_role);
            // An agent thread may have come to lead while this one waited for the role.
            if self.lease_left().is_zero() {
                self.round(self.config.tick, None, None, &mut frames);
            }
            drop(role);
            self.wake_followers();
        }
    }

    /// One round led by agent `me`'s thread (polling the transport until `spin_until`), unless
    /// another thread holds the pump role (`None`); the frames received. Renews the lease either
    /// way: a thread that wants to lead keeps the pump thread away.
    fn try_lead(
        &self,
        me: &str,
        wait: Duration,
        spin_until: Instant,
        frames: &mut Vec<(PeerAddr, Vec<u8>)>,
    ) -> Option<usize> {
        let wait = wait.min(self.config.tick);
        let until = duration_ns(self.started.elapsed())
            .saturating_add(duration_ns(wait.saturating_add(LEASE)));
        self.lease_until.fetch_max(until, Ordering::AcqRel);
        let _role = match self.pump_role.try_lock() {
            Ok(role) => role,
            Err(TryLockError::Poisoned(role)) => role.into_inner(),
            Err(TryLockError::WouldBlock) => return None,
        };
        Some(self.round(wait, Some(spin_until), Some(me), frames))
    }

    /// Real time left on the agent threads' lease.
    fn lease_left(&self) -> Duration {
        let now = duration_ns(self.started.elapsed());
        Duration::from_nanos(self.lease_until.load(Ordering::Acquire).saturating_sub(now))
    }

    /// Adds (`true`) or removes the calling thread from the followers.
    fn follow(&self, waiting: bool) {
        let me = std::thread::current();
        let mut followers = lock(&self.followers);
        followers.retain(|t| t.id() != me.id());
        if waiting {
            followers.push(me);
        }
    }

    /// Called by a thread that gives the pump role up for a while: a follower may take it.
    fn wake_followers(&self) {
        for follower in lock(&self.followers).drain(..) {
            follower.unpark();
        }
    }

    /// [`Inner::pump_round`]; a receive error stops all receiving.
    fn round(
        &self,
        wait: Duration,
        spin_until: Option<Instant>,
        leader: Option<&str>,
        frames: &mut Vec<(PeerAddr, Vec<u8>)>,
    ) -> usize {
        match self.pump_round(wait, spin_until, leader, frames) {
            Ok(received) => received,
            Err(e) => {
                tracing::warn!(error = %e, "transport receive failed; the bus stops receiving");
                self.stop.store(true, Ordering::Release);
                0
            }
        }
    }

    /// One round, by the holder of the pump role (the agent thread of `leader`, or the pump
    /// thread): waits up to `wait` (less if a layer timer is due sooner) for a frame, polling
    /// until `spin_until` before it blocks; takes every frame already waiting (up to
    /// [`MAX_BATCH`]), runs them up the stack and collects what the layers originate under one
    /// lock (unless `leader` gets an envelope: see the module documentation), then delivers and
    /// sends after unlocking. Returns the frames received. After a receive error the frames
    /// already taken are still handled, then the error is returned.
    fn pump_round(
        &self,
        mut wait: Duration,
        spin_until: Option<Instant>,
        leader: Option<&str>,
        frames: &mut Vec<(PeerAddr, Vec<u8>)>,
    ) -> Result<usize, TransportError> {
        let deadline = self.next_deadline.load(Ordering::Acquire);
        if deadline != NO_DEADLINE && !self.clock.is_mock() {
            wait = wait.min(Time::from_ns(deadline).since(self.clock.now()));
        }
        let mut failed = None;
        match self.first_frame(wait, spin_until) {
            Ok(Some(frame)) => frames.push(frame),
            Ok(None) => {}
            Err(e) => failed = Some(e),
        }
        // Take every frame already waiting before going back to sleep.
        while failed.is_none() && !frames.is_empty() && frames.len() < MAX_BATCH {
            match self.transport.recv_timeout(Duration::ZERO) {
                Ok(Some(frame)) => frames.push(frame),
                Ok(None) => break,
                Err(e) => failed = Some(e),
            }
        }
        let received = frames.len();
        let decoded: Vec<_> = frames
            .drain(..)
            .map(|(from, frame)| (from, self.config.codec.decode_datagram_owned(frame)))
            .collect();
        // One lock and one clock read for the whole batch and what the layers originate in
        // answer.
        let mut out = Outcome::default();
        {
            let mut stack = lock(&self.stack);
            let now = self.clock.now();
            for (from, env) in decoded {
                match env {
                    Ok(mut env) => {
                        if let Verdict::Pass = stack.inbound(&mut env, now) {
                            out.deliver.push(env);
                        }
                    }
                    Err(e) => {
                        tracing::debug!(%from, error = %e, "undecodable frame");
                        stack.record(Reason::BadFrame);
                    }
                }
            }
            // Left uncollected, the layers' frames make their next deadline now: whoever runs
            // the next round does not wait for them.
            if !leader.is_some_and(|me| out.deliver.iter().any(|env| env.header.receiver == me)) {
                self.collect_locked(&mut stack, now, &mut out);
            }
            let next = stack.next_deadline().map_or(NO_DEADLINE, Time::as_ns);
            self.next_deadline.store(next, Ordering::Release);
        }
        self.finish(out);
        failed.map_or(Ok(received), Err)
    }

    /// The first frame of a round: polls (yielding the core) until `spin_until`, then blocks for
    /// the rest of `wait`.
    fn first_frame(
        &self,
        wait: Duration,
        spin_until: Option<Instant>,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError> {
        let start = Instant::now();
        let Some(spin_until) =
            spin_until.map(|s| start.checked_add(wait).map_or(s, |end| s.min(end)))
        else {
            return self.transport.recv_timeout(wait);
        };
        loop {
            if let Some(frame) = self.transport.recv_timeout(Duration::ZERO)? {
                return Ok(Some(frame));
            }
            let now = Instant::now();
            if now >= spin_until {
                return self
                    .transport
                    .recv_timeout(wait.saturating_sub(now - start));
            }
            std::thread::yield_now();
        }
    }
}

thread_local! {
    /// The frame buffer of every send from this thread (as long as the longest frame it sent):
    /// no allocation per frame.
    static FRAME: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

/// Frames the pump takes in one go before it runs them through the stack.
const MAX_BATCH: usize = 64;

/// What one locked pass through the stack produced: envelopes for local mailboxes, and
/// envelopes for the transport.
#[derive(Default)]
struct Outcome {
    deliver: Vec<Envelope>,
    send: Vec<(Arc<PeerAddr>, Envelope)>,
}

/// Where the envelopes for one agent go.
enum Destination {
    /// Its mailbox on this bus.
    Local,
    /// The endpoint of its route.
    Remote(Arc<PeerAddr>),
}
