//! The [`Bus`]: agent mailboxes, routing by agent name to a local mailbox or a remote endpoint,
//! and the pump that moves frames between the layer [`Stack`] and a [`FrameTransport`].
//!
//! Sending runs the envelope down the stack (outbound), then either straight back up the same
//! stack (inbound) for a local receiver, or encodes it and hands the frame to the transport.
//! A pump thread receives frames, decodes them, runs them up the stack and delivers them; it also
//! sends whatever the layers originate (acknowledgements, retransmissions) when due.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError, RwLock};
use std::thread::JoinHandle;
use std::time::Duration;

use tokio::sync::mpsc;

use crate::BusError;
use crate::codec::FrameCodec;
use crate::envelope::{Envelope, IdGen, MsgId};
use crate::layer::{Counters, Layer, Reason, Stack, Verdict};
use crate::time::Clock;
use crate::transport::{FrameTransport, PeerAddr};

/// Bus settings.
#[derive(Debug, Clone, Copy)]
pub struct BusConfig {
    /// Envelopes a mailbox holds before further ones are dropped ([`Reason::MailboxFull`]).
    pub mailbox_capacity: usize,
    /// Longest the pump waits for a frame before it checks the layers' timers (default 1 ms).
    pub tick: Duration,
    /// Frame codec (size limit).
    pub codec: FrameCodec,
}

impl Default for BusConfig {
    fn default() -> Self {
        BusConfig { mailbox_capacity: 1024, tick: Duration::from_millis(1), codec: FrameCodec::new() }
    }
}

/// An agent's inbox: envelopes addressed to it that passed every layer.
#[derive(Debug)]
pub struct Mailbox {
    name: String,
    rx: mpsc::Receiver<Envelope>,
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
    /// The next envelope if one is waiting.
    pub fn try_recv(&mut self) -> Option<Envelope> {
        self.rx.try_recv().ok()
    }
    /// Blocks for the next envelope (not from inside an async runtime).
    pub fn blocking_recv(&mut self) -> Option<Envelope> {
        self.rx.blocking_recv()
    }
}

struct Inner {
    stack: Mutex<Stack>,
    transport: Arc<dyn FrameTransport>,
    clock: Clock,
    config: BusConfig,
    local: RwLock<HashMap<String, mpsc::Sender<Envelope>>>,
    routes: RwLock<HashMap<String, PeerAddr>>,
    ids: Mutex<IdGen>,
    stop: AtomicBool,
}

