//! [`GuardedTransport`]: a frame transport whose frames pass through a layer [`Stack`], for
//! traffic that is not between agents (container control: join, heartbeat, election, GAL).

use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use iw_bus::transport::{FrameTransport, PeerAddr, TransportError};
use iw_bus::{
    Clock, Counters, Envelope, FrameCodec, IdGen, Layer, LayerKind, LayerSet, Stack, Verdict,
    WarnEvery,
};

use crate::{
    Directory, Identity, PreSharedKey, Registry, SecurityConfig, SecurityError, StackConfig, build,
};

/// The receiver name every guarded frame is addressed to (the group, not one member).
pub const GROUP: &str = "containers";

/// A [`FrameTransport`] whose frames are envelopes sealed by the security layer (AES-256-GCM under
/// a key the group shares) and stamped by the temporal layer (timestamp, sequence number).
///
/// What the peer gets from [`FrameTransport::recv_timeout`] is only what passed both layers: a
/// frame from anyone without the group key, altered, replayed or stale is dropped and counted
/// ([`GuardedTransport::counters`]), never handed up. Each member needs a name of its own (it
/// keys the sequence numbers), new at each start (e.g. with the incarnation in it).
pub struct GuardedTransport {
    inner: Arc<dyn FrameTransport>,
    name: String,
    clock: Clock,
    codec: FrameCodec,
    state: Mutex<(Stack, IdGen, WarnEvery<()>)>,
}

impl GuardedTransport {
    /// Guards `inner` with the group key `key`; this member speaks as `name`.
    pub fn new(
        inner: Arc<dyn FrameTransport>,
        name: &str,
        key: PreSharedKey,
        clock: Clock,
    ) -> Result<Self, SecurityError> {
        let mut config =
            StackConfig::with_layers(LayerSet::of(&[LayerKind::Temporal, LayerKind::Security]));
        config.security = SecurityConfig {
            group_key: Some(key),
            ..SecurityConfig::default()
        };
        // Pre-shared-key mode only: the identity is never used to agree keys or sign.
        let identity = Arc::new(Identity::generate()?);
        let stack = build(
            &config,
            identity,
            Arc::new(Directory::default()),
            Arc::new(Registry::default()),
        );
        let codec = FrameCodec::with_max_frame_len(inner.max_frame_len());
        Ok(Self {
            inner,
            name: name.to_string(),
            clock,
            codec,
            state: Mutex::new((stack, IdGen::new(), WarnEvery::new(iw_bus::WARN_PERIOD))),
        })
    }

    /// Frames refused so far, per reason.
    pub fn counters(&self) -> Counters {
        self.lock().0.counters().clone()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, (Stack, IdGen, WarnEvery<()>)> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl std::fmt::Debug for GuardedTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GuardedTransport")
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

impl FrameTransport for GuardedTransport {
    fn local_addr(&self) -> &PeerAddr {
        self.inner.local_addr()
    }

    fn max_frame_len(&self) -> usize {
        self.inner.max_frame_len()
    }

    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError> {
        let sealed = {
            let mut state = self.lock();
            let (stack, ids, _) = &mut *state;
            let mut env = Envelope::new(ids.next_id(), self.name.as_str(), GROUP, frame.to_vec());
            match stack.outbound(&mut env, self.clock.now()) {
                Verdict::Pass => env,
                // Nothing is held back in pre-shared-key mode; a refusal is a layer failure.
                Verdict::Drop(_) | Verdict::Consumed => {
                    return Err(TransportError::Refused {
                        context: format!("guarding a control frame for {to}"),
                    });
                }
            }
        };
        let bytes = self
            .codec
            .encode_to_vec(&sealed)
            .map_err(|e| TransportError::Middleware {
                context: format!("encoding a control frame for {to}"),
                source: Box::new(e),
            })?;
        self.inner.send(to, &bytes)
    }

    fn recv_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let Some((from, bytes)) = self.inner.recv_timeout(left)? else {
                return Ok(None);
            };
            let mut state = self.lock();
            match self.codec.decode_datagram(&bytes) {
                Ok(mut env) => match state.0.inbound(&mut env, self.clock.now()) {
                    Verdict::Pass => return Ok(Some((from, env.payload))),
                    Verdict::Drop(reason) => {
                        tracing::debug!(%from, %reason, "control frame refused")
                    }
                    Verdict::Consumed => {}
                },
                Err(e) => {
                    state.0.record(iw_bus::Reason::BadFrame);
                    match state.2.admit((), self.clock.now()) {
                        Some(held_back) => {
                            tracing::warn!(%from, error = %e, held_back, "control frame does not decode (one warning per 10 s)")
                        }
                        None => tracing::debug!(%from, error = %e, "control frame does not decode"),
                    }
                }
            }
            if left.is_zero() {
                return Ok(None);
            }
        }
    }
}
