//! TCP frame transport: length-prefixed frames (see [`crate::frame`]) over cached connections.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use iw_bus::ConnectionSlots;
use iw_bus::transport::{FrameTransport, PeerAddr, TransportError};

use crate::NetError;
use crate::frame::{FrameCodec, FrameKind, HEADER_LEN};
use crate::udp::resolve;

/// Default largest frame, bytes (1 MiB).
pub const TCP_DEFAULT_MAX_FRAME: usize = 1 << 20;
/// Frames received but not yet taken by `recv_timeout`; beyond it readers wait (TCP backpressure).
const INBOX_CAPACITY: usize = 1024;
/// How long a connection attempt may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);
/// Longest a hello frame (a listening address) may be, bytes.
const MAX_HELLO_LEN: usize = 256;

/// What inbound connections may hold; the defaults suit a deployment, tests shorten them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TcpLimits {
    /// Time an accepted connection has to send its hello: a connector sends it at once, so a
    /// silent or trickling peer is cut instead of holding a reader thread forever.
    pub hello_timeout: Duration,
    /// Longest silence after the hello (between frames or inside one) before the connection is
    /// cut and its slot freed. A sender reconnects instead of writing into a connection idle for
    /// half of this, so a quiet but live peer loses nothing to the cut.
    pub idle_timeout: Duration,
    /// Inbound connections read at once (one thread each); more are closed at accept, so a
    /// flood of connections cannot exhaust threads or descriptors.
    pub max_inbound: usize,
    /// Inbound connections one source address may hold at once, so one host cannot take every
    /// slot (the containers of one host each hold one connection to a peer).
    pub max_per_source: usize,
}

impl Default for TcpLimits {
    fn default() -> Self {
        Self {
            hello_timeout: Duration::from_secs(5),
            idle_timeout: Duration::from_secs(60),
            max_inbound: 256,
            max_per_source: 64,
        }
    }
}

type Inbound = (PeerAddr, Vec<u8>);

/// A TCP endpoint: a listener for inbound connections and a cache of outbound ones.
///
/// Each connection opens with a hello frame naming the sender's listening address, so a frame's
/// `from` is an address that can be replied to. A send on a broken cached connection reconnects
/// once and retries; a frame written into a connection the peer has just closed may still be lost
/// (the kernel accepts it before the reset arrives), which the communication layer repairs like a
/// lost datagram. Frames above the limit are refused on send and close the connection on receive.
#[derive(Debug)]
pub struct TcpTransport {
    local: PeerAddr,
    codec: FrameCodec,
    limits: TcpLimits,
    inbox: Mutex<Receiver<Inbound>>,
    /// Connections to peers and when each last carried a frame.
    outbound: Mutex<HashMap<PeerAddr, (TcpStream, Instant)>>,
    shared: Arc<Shared>,
    acceptor: Option<JoinHandle<()>>,
}

#[derive(Debug)]
struct Shared {
    stop: AtomicBool,
    /// Clones of accepted streams, shut down on drop so their reader threads end.
    accepted: Mutex<Vec<TcpStream>>,
    /// One per reader thread running, under [`TcpLimits`]' caps.
    slots: Arc<ConnectionSlots>,
}

impl TcpTransport {
    /// Listens on `addr` (`127.0.0.1:0` picks a free port) with a 1 MiB frame limit.
    pub fn bind(addr: &str) -> Result<Self, TransportError> {
        Self::bind_with_limit(addr, TCP_DEFAULT_MAX_FRAME)
    }

    /// Listens on `addr`, refusing frames longer than `max_frame_len` bytes.
    pub fn bind_with_limit(addr: &str, max_frame_len: usize) -> Result<Self, TransportError> {
        Self::bind_with_limits(addr, max_frame_len, TcpLimits::default())
    }

