//! Same-host frame transport over iceoryx2 shared memory (thesis 3.3.3: agents of different
//! processes on one wheelchair computer talk without the network stack).
//!
//! Organization:
//! - [`ShmTransport`]: one endpoint. Its address names an inbox, an iceoryx2 publish/subscribe
//!   service of byte slices (`[u8]`) that this endpoint subscribes to; sending to a peer publishes
//!   into the peer's inbox through a publisher opened once per peer and cached.
//! - [`PollPolicy`]: how a receive waits: poll, then `yield_now`, then short sleeps. Never a pure
//!   busy spin: measured on the reference machine (2 cores), busy polling collapses to an 8 ms
//!   p99 as soon as a third thread wants a core, whereas poll+yield keeps p50 near 3 us.
//! - [`ShmError`]: this crate's errors (address and frame-header problems).
//!
//! Each sample is `[sender address length: u8][sender address][frame]`, so a frame's `from` can be
//! replied to. Service names are `iw/frames/<address>`.
//!
//! Guarantees: frames arrive whole, in order per sender, or not at all (a full inbox overwrites
//! its oldest frame, like a lost datagram; the communication layer repairs it); a frame longer
//! than [`ShmTransport::max_frame_len`] is refused on send and dropped on receive; a malformed
//! sample cannot panic the receiver. iceoryx2 keeps state in `/dev/shm` and `/tmp/iceoryx2`:
//! it is removed when the last endpoint of a service is dropped, and endpoints created after a
//! crash clean up the dead nodes' leftovers. Use distinct addresses for concurrent tests.
#![warn(missing_docs)]

use std::collections::HashMap;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iw_bus::transport::{FrameTransport, PeerAddr, TransportError};

/// The iceoryx2 service flavour: ports usable from several threads, as `FrameTransport` requires.
type Svc = ipc_threadsafe::Service;

/// Default largest frame, bytes (64 KiB).
pub const SHM_DEFAULT_MAX_FRAME: usize = 64 * 1024;
/// Frames an inbox holds before the oldest is overwritten.
const INBOX_DEPTH: usize = 256;
/// Most endpoints that may publish into one inbox.
const MAX_SENDERS: usize = 64;
/// Slice length a publisher starts with; it grows (powers of two) for longer frames.
const INITIAL_SLICE_LEN: usize = 1024;
/// Prefix of every inbox service name.
const SERVICE_PREFIX: &str = "iw/frames/";

/// This crate's errors, with the offending input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ShmError {
    /// An address that cannot name an inbox.
    #[error("shared-memory address `{addr}` is unusable: {reason}")]
    BadAddress {
        /// The address as given.
        addr: String,
        /// Why.
        reason: String,
    },
    /// An address iceoryx2 refuses as a service name.
    #[error("shared-memory address `{addr}` is unusable: {source}")]
    ServiceName {
        /// The address as given.
        addr: String,
        /// What iceoryx2 said.
        #[source]
        source: iceoryx2::service::service_name::ServiceNameError,
    },
    /// A received sample whose sender header is cut short or not UTF-8.
    #[error("malformed sample of {len} bytes: {reason}")]
    MalformedSample {
        /// Sample length, bytes.
        len: usize,
        /// What was wrong.
        reason: &'static str,
    },
}

impl From<ShmError> for TransportError {
    fn from(e: ShmError) -> Self {
        match e {
            ShmError::BadAddress { addr, reason } => TransportError::BadAddress { addr, reason },
            other => TransportError::Middleware {
                context: "shared-memory transport".into(),
                source: Box::new(other),
            },
        }
    }
}

/// How [`ShmTransport::recv_timeout`] waits for a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PollPolicy {
    /// How long to poll with `yield_now` between checks before sleeping.
    pub yield_phase: Duration,
    /// Sleep between checks after the yield phase (at least 1 µs).
    pub sleep: Duration,
}

impl Default for PollPolicy {
    /// Yield for 2 ms (latency of a few µs while traffic flows), then check every 50 µs.
    fn default() -> Self {
        Self {
            yield_phase: Duration::from_millis(2),
            sleep: Duration::from_micros(50),
        }
    }
}

struct Outbox {
    publisher: Publisher<Svc, [u8], ()>,
    /// Header + frame assembled here, then copied once into the loaned sample.
    scratch: Vec<u8>,
}

