//! The receiving side: an HTTP/1.1 server on tokio that accepts FIPA MTP posts.

use std::net::{IpAddr, SocketAddr};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use iw_acl::AclMessage;
use iw_acl::codec::{ParseOptions, parse_with};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio_rustls::TlsAcceptor;
use tokio_rustls::rustls::ServerConfig;

use crate::envelope::Envelope;
use crate::tls::BoxedIo;
use crate::{Error, wire};

/// The loopback address to bind to unless configured otherwise (port chosen by the OS).
pub const LOOPBACK: SocketAddr =
    SocketAddr::new(std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST), 0);

/// What peers may hold of the server. Without them a flood of connections, or a peer trickling
/// a request a byte at a time (each byte restarting a silence timer), holds descriptors and up to
/// [`wire::MAX_BODY_LEN`] of memory per connection without bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServerLimits {
    /// Connections served at once; more are closed at accept.
    pub max_connections: usize,
    /// Connections one source address may hold at once, so one peer cannot take every slot.
    pub max_per_source: usize,
    /// Longest a TLS handshake, or one request (head and body, counted from when the server
    /// starts waiting for it, so also the longest a kept-alive connection idles), may take.
    pub request_timeout: Duration,
}

impl Default for ServerLimits {
    fn default() -> Self {
        Self {
            max_connections: 256,
            max_per_source: 32,
            request_timeout: Duration::from_secs(30),
        }
    }
}

/// One message received: its transport envelope and the parsed ACL payload.
#[derive(Clone, Debug)]
pub struct Delivery {
    /// The envelope (receivers, sender, date).
    pub envelope: Envelope,
    /// The ACL message.
    pub message: AclMessage,
}

/// A running server; dropping it stops accepting connections.
#[derive(Debug)]
pub struct MtpServer {
    local_addr: SocketAddr,
    secure: bool,
    task: JoinHandle<()>,
}

impl MtpServer {
    /// Binds `addr` and hands every accepted message to `sink`; serves `https://` when given a
    /// TLS configuration (see [`crate::tls::server_config`]). Under the default [`ServerLimits`].
    pub async fn bind(
        addr: SocketAddr,
        tls: Option<Arc<ServerConfig>>,
        sink: mpsc::Sender<Delivery>,
    ) -> Result<Self, Error> {
        Self::bind_with_limits(addr, tls, sink, ServerLimits::default()).await
    }

    /// [`MtpServer::bind`] under `limits`.
    pub async fn bind_with_limits(
        addr: SocketAddr,
        tls: Option<Arc<ServerConfig>>,
        sink: mpsc::Sender<Delivery>,
        limits: ServerLimits,
    ) -> Result<Self, Error> {
        let listener = TcpListener::bind(addr).await.map_err(|source| Error::Io {
            peer: addr.to_string(),
            source,
        })?;
        let local_addr = listener.local_addr().map_err(|source| Error::Io {
            peer: addr.to_string(),
            source,
        })?;
        let secure = tls.is_some();
        let acceptor = tls.map(TlsAcceptor::from);
        let slots = Arc::new(Slots::new(limits));
        let task = tokio::spawn(async move {
            loop {
                match listener.accept().await {
                    Ok((stream, peer)) => {
                        let slot = match slots.take(peer.ip()) {
                            Ok(slot) => slot,
                            Err(why) => {
                                slots.warn(why, &peer, &"connection closed at accept");
                                continue;
                            }
                        };
                        let sink = sink.clone();
                        let acceptor = acceptor.clone();
                        tokio::spawn(async move {
                            let _ = stream.set_nodelay(true);
                            let timeout = limits.request_timeout;
                            let served = match acceptor {
                                None => {
                                    serve_connection(Box::new(stream), &peer, &sink, timeout).await
                                }
                                Some(acceptor) => {
                                    match tokio::time::timeout(timeout, acceptor.accept(stream))
                                        .await
                                    {
                                        Ok(Ok(tls)) => {
                                            serve_connection(Box::new(tls), &peer, &sink, timeout)
                                                .await
                                        }
                                        Ok(Err(source)) => Err(Error::Handshake {
                                            peer: peer.to_string(),
                                            source,
                                        }),
                                        Err(_) => Err(Error::Timeout {
                                            peer: peer.to_string(),
                                            seconds: timeout.as_secs(),
                                        }),
                                    }
                                }
                            };
                            if let Err(e) = served {
                                slot.slots.warn("connection closed on an error", &peer, &e);
                            }
                            drop(slot);
                        });
                    }
                    Err(e) => {
                        // Out of descriptors (EMFILE): back off instead of spinning.
                        tracing::warn!(error = %e, "HTTP MTP accept failed");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                    }
                }
            }
        });
        Ok(Self {
            local_addr,
            secure,
            task,
        })
    }

    /// The bound socket address.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The FIPA transport address of this server (`http://ip:port/acc`, or `https://`).
    pub fn url(&self) -> String {
        let scheme = if self.secure { "https" } else { "http" };
        format!("{scheme}://{}/acc", self.local_addr)
    }
}

impl Drop for MtpServer {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Connections held, in total and per source, under [`ServerLimits`]; and the rate-limited
/// warnings about refused and failed ones (one per kind per 10 s, with the count held back).
struct Slots {
    held: Arc<iw_bus::ConnectionSlots>,
    warnings: Mutex<iw_bus::WarnEvery<&'static str>>,
    started: Instant,
}

/// One connection's hold on [`Slots`], given back when dropped.
struct Slot {
    slots: Arc<Slots>,
    _held: iw_bus::ConnectionSlot,
}

impl Slots {
    fn new(limits: ServerLimits) -> Self {
        Self {
            held: iw_bus::ConnectionSlots::new(limits.max_connections, limits.max_per_source),
            warnings: Mutex::new(iw_bus::WarnEvery::new(Duration::from_secs(10))),
            started: Instant::now(),
        }
    }