    /// Listens on `addr` under `limits`, refusing frames longer than `max_frame_len` bytes.
    pub fn bind_with_limits(
        addr: &str,
        max_frame_len: usize,
        limits: TcpLimits,
    ) -> Result<Self, TransportError> {
        let listener = TcpListener::bind(addr).map_err(|source| TransportError::Io {
            context: format!("listening on TCP `{addr}`"),
            source,
        })?;
        let bound = listener.local_addr().map_err(|source| TransportError::Io {
            context: "reading the TCP listening address".into(),
            source,
        })?;
        let codec = FrameCodec::new(max_frame_len);
        let (tx, rx) = std::sync::mpsc::sync_channel(INBOX_CAPACITY);
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            accepted: Mutex::new(Vec::new()),
            slots: ConnectionSlots::new(limits.max_inbound, limits.max_per_source),
        });
        let acceptor = {
            let shared = Arc::clone(&shared);
            std::thread::Builder::new()
                .name(format!("iw-tcp-accept-{bound}"))
                .spawn(move || accept_loop(listener, codec, limits, tx, shared))
                .map_err(|source| TransportError::Io {
                    context: "spawning the TCP accept thread".into(),
                    source,
                })?
        };
        Ok(Self {
            local: PeerAddr(bound.to_string()),
            codec,
            limits,
            inbox: Mutex::new(rx),
            outbound: Mutex::new(HashMap::new()),
            shared,
            acceptor: Some(acceptor),
        })
    }

    fn connect(&self, to: &PeerAddr) -> Result<TcpStream, TransportError> {
        let dest = resolve(to)?;
        let io = |context: &str| {
            let context = format!("{context} {to}");
            move |source| TransportError::Io { context, source }
        };
        let mut stream =
            TcpStream::connect_timeout(&dest, CONNECT_TIMEOUT).map_err(io("connecting to"))?;
        stream
            .set_nodelay(true)
            .map_err(io("disabling Nagle on the connection to"))?;
        let mut hello = Vec::new();
        self.codec
            .encode(FrameKind::Hello, self.local.0.as_bytes(), &mut hello)
            .map_err(|e| TransportError::Middleware {
                context: format!("encoding the hello of {}", self.local),
                source: Box::new(e),
            })?;
        stream.write_all(&hello).map_err(io("greeting"))?;
        Ok(stream)
    }
}

impl FrameTransport for TcpTransport {
    fn local_addr(&self) -> &PeerAddr {
        &self.local
    }

    fn max_frame_len(&self) -> usize {
        self.codec.max_frame_len()
    }

    fn send(&self, to: &PeerAddr, frame: &[u8]) -> Result<(), TransportError> {
        let mut bytes = Vec::new();
        self.codec
            .encode(FrameKind::Data, frame, &mut bytes)
            .map_err(|_| TransportError::FrameTooLarge {
                len: frame.len(),
                max: self.codec.max_frame_len(),
            })?;
        let mut cache = self.outbound.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((stream, used)) = cache.get_mut(to) {
            // Well before the peer's idle cut: a frame written as it closes could be lost.
            if used.elapsed() >= self.limits.idle_timeout / 2 {
                cache.remove(to);
            } else {
                match stream.write_all(&bytes) {
                    Ok(()) => {
                        *used = Instant::now();
                        return Ok(());
                    }
                    Err(e) => {
                        tracing::debug!(%to, error = %e, "cached TCP connection broken; reconnecting");
                        cache.remove(to);
                    }
                }
            }
        }
        let mut stream = self.connect(to)?;
        stream
            .write_all(&bytes)
            .map_err(|source| TransportError::Io {
                context: format!("sending a frame to {to}"),
                source,
            })?;
        cache.insert(to.clone(), (stream, Instant::now()));
        Ok(())
    }

    fn recv_timeout(
        &self,
        timeout: Duration,
    ) -> Result<Option<(PeerAddr, Vec<u8>)>, TransportError> {
        let inbox = self.inbox.lock().unwrap_or_else(PoisonError::into_inner);
        match inbox.recv_timeout(timeout) {
            Ok(got) => Ok(Some(got)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(TransportError::Closed),
        }
    }
}

impl Drop for TcpTransport {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        for stream in self
            .shared
            .accepted
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .drain(..)
        {
            let _ = stream.shutdown(Shutdown::Both);
        }
        for stream in self
            .outbound
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .values()
        {
            let _ = stream.0.shutdown(Shutdown::Both);
        }
        // Wake the blocking accept so the thread sees `stop`.
        if let Ok(addr) = self.local.0.parse::<SocketAddr>() {
            let _ = TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT);
        }
        if let Some(acceptor) = self.acceptor.take() {
            let _ = acceptor.join();
        }
    }
}