/// A same-host endpoint over iceoryx2 publish/subscribe.
pub struct ShmTransport {
    node: Node<Svc>,
    local: PeerAddr,
    max_frame_len: usize,
    poll: PollPolicy,
    inbox: Subscriber<Svc, [u8], ()>,
    outboxes: Mutex<HashMap<PeerAddr, Outbox>>,
}

impl std::fmt::Debug for ShmTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShmTransport")
            .field("local", &self.local)
            .field("max_frame_len", &self.max_frame_len)
            .finish()
    }
}

fn middleware<E: std::error::Error + Send + Sync + 'static>(
    context: String,
) -> impl FnOnce(E) -> TransportError {
    move |e| TransportError::Middleware {
        context,
        source: Box::new(e),
    }
}

impl ShmTransport {
    /// Opens the endpoint `addr` (letters, digits, `-`, `_`, `.`, `/`; at most 200 bytes and
    /// unique among live endpoints) with the default frame limit and poll policy.
    pub fn open(addr: &str) -> Result<Self, TransportError> {
        Self::open_with(addr, SHM_DEFAULT_MAX_FRAME, PollPolicy::default())
    }

    /// Opens the endpoint `addr` with a frame limit and a poll policy.
    pub fn open_with(
        addr: &str,
        max_frame_len: usize,
        poll: PollPolicy,
    ) -> Result<Self, TransportError> {
        let service_name = inbox_service_name(addr)?;
        // An explicit default config: no search for a config file (and no warning when none exists).
        let node = NodeBuilder::new()
            .config(&Config::default())
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .map_err(middleware(format!(
                "creating the iceoryx2 node for `{addr}`"
            )))?;
        // Leftovers of crashed processes would otherwise block reopening their services.
        let _ = node.try_cleanup_dead_nodes();
        let service = open_inbox(&node, &service_name)?;
        let inbox = service
            .subscriber_builder()
            .create()
            .map_err(middleware(format!("subscribing to the inbox of `{addr}`")))?;
        Ok(Self {
            node,
            local: PeerAddr(addr.to_owned()),
            max_frame_len,
            poll,
            inbox,
            outboxes: Mutex::new(HashMap::new()),
        })
    }

    fn open_outbox(&self, to: &PeerAddr) -> Result<Outbox, TransportError> {
        let service_name = inbox_service_name(&to.0)?;
        let service = open_inbox(&self.node, &service_name)?;
        let publisher = service
            .publisher_builder()
            .initial_max_slice_len(INITIAL_SLICE_LEN)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(middleware(format!("publishing to `{to}`")))?;
        Ok(Outbox {
            publisher,
            scratch: Vec::with_capacity(INITIAL_SLICE_LEN),
        })
    }

    fn try_receive(&self) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError> {
        loop {
            let sample = self
                .inbox
                .receive()
                .map_err(middleware(format!("receiving on `{}`", self.local)))?;
            let Some(sample) = sample else {
                return Ok(None);
            };
            match split_sample(sample.payload(), self.max_frame_len) {
                Ok((from, frame)) => return Ok(Some((PeerAddr(from.to_owned()), frame.to_vec()))),
                Err(e) => {
                    tracing::warn!(endpoint = %self.local, error = %e, "dropping a malformed sample")
                }
            }
        }
    }
}

/// Splits a sample into sender address and frame.
fn split_sample(sample: &[u8], max_frame_len: usize) -> Result<(&str, &[u8]), ShmError> {
    let len = sample.len();
    let (&name_len, rest) = sample.split_first().ok_or(ShmError::MalformedSample {
        len,
        reason: "empty",
    })?;
    let name_len = usize::from(name_len);
    let name = rest.get(..name_len).ok_or(ShmError::MalformedSample {
        len,
        reason: "sender address cut short",
    })?;
    let frame = rest.get(name_len..).unwrap_or_default();
    if frame.len() > max_frame_len {
        return Err(ShmError::MalformedSample {
            len,
            reason: "frame above the limit",
        });
    }
    let name = std::str::from_utf8(name).map_err(|_| ShmError::MalformedSample {
        len,
        reason: "sender address not UTF-8",
    })?;
    Ok((name, frame))
}