/// The message bus of one container.
pub struct Bus {
    inner: Arc<Inner>,
    pump: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus").field("addr", self.inner.transport.local_addr()).finish()
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Bus {
    /// Starts a bus over `transport` with the given layers; spawns its pump thread.
    pub fn start(stack: Stack, transport: Arc<dyn FrameTransport>, clock: Clock, config: BusConfig) -> Result<Bus, BusError> {
        let inner = Arc::new(Inner {
            stack: Mutex::new(stack),
            transport,
            clock,
            config,
            local: RwLock::new(HashMap::new()),
            routes: RwLock::new(HashMap::new()),
            ids: Mutex::new(IdGen::new()),
            stop: AtomicBool::new(false),
        });
        let pump_inner = inner.clone();
        let pump = std::thread::Builder::new()
            .name(format!("bus-pump-{}", inner.transport.local_addr()))
            .spawn(move || pump_inner.pump())
            .map_err(|source| BusError::Spawn { source })?;
        Ok(Bus { inner, pump: Some(pump) })
    }

    /// Registers a local agent and returns its mailbox.
    pub fn register(&self, name: &str) -> Result<Mailbox, BusError> {
        let mut local = self.inner.local.write().unwrap_or_else(PoisonError::into_inner);
        if local.contains_key(name) {
            return Err(BusError::AgentExists { name: name.to_string() });
        }
        let (tx, rx) = mpsc::channel(self.inner.config.mailbox_capacity.max(1));
        local.insert(name.to_string(), tx);
        Ok(Mailbox { name: name.to_string(), rx })
    }

    /// Removes a local agent; its mailbox sees the end of the stream.
    pub fn deregister(&self, name: &str) {
        self.inner.local.write().unwrap_or_else(PoisonError::into_inner).remove(name);
    }

    /// Routes envelopes for the remote agent `agent` to the endpoint `addr`.
    pub fn add_route(&self, agent: &str, addr: PeerAddr) {
        self.inner.routes.write().unwrap_or_else(PoisonError::into_inner).insert(agent.to_string(), addr);
    }

    /// Forgets the route to `agent`.
    pub fn remove_route(&self, agent: &str) {
        self.inner.routes.write().unwrap_or_else(PoisonError::into_inner).remove(agent);
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
    pub fn send_envelope(&self, env: Envelope) -> Result<(), BusError> {
        let receiver = env.header.receiver.clone();
        if !self.inner.is_local(&receiver) && self.inner.route(&receiver).is_none() {
            lock(&self.inner.stack).record(Reason::NoRoute);
            return Err(BusError::NoRoute { receiver });
        }
        // One lock for the message: down the stack, back up for a local receiver, and whatever
        // the layers originate meanwhile; delivery and sending happen after it is released.
        let mut out = Outcome::default();
        let remote = {
            let mut stack = lock(&self.inner.stack);
            let now = self.inner.clock.now();
            let remote = match stack.outbound(env, now) {
                Verdict::Pass(env) => self.inner.route_locked(&mut stack, env, &mut out.deliver),
                Verdict::Drop(_) | Verdict::Consumed => None,
            };
            self.inner.collect_locked(&mut stack, &mut out);
            remote
        };
        let sent = remote.map_or(Ok(()), |env| self.inner.send_remote(env));
        self.inner.finish(out);
        sent
    }

    /// Rejections so far, per reason (all layers and the bus itself).
    pub fn counters(&self) -> Counters {
        lock(&self.inner.stack).counters().clone()
    }

    /// Stops the pump thread and waits for it.
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
    fn is_local(&self, agent: &str) -> bool {
        self.local.read().unwrap_or_else(PoisonError::into_inner).contains_key(agent)
    }

    fn route(&self, agent: &str) -> Option<PeerAddr> {
        self.routes.read().unwrap_or_else(PoisonError::into_inner).get(agent).cloned()
    }

    /// An envelope that passed the stack outbound (the stack is locked): run it back up for a
    /// local receiver (queued in `deliver` if it passes), or hand it back to be sent.
    fn route_locked(&self, stack: &mut Stack, env: Envelope, deliver: &mut Vec<Envelope>) -> Option<Envelope> {
        if self.is_local(&env.header.receiver) {
            let now = self.clock.now();
            if let Verdict::Pass(env) = stack.inbound(env, now) {
                deliver.push(env);
            }
            return None;
        }
        Some(env)
    }

    /// Takes everything the layers originated that is due now (the stack is locked).
    fn collect_locked(&self, stack: &mut Stack, out: &mut Outcome) {
        loop {
            let now = self.clock.now();
            let Some(env) = stack.poll_transmit(now) else { return };
            if let Some(env) = self.route_locked(stack, env, &mut out.deliver) {
                out.send.push(env);
            }
        }
    }

    /// Delivers and sends what a locked pass through the stack produced.
    fn finish(&self, out: Outcome) {
        for env in out.deliver {
            self.deliver(env);
        }
        for env in out.send {
            if let Err(e) = self.send_remote(env) {
                tracing::warn!(error = %e, "layer-originated frame not sent");
            }
        }
    }

    /// Encodes an envelope for a remote receiver and hands it to the transport.
    fn send_remote(&self, env: Envelope) -> Result<(), BusError> {
        let Some(addr) = self.route(&env.header.receiver) else {
            lock(&self.stack).record(Reason::NoRoute);
            return Err(BusError::NoRoute { receiver: env.header.receiver });
        };
        let frame = self.config.codec.encode_to_vec(&env)?;
        self.transport
            .send(&addr, &frame)
            .map_err(|source| BusError::Transport { context: format!("sending to {addr}"), source })
    }

    fn deliver(&self, env: Envelope) {
        let local = self.local.read().unwrap_or_else(PoisonError::into_inner);
        let sent = match local.get(&env.header.receiver) {
            Some(tx) => tx.try_send(env).is_ok(),
            None => false,
        };
        drop(local);
        if !sent {
            lock(&self.stack).record(Reason::MailboxFull);
        }
    }

    fn pump(&self) {
        let mut deadline = lock(&self.stack).next_deadline();
        let mut frames = Vec::new();
        while !self.stop.load(Ordering::Acquire) {
            let now = self.clock.now();
            let mut wait = self.config.tick;
            if let Some(deadline) = deadline
                && !self.clock.is_mock()
            {
                wait = wait.min(deadline.since(now));
            }
            let mut failed = None;
            match self.transport.recv_timeout(wait) {
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
            let decoded: Vec<_> = frames.drain(..).map(|(from, frame)| (from, self.config.codec.decode_datagram(&frame))).collect();
            // One lock for the whole batch and what the layers originate in answer.
            let mut out = Outcome::default();
            {
                let mut stack = lock(&self.stack);
                for (from, env) in decoded {
                    match env {
                        Ok(env) => {
                            let now = self.clock.now();
                            if let Verdict::Pass(env) = stack.inbound(env, now) {
                                out.deliver.push(env);
                            }
                        }
                        Err(e) => {
                            tracing::debug!(%from, error = %e, "undecodable frame");
                            stack.record(Reason::BadFrame);
                        }
                    }
                }
                self.collect_locked(&mut stack, &mut out);
                deadline = stack.next_deadline();
            }
            self.finish(out);
            if let Some(e) = failed {
                tracing::warn!(error = %e, "transport receive failed; pump stops");
                return;
            }
        }
    }
}

/// Frames the pump takes in one go before it runs them through the stack.
const MAX_BATCH: usize = 64;

/// What one locked pass through the stack produced: envelopes for local mailboxes, and
/// envelopes for the transport.
#[derive(Default)]
struct Outcome {
    deliver: Vec<Envelope>,
    send: Vec<Envelope>,
}

