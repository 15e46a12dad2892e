//! The lockstep transport: real bus frames between the containers of one process, released only
//! between agent steps so a simulated run is deterministic, with injectable link loss.

use std::collections::{BTreeSet, VecDeque};
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use iw_bus::transport::{FrameTransport, PeerAddr, TransportError};
use iw_bus::{FrameCodec, InProcNetwork, InProcTransport};

type Frame = (PeerAddr, Vec<u8>);

/// One frame that crossed between containers, for snapshots and reports.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Exchange {
    /// Sending agent.
    pub sender: String,
    /// Receiving agent.
    pub receiver: String,
    /// The ACL text.
    pub acl: String,
    /// Whether a link fault dropped it.
    pub dropped: bool,
}

#[derive(Default)]
struct State {
    /// Frames may be handed to the pumps.
    open: bool,
    /// Containers whose link is down (frames to or from them are dropped).
    down: BTreeSet<String>,
    /// Every frame offered to the network, in send order.
    exchanges: Vec<Exchange>,
}

struct Shared {
    state: Mutex<State>,
    /// Frames sent and not yet processed by the receiving pump.
    in_flight: AtomicI64,
}

fn lock(state: &Mutex<State>) -> MutexGuard<'_, State> {
    state.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The network all containers of a fleet share (cloning shares it).
#[derive(Clone)]
pub struct LockstepNetwork {
    inner: InProcNetwork,
    shared: Arc<Shared>,
}

impl Default for LockstepNetwork {
    fn default() -> Self {
        LockstepNetwork {
            inner: InProcNetwork::new(),
            shared: Arc::new(Shared {
                state: Mutex::new(State::default()),
                in_flight: AtomicI64::new(0),
            }),
        }
    }
}

impl LockstepNetwork {
    /// A new, closed network.
    pub fn new() -> Self {
        Self::default()
    }

    /// The endpoint of container `name`.
    pub fn endpoint(&self, name: &str) -> Result<LockstepTransport, TransportError> {
        Ok(LockstepTransport {
            inner: self.inner.endpoint(name)?,
            shared: self.shared.clone(),
            stash: Mutex::new(VecDeque::new()),
            handed: AtomicI64::new(0),
        })
    }

    /// Lets the pumps deliver every frame sent so far, waits until each is in its mailbox, and
    /// closes again. Frames sent by agents while closed wait for the next settle.
    pub fn settle(&self) {
        lock(&self.shared.state).open = true;
        // The pumps poll every bus tick; this waits for them, never for simulated time.
        while self.shared.in_flight.load(Ordering::Acquire) > 0 {
            std::thread::sleep(Duration::from_micros(50));
        }
        lock(&self.shared.state).open = false;
    }

    /// Takes container `name`'s link down (`false`) or up.
    pub fn set_link(&self, name: &str, up: bool) {
        let mut state = lock(&self.shared.state);
        if up {
            state.down.remove(name);
        } else {
            state.down.insert(name.to_string());
        }
    }

    /// Every frame offered so far, in order.
    pub fn exchanges(&self) -> Vec<Exchange> {
        lock(&self.shared.state).exchanges.clone()
    }

    /// The last `n` frames offered.
    pub fn recent(&self, n: usize) -> Vec<Exchange> {
        let state = lock(&self.shared.state);
        state.exchanges[state.exchanges.len().saturating_sub(n)..].to_vec()
    }
}

/// One container's endpoint on a [`LockstepNetwork`].
pub struct LockstepTransport {
    inner: InProcTransport,
    shared: Arc<Shared>,
    /// Frames that arrived while the network was closed.
    stash: Mutex<VecDeque<Frame>>,
    /// Frames handed to the pump and not yet known to be in their mailboxes. The pump asks with
    /// a zero timeout only while it gathers a batch, and delivers the batch before it waits for
    /// the next frame: an ask that may wait means every frame handed before is delivered.
    handed: AtomicI64,
}

impl LockstepTransport {
    fn hand_over(&self, frame: Frame) -> Option<Frame> {
        self.handed.fetch_add(1, Ordering::AcqRel);
        Some(frame)
    }
}

impl FrameTransport for LockstepTransport {
    fn local_addr(&self) -> &PeerAddr {
        self.inner.local_addr()
    }

    fn max_frame_len(&self) -> usize {
        self.inner.max_frame_len()
    }

    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError> {
        let mut state = lock(&self.shared.state);
        let from = &self.local_addr().0;
        let dropped = state.down.contains(from) || state.down.contains(&to.0);
        let (sender, receiver, acl) = match FrameCodec::new().decode_datagram(frame) {
            Ok(env) => (
                env.header.sender,
                env.header.receiver,
                String::from_utf8_lossy(&env.payload).into_owned(),
            ),
            Err(e) => (
                from.clone(),
                to.0.clone(),
                format!("<undecodable frame: {e}>"),
            ),
        };
        state.exchanges.push(Exchange {
            sender,
            receiver,
            acl,
            dropped,
        });
        if dropped {
            return Ok(()); // a lost link loses frames silently, as a radio does
        }
        self.shared.in_flight.fetch_add(1, Ordering::AcqRel);
        let sent = self.inner.send(to, frame);
        if sent.is_err() {
            self.shared.in_flight.fetch_sub(1, Ordering::AcqRel);
        }
        sent
    }

    fn recv_timeout(&self, timeout: Duration) -> Result<Option<Frame>, TransportError> {
        if !timeout.is_zero() {
            self.shared
                .in_flight
                .fetch_sub(self.handed.swap(0, Ordering::AcqRel), Ordering::AcqRel);
        }
        if lock(&self.shared.state).open {
            let stashed = self
                .stash
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .pop_front();
            if let Some(frame) = stashed {
                return Ok(self.hand_over(frame));
            }
        }
        let Some(frame) = self
            .inner
            .recv_timeout(timeout.min(Duration::from_millis(1)))?
        else {
            return Ok(None);
        };
        // Decide under the state lock, so a settle cannot close between the check and the hand-over.
        let state = lock(&self.shared.state);
        if state.open {
            drop(state);
            Ok(self.hand_over(frame))
        } else {
            self.stash
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .push_back(frame);
            Ok(None)
        }
    }
}