fn inbox_service_name(addr: &str) -> Result<ServiceName, ShmError> {
    let bad = |reason: &str| ShmError::BadAddress {
        addr: addr.to_owned(),
        reason: reason.to_owned(),
    };
    if addr.is_empty() || addr.len() > 200 {
        return Err(bad("must be 1 to 200 bytes long"));
    }
    if !addr
        .bytes()
        .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.' | b'/'))
    {
        return Err(bad(
            "only letters, digits, `-`, `_`, `.` and `/` are allowed",
        ));
    }
    ServiceName::new(&format!("{SERVICE_PREFIX}{addr}")).map_err(|source| ShmError::ServiceName {
        addr: addr.to_owned(),
        source,
    })
}

fn open_inbox(
    node: &Node<Svc>,
    name: &ServiceName,
) -> Result<
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u8], ()>,
    TransportError,
> {
    node.service_builder(name)
        .publish_subscribe::<[u8]>()
        .subscriber_max_buffer_size(INBOX_DEPTH)
        .max_publishers(MAX_SENDERS)
        .max_subscribers(4)
        .history_size(0)
        .open_or_create()
        .map_err(middleware(format!("opening the iceoryx2 service `{name}`")))
}

impl FrameTransport for ShmTransport {
    fn local_addr(&self) -> &PeerAddr {
        &self.local
    }

    fn max_frame_len(&self) -> usize {
        self.max_frame_len
    }

    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError> {
        if frame.len() > self.max_frame_len {
            return Err(TransportError::FrameTooLarge {
                len: frame.len(),
                max: self.max_frame_len,
            });
        }
        let mut outboxes = self.outboxes.lock().unwrap_or_else(PoisonError::into_inner);
        if !outboxes.contains_key(to) {
            let outbox = self.open_outbox(to)?;
            outboxes.insert(to.clone(), outbox);
        }
        let Some(outbox) = outboxes.get_mut(to) else {
            return Err(TransportError::Closed);
        };
        let name = self.local.0.as_bytes();
        outbox.scratch.clear();
        // Address length is checked at open (at most 200 bytes), so it fits in one byte.
        outbox
            .scratch
            .push(u8::try_from(name.len()).unwrap_or(u8::MAX));
        outbox.scratch.extend_from_slice(name);
        outbox.scratch.extend_from_slice(frame);
        let sample = outbox
            .publisher
            .loan_slice_uninit(outbox.scratch.len())
            .map_err(middleware(format!(
                "loaning a {}-byte sample for `{to}`",
                frame.len()
            )))?;
        sample
            .write_from_slice(&outbox.scratch)
            .send()
            .map_err(middleware(format!("publishing to `{to}`")))?;
        Ok(())
    }

    fn recv_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError> {
        let start = Instant::now();
        let yield_phase = self.poll.yield_phase;
        let sleep = self.poll.sleep.max(Duration::from_micros(1));
        loop {
            if let Some(got) = self.try_receive()? {
                return Ok(Some(got));
            }
            let waited = start.elapsed();
            if waited >= timeout {
                return Ok(None);
            }
            if waited < yield_phase {
                std::thread::yield_now();
            } else {
                std::thread::sleep(sleep.min(timeout - waited));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn addresses_are_checked() {
        assert!(matches!(
            inbox_service_name(""),
            Err(ShmError::BadAddress { .. })
        ));
        assert!(
            matches!(inbox_service_name("a b"), Err(ShmError::BadAddress { ref addr, .. }) if addr == "a b")
        );
        assert!(inbox_service_name("test/x-1_y.z").is_ok());
    }

    #[test]
    fn sample_split_reports_malformed_input() {
        assert!(matches!(
            split_sample(&[], 10),
            Err(ShmError::MalformedSample {
                reason: "empty",
                ..
            })
        ));
        assert!(matches!(
            split_sample(&[5, b'a'], 10),
            Err(ShmError::MalformedSample {
                reason: "sender address cut short",
                ..
            })
        ));
        assert!(matches!(
            split_sample(&[1, 0xff], 10),
            Err(ShmError::MalformedSample {
                reason: "sender address not UTF-8",
                ..
            })
        ));
        assert!(matches!(
            split_sample(&[1, b'a', 1, 2, 3], 2),
            Err(ShmError::MalformedSample {
                reason: "frame above the limit",
                ..
            })
        ));
        assert_eq!(split_sample(&[1, b'a', 9], 10).unwrap(), ("a", &[9u8][..]));
    }

    proptest! {
        #[test]
        fn sample_split_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = split_sample(&bytes, 100);
        }
    }
}