fn accept_loop(
    listener: TcpListener,
    codec: FrameCodec,
    limits: TcpLimits,
    tx: SyncSender<Inbound>,
    shared: Arc<Shared>,
) {
    for stream in listener.incoming() {
        if shared.stop.load(Ordering::Relaxed) {
            break;
        }
        let stream = match stream {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!(error = %e, "TCP accept failed");
                continue;
            }
        };
        let slot = match stream.peer_addr().map(|a| shared.slots.take(a.ip())) {
            Ok(Ok(slot)) => slot,
            Ok(Err(why)) => {
                tracing::debug!("TCP connection closed at accept: {why}");
                continue;
            }
            Err(e) => {
                tracing::debug!(error = %e, "TCP connection gone at accept");
                continue;
            }
        };
        let _ = stream.set_nodelay(true);
        match stream.try_clone() {
            Ok(clone) => {
                let mut accepted = shared
                    .accepted
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner);
                accepted.retain(|s| s.peer_addr().is_ok());
                accepted.push(clone);
            }
            Err(e) => tracing::warn!(error = %e, "cannot track an accepted TCP connection"),
        }
        let tx = tx.clone();
        let spawned = std::thread::Builder::new()
            .name("iw-tcp-read".into())
            .spawn(move || {
                let peer = stream
                    .peer_addr()
                    .map(|a| a.to_string())
                    .unwrap_or_default();
                // `accepted` holds a clone: only a shutdown closes the connection for the peer.
                let closer = stream.try_clone();
                if let Err(e) = read_connection(stream, codec, &limits, &tx) {
                    tracing::debug!(%peer, error = %e, "TCP connection closed");
                }
                if let Ok(closer) = closer {
                    let _ = closer.shutdown(Shutdown::Both);
                }
                drop(slot);
            });
        if let Err(e) = spawned {
            tracing::warn!(error = %e, "cannot spawn a TCP reader thread");
        }
    }
}