    /// A slot for a connection from `source`, or why there is none.
    fn take(self: &Arc<Self>, source: IpAddr) -> Result<Slot, &'static str> {
        Ok(Slot {
            slots: Arc::clone(self),
            _held: self.held.take(source)?,
        })
    }

    fn warn(&self, kind: &'static str, peer: &SocketAddr, error: &dyn std::fmt::Display) {
        let now = iw_bus::Time::from_ns(iw_bus::duration_ns(self.started.elapsed()));
        let admitted = self
            .warnings
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .admit(kind, now);
        if let Some(held_back) = admitted {
            tracing::warn!(%peer, %error, held_back, "HTTP MTP: {kind}");
        }
    }
}

/// Serves requests on one connection until the peer closes, asks to, or takes longer than
/// `timeout` to send a whole request.
async fn serve_connection(
    mut stream: BoxedIo,
    peer: &SocketAddr,
    sink: &mpsc::Sender<Delivery>,
    timeout: Duration,
) -> Result<(), Error> {
    let io = |source| Error::Io {
        peer: peer.to_string(),
        source,
    };
    let mut buf = Vec::with_capacity(4096);
    loop {
        let by = (tokio::time::Instant::now() + timeout, timeout);
        let head_end = loop {
            match wire::find_head_end(&buf) {
                Ok(Some(end)) => break end,
                Ok(None) => {}
                Err(e) => return reject(&mut stream, e).await,
            }
            if read_more(&mut stream, &mut buf, peer, by)
                .await
                .map_err(io)?
                == 0
            {
                return Ok(());
            }
        };
        let head = match wire::parse_request_head(&buf[..head_end]) {
            Ok(head) => head,
            Err(e) => return reject(&mut stream, e).await,
        };
        while buf.len() < head_end + head.content_length {
            if read_more(&mut stream, &mut buf, peer, by)
                .await
                .map_err(io)?
                == 0
            {
                return Err(Error::Http {
                    reason: format!(
                        "body ends after {} of {} bytes",
                        buf.len() - head_end,
                        head.content_length
                    ),
                });
            }
        }
        let body: Vec<u8> = buf
            .drain(..head_end + head.content_length)
            .skip(head_end)
            .collect();
        let delivery = match decode(&head, &body) {
            Ok(d) => d,
            Err(e) => return reject(&mut stream, e).await,
        };
        stream
            .write_all(&wire::encode_response(200, "OK", head.close))
            .await
            .map_err(io)?;
        stream.flush().await.map_err(io)?;
        if sink.send(delivery).await.is_err() {
            return Ok(());
        }
        if head.close {
            return Ok(());
        }
    }
}

/// Reads what the peer sent next; the request not being whole by `by` (its deadline and the
/// timeout it came from) is a timeout error.
async fn read_more(
    stream: &mut BoxedIo,
    buf: &mut Vec<u8>,
    peer: &SocketAddr,
    (deadline, timeout): (tokio::time::Instant, Duration),
) -> std::io::Result<usize> {
    let mut chunk = [0u8; 8192];
    let n = tokio::time::timeout_at(deadline, stream.read(&mut chunk))
        .await
        .map_err(|_| {
            std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!(
                    "{peer} sent no whole request within {:.1} s",
                    timeout.as_secs_f64()
                ),
            )
        })??;
    buf.extend_from_slice(&chunk[..n]);
    Ok(n)
}

/// Answers 400, closes, and returns the reason so the caller logs it.
async fn reject(stream: &mut BoxedIo, error: Error) -> Result<(), Error> {
    let _ = stream
        .write_all(&wire::encode_response(400, "Bad Request", true))
        .await;
    let _ = stream.flush().await;
    Err(error)
}

/// Decodes one POST body into envelope and message.
pub fn decode(head: &wire::RequestHead, body: &[u8]) -> Result<Delivery, Error> {
    if head.method != "POST" {
        return Err(Error::Http {
            reason: format!("method {:?}; the MTP takes POST", head.method),
        });
    }
    let content_type = head.content_type.as_deref().ok_or_else(|| Error::Http {
        reason: "no Content-Type".into(),
    })?;
    let boundary = wire::boundary_of(content_type)?;
    let (envelope_bytes, payload) = wire::split_multipart(body, boundary)?;
    let envelope_text = std::str::from_utf8(envelope_bytes).map_err(|source| Error::Utf8 {
        what: "envelope",
        source,
    })?;
    let envelope = Envelope::from_xml(envelope_text)?;
    if let Some(rep) = envelope.acl_representation.as_deref()
        && rep != crate::envelope::ACL_REP_STRING
    {
        return Err(Error::Envelope {
            reason: format!("acl-representation {rep:?} unsupported"),
        });
    }
    if let Some(len) = envelope.payload_length
        && len != payload.len()
    {
        tracing::warn!(
            declared = len,
            actual = payload.len(),
            "payload-length differs from the payload"
        );
    }
    let payload = std::str::from_utf8(payload).map_err(|source| Error::Utf8 {
        what: "ACL payload",
        source,
    })?;
    let message = parse_with(payload, &ParseOptions::jade())?;
    Ok(Delivery { envelope, message })
}
