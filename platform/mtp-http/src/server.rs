//! The receiving side: an HTTP/1.1 server on tokio that accepts FIPA MTP posts.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

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

/// Longest a connection may stay silent (in a handshake, a request, or between kept-alive
/// requests) before the server closes it, so idle or stalled peers cannot pile up.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(30);

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
    /// TLS configuration (see [`crate::tls::server_config`]).
    pub async fn bind(
        addr: SocketAddr,
        tls: Option<Arc<ServerConfig>>,
        sink: mpsc::Sender<Delivery>,
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
        let task = tokio::spawn(async move {
            loop {
                match listener.accept().await {
                    Ok((stream, peer)) => {
                        let sink = sink.clone();
                        let acceptor = acceptor.clone();
                        tokio::spawn(async move {
                            let _ = stream.set_nodelay(true);
                            let served = match acceptor {
                                None => serve_connection(Box::new(stream), &peer, &sink).await,
                                Some(acceptor) => match tokio::time::timeout(
                                    IDLE_TIMEOUT,
                                    acceptor.accept(stream),
                                )
                                .await
                                {
                                    Ok(Ok(tls)) => {
                                        serve_connection(Box::new(tls), &peer, &sink).await
                                    }
                                    Ok(Err(source)) => Err(Error::Handshake {
                                        peer: peer.to_string(),
                                        source,
                                    }),
                                    Err(_) => Err(Error::Timeout {
                                        peer: peer.to_string(),
                                        seconds: IDLE_TIMEOUT.as_secs(),
                                    }),
                                },
                            };
                            if let Err(e) = served {
                                tracing::warn!(%peer, error = %e, "HTTP MTP connection closed");
                            }
                        });
                    }
                    Err(e) => tracing::warn!(error = %e, "HTTP MTP accept failed"),
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

/// Serves requests on one connection until the peer closes, asks to, or stays silent too long.
async fn serve_connection(
    mut stream: BoxedIo,
    peer: &SocketAddr,
    sink: &mpsc::Sender<Delivery>,
) -> Result<(), Error> {
    let io = |source| Error::Io {
        peer: peer.to_string(),
        source,
    };
    let mut buf = Vec::with_capacity(4096);
    loop {
        let head_end = loop {
            match wire::find_head_end(&buf) {
                Ok(Some(end)) => break end,
                Ok(None) => {}
                Err(e) => return reject(&mut stream, e).await,
            }
            if read_more(&mut stream, &mut buf, peer).await.map_err(io)? == 0 {
                return Ok(());
            }
        };
        let head = match wire::parse_request_head(&buf[..head_end]) {
            Ok(head) => head,
            Err(e) => return reject(&mut stream, e).await,
        };
        while buf.len() < head_end + head.content_length {
            if read_more(&mut stream, &mut buf, peer).await.map_err(io)? == 0 {
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

/// Reads what the peer sent next; a silence longer than [`IDLE_TIMEOUT`] is a timeout error.
async fn read_more(
    stream: &mut BoxedIo,
    buf: &mut Vec<u8>,
    peer: &SocketAddr,
) -> std::io::Result<usize> {
    let mut chunk = [0u8; 8192];
    let n = tokio::time::timeout(IDLE_TIMEOUT, stream.read(&mut chunk))
        .await
        .map_err(|_| {
            std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("{peer} silent for {} s", IDLE_TIMEOUT.as_secs()),
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