/// Reads frames until EOF, a corrupt frame or a silence past the limits; the first must be a
/// hello naming the sender.
fn read_connection(
    mut stream: TcpStream,
    codec: FrameCodec,
    limits: &TcpLimits,
    tx: &SyncSender<Inbound>,
) -> Result<(), NetError> {
    let mut from: Option<PeerAddr> = None;
    let mut header = [0u8; HEADER_LEN];
    // Until the hello is in; a read past the deadline fails (WouldBlock or TimedOut).
    stream
        .set_read_timeout(Some(limits.hello_timeout))
        .map_err(|source| NetError::Io {
            context: "setting the hello timeout".into(),
            source,
        })?;
    loop {
        match stream.read_exact(&mut header) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(source) => {
                let context = match source.kind() {
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => {
                        "silent past the hello or idle timeout; cut"
                    }
                    _ => "reading a frame header",
                };
                return Err(NetError::Io {
                    context: context.into(),
                    source,
                });
            }
        }
        let Some(h) = codec.decode_header(&header)? else {
            return Ok(());
        };
        if from.is_none() && h.len > MAX_HELLO_LEN {
            // Refused before its payload is allocated.
            return Err(NetError::BadHello {
                reason: format!(
                    "a {}-byte first frame (a hello is at most {MAX_HELLO_LEN})",
                    h.len
                ),
            });
        }
        let mut payload = vec![0u8; h.len];
        stream
            .read_exact(&mut payload)
            .map_err(|source| NetError::Io {
                context: format!("reading a {}-byte frame", h.len),
                source,
            })?;
        match (h.kind, &from) {
            (FrameKind::Hello, None) if h.len <= MAX_HELLO_LEN => {
                let addr = String::from_utf8(payload)
                    .map_err(|source| NetError::HelloNotUtf8 { source })?;
                from = Some(PeerAddr(addr));
                stream
                    .set_read_timeout(Some(limits.idle_timeout))
                    .map_err(|source| NetError::Io {
                        context: "setting the idle timeout".into(),
                        source,
                    })?;
            }
            (FrameKind::Hello, _) => {
                return Err(NetError::BadHello {
                    reason: "a second or oversized hello".into(),
                });
            }
            (FrameKind::Data, None) => {
                return Err(NetError::BadHello {
                    reason: "data before hello".into(),
                });
            }
            (FrameKind::Data, Some(peer)) => {
                let mut item = (peer.clone(), payload);
                loop {
                    match tx.try_send(item) {
                        Ok(()) => break,
                        Err(TrySendError::Full(back)) => {
                            item = back;
                            std::thread::sleep(Duration::from_micros(100));
                        }
                        Err(TrySendError::Disconnected(_)) => return Ok(()),
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WAIT: Duration = Duration::from_secs(5);

    #[test]
    fn frames_and_replies_use_listening_addresses() {
        let a = TcpTransport::bind("127.0.0.1:0").unwrap();
        let b = TcpTransport::bind("127.0.0.1:0").unwrap();
        for i in 0..100u32 {
            a.send(b.local_addr(), &i.to_be_bytes()).unwrap();
        }
        for i in 0..100u32 {
            let (from, frame) = b.recv_timeout(WAIT).unwrap().unwrap();
            assert_eq!(&from, a.local_addr());
            assert_eq!(frame, i.to_be_bytes());
        }
        b.send(a.local_addr(), b"reply").unwrap();
        assert_eq!(a.recv_timeout(WAIT).unwrap().unwrap().1, b"reply");
        assert!(a.recv_timeout(Duration::from_millis(5)).unwrap().is_none());
    }

    #[test]
    fn max_frame_length_is_enforced_both_ways() {
        let small = TcpTransport::bind_with_limit("127.0.0.1:0", 16).unwrap();
        let big = TcpTransport::bind("127.0.0.1:0").unwrap();
        assert!(matches!(
            small.send(big.local_addr(), &[0; 17]),
            Err(TransportError::FrameTooLarge { len: 17, max: 16 })
        ));
        // Oversized frame closes the connection at the receiver; nothing is delivered.
        big.send(small.local_addr(), &[0; 17]).unwrap();
        assert!(
            small
                .recv_timeout(Duration::from_millis(200))
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn garbage_on_a_connection_is_refused_without_delivering() {
        let t = TcpTransport::bind("127.0.0.1:0").unwrap();
        let mut raw = TcpStream::connect(t.local_addr().0.as_str()).unwrap();
        raw.write_all(b"GET / HTTP/1.1\r\n\r\n").unwrap();
        assert!(
            t.recv_timeout(Duration::from_millis(200))
                .unwrap()
                .is_none()
        );
    }

    /// Whether the transport closed `raw` within `within` (EOF or a reset).
    fn closed_within(raw: &mut TcpStream, within: Duration) -> bool {
        raw.set_read_timeout(Some(within)).unwrap();
        match raw.read(&mut [0u8; 16]) {
            Ok(n) => n == 0,
            Err(e) => !matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            ),
        }
    }

    /// A raw connection that has sent its hello, as a connector would.
    fn greeted(to: &str) -> TcpStream {
        let mut raw = TcpStream::connect(to).unwrap();
        let mut hello = Vec::new();
        FrameCodec::new(TCP_DEFAULT_MAX_FRAME)
            .encode(FrameKind::Hello, b"127.0.0.1:9", &mut hello)
            .unwrap();
        raw.write_all(&hello).unwrap();
        raw
    }

    /// Limits short enough for a test: 300 ms to the hello and of silence.
    fn short(max_inbound: usize, max_per_source: usize) -> TcpLimits {
        TcpLimits {
            hello_timeout: Duration::from_millis(300),
            idle_timeout: Duration::from_millis(300),
            max_inbound,
            max_per_source,
        }
    }

    fn bind_short(limits: TcpLimits) -> TcpTransport {
        TcpTransport::bind_with_limits("127.0.0.1:0", TCP_DEFAULT_MAX_FRAME, limits).unwrap()
    }

    /// Whether `t` receives `frame` from a fresh transport within a bounded number of tries.
    fn served(t: &TcpTransport, frame: &[u8]) -> bool {
        let a = TcpTransport::bind("127.0.0.1:0").unwrap();
        for _ in 0..100 {
            let _ = a.send(t.local_addr(), frame);
            if let Some(got) = t.recv_timeout(Duration::from_millis(100)).unwrap() {
                return got.1 == frame;
            }
        }
        false
    }

    #[test]
    fn a_connection_silent_before_its_hello_is_cut() {
        let t = bind_short(short(8, 8));
        let mut silent = TcpStream::connect(t.local_addr().0.as_str()).unwrap();
        assert!(
            closed_within(&mut silent, WAIT),
            "a peer that never sends its hello holds a reader thread"
        );
    }

    #[test]
    fn a_peer_silent_after_its_hello_is_cut_and_its_slot_served_to_another() {
        let t = bind_short(short(1, 1));
        let mut silent = greeted(&t.local_addr().0);
        assert!(
            closed_within(&mut silent, WAIT),
            "a peer that says hello and goes silent keeps its slot"
        );
        assert!(served(&t, b"in the freed slot"));
    }

    #[test]
    fn a_quiet_live_peer_loses_nothing_across_the_idle_cut() {
        let limits = short(8, 8);
        let a = bind_short(limits);
        let b = bind_short(limits);
        a.send(b.local_addr(), b"one").unwrap();
        assert_eq!(b.recv_timeout(WAIT).unwrap().unwrap().1, b"one");
        // b cuts a's quiet connection; a's next frame must not vanish into it.
        std::thread::sleep(limits.idle_timeout * 3);
        a.send(b.local_addr(), b"two").unwrap();
        assert_eq!(b.recv_timeout(WAIT).unwrap().unwrap().1, b"two");
    }

    #[test]
    fn a_flood_of_connections_is_capped_and_a_peer_is_served_once_it_ends() {
        let limits = TcpLimits {
            max_inbound: 16,
            max_per_source: 16,
            ..TcpLimits::default()
        };
        let t = bind_short(limits);
        let addr = t.local_addr().0.clone();
        let flood: Vec<TcpStream> = (0..limits.max_inbound).map(|_| greeted(&addr)).collect();
        let mut over = greeted(&addr);
        assert!(
            closed_within(&mut over, WAIT),
            "connection {} was accepted and read",
            limits.max_inbound + 1
        );
        drop(flood);
        assert!(served(&t, b"after the flood"));
    }

    /// A connection to `to` from local address `source` (another loopback address than
    /// 127.0.0.1: another host, as far as the listener can tell).
    fn connect_from(source: std::net::Ipv4Addr, to: SocketAddr) -> TcpStream {
        use std::os::fd::FromRawFd;
        let SocketAddr::V4(to) = to else {
            panic!("{to} is not IPv4")
        };
        let sockaddr = |ip: std::net::Ipv4Addr, port: u16| libc::sockaddr_in {
            sin_family: libc::AF_INET as libc::sa_family_t,
            sin_port: port.to_be(),
            sin_addr: libc::in_addr {
                s_addr: u32::from(ip).to_be(),
            },
            sin_zero: [0; 8],
        };
        let len = std::mem::size_of::<libc::sockaddr_in>() as libc::socklen_t;
        // SAFETY: a fresh socket owned by the returned stream; the addresses outlive the calls.
        unsafe {
            let fd = libc::socket(libc::AF_INET, libc::SOCK_STREAM | libc::SOCK_CLOEXEC, 0);
            assert!(fd >= 0, "socket: {}", std::io::Error::last_os_error());
            let stream = TcpStream::from_raw_fd(fd);
            let local = sockaddr(source, 0);
            let bound = libc::bind(fd, (&raw const local).cast(), len);
            assert_eq!(bound, 0, "bind: {}", std::io::Error::last_os_error());
            let remote = sockaddr(*to.ip(), to.port());
            let connected = libc::connect(fd, (&raw const remote).cast(), len);
            assert_eq!(connected, 0, "connect: {}", std::io::Error::last_os_error());
            stream
        }
    }

    #[test]
    fn one_source_cannot_take_every_slot() {
        let t = bind_short(TcpLimits {
            max_inbound: 16,
            max_per_source: 2,
            ..TcpLimits::default()
        });
        let addr = t.local_addr().0.clone();
        let _held: Vec<TcpStream> = (0..2).map(|_| greeted(&addr)).collect();
        let mut third = greeted(&addr);
        assert!(
            closed_within(&mut third, WAIT),
            "a third connection from one source was read"
        );
        // Another source is still served.
        let mut other = connect_from([127, 0, 0, 2].into(), addr.parse().unwrap());
        let codec = FrameCodec::new(TCP_DEFAULT_MAX_FRAME);
        let mut frames = Vec::new();
        codec
            .encode(FrameKind::Hello, b"127.0.0.2:9", &mut frames)
            .unwrap();
        codec
            .encode(FrameKind::Data, b"from elsewhere", &mut frames)
            .unwrap();
        other.write_all(&frames).unwrap();
        let (from, frame) = t.recv_timeout(WAIT).unwrap().unwrap();
        assert_eq!(
            (from.0.as_str(), &frame[..]),
            ("127.0.0.2:9", &b"from elsewhere"[..])
        );
    }

    #[test]
    fn a_restarted_peer_is_reached_again_after_reconnect() {
        let a = TcpTransport::bind("127.0.0.1:0").unwrap();
        let b = TcpTransport::bind("127.0.0.1:0").unwrap();
        let b_addr = b.local_addr().clone();
        a.send(&b_addr, b"one").unwrap();
        assert_eq!(b.recv_timeout(WAIT).unwrap().unwrap().1, b"one");
        drop(b);
        let b = TcpTransport::bind(&b_addr.0).unwrap();
        // The first writes may vanish into the dead connection; a bounded retry gets through.
        let mut got = None;
        for _ in 0..50 {
            let _ = a.send(&b_addr, b"two");
            if let Some(frame) = b.recv_timeout(Duration::from_millis(20)).unwrap() {
                got = Some(frame.1);
                break;
            }
        }
        assert_eq!(got.as_deref(), Some(&b"two"[..]));
    }
}
