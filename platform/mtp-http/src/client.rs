//! The sending side: posts one message to a foreign platform's address, over plain TCP or TLS,
//! reusing a kept-alive connection when the platform allows it.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use iw_acl::codec::{PrintOptions, print_with};
use iw_acl::{AclMessage, AgentId, FipaDateTime};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_rustls::TlsConnector;
use tokio_rustls::rustls::ClientConfig;
use tokio_rustls::rustls::pki_types::ServerName;

use crate::Error;
use crate::envelope::Envelope;
use crate::tls::BoxedIo;
use crate::wire::{self, Url};

/// Longest wait for a connection, a TLS handshake or the platform's answer.
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(30);

/// Idle connections kept per platform address.
const IDLE_PER_PEER: usize = 4;

/// Posts messages over HTTP/1.1. Clones share the pool of idle kept-alive connections.
#[derive(Clone, Default)]
pub struct MtpClient {
    tls: Option<Arc<ClientConfig>>,
    idle: Arc<Mutex<HashMap<String, Vec<BoxedIo>>>>,
}

impl std::fmt::Debug for MtpClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MtpClient")
            .field("tls", &self.tls.is_some())
            .finish_non_exhaustive()
    }
}

impl MtpClient {
    /// A client for `http://` addresses.
    pub fn new() -> Self {
        Self::default()
    }

    /// A client that also reaches `https://` addresses, trusting what `tls` trusts
    /// (see [`crate::tls::client_config`]).
    pub fn with_tls(tls: Arc<ClientConfig>) -> Self {
        Self {
            tls: Some(tls),
            ..Self::default()
        }
    }

    /// The exact bytes of a POST of `message` to `url` for the receivers `to`.
    pub fn encode(url: &str, message: &AclMessage, to: Vec<AgentId>) -> Result<Vec<u8>, Error> {
        let url = Url::parse(url)?;
        let payload = print_with(message, &PrintOptions::jade())?;
        let from = message.sender.clone().unwrap_or_default();
        let envelope = Envelope::for_payload(
            from,
            to,
            &payload,
            FipaDateTime::from_unix_ms(now_unix_ms()),
        );
        let boundary = format!("{:031x}", rand::random::<u128>() >> 4);
        Ok(wire::encode_request(
            &url,
            &envelope.to_xml(),
            &payload,
            &boundary,
            false,
        ))
    }

    /// Sends `message` to the receivers `to` at `url`; Ok once the platform answered 200.
    pub async fn send(
        &self,
        url: &str,
        message: &AclMessage,
        to: Vec<AgentId>,
    ) -> Result<(), Error> {
        let bytes = Self::encode(url, message, to)?;
        let target = Url::parse(url)?;
        let key = target.to_string();
        // A kept-alive connection may have been closed by the platform meanwhile: then the
        // post is retried once on a fresh connection.
        let mut pooled = self.take_idle(&key);
        loop {
            let reused = pooled.is_some();
            let mut stream = match pooled.take() {
                Some(stream) => stream,
                None => self.connect(&target).await?,
            };
            match exchange(&mut stream, &bytes, url).await {
                Ok(head) => {
                    if !head.close {
                        self.put_idle(key, stream);
                    }
                    return match head.status {
                        200 => Ok(()),
                        status => Err(Error::Rejected {
                            url: url.to_owned(),
                            status,
                        }),
                    };
                }
                Err(e) if reused => {
                    tracing::debug!(%url, error = %e, "kept-alive connection was closed; reconnecting")
                }
                Err(e) => return Err(e),
            }
        }
    }

    async fn connect(&self, target: &Url) -> Result<BoxedIo, Error> {
        let peer = target.authority();
        let io = |source| Error::Io {
            peer: peer.clone(),
            source,
        };
        let connect = TcpStream::connect((target.host.as_str(), target.port));
        let tcp = tokio::time::timeout(ANSWER_TIMEOUT, connect)
            .await
            .map_err(|_| timeout(&peer))?
            .map_err(io)?;
        tcp.set_nodelay(true).map_err(io)?;
        if !target.secure {
            return Ok(Box::new(tcp));
        }
        let config = self.tls.clone().ok_or_else(|| Error::Address {
            address: target.to_string(),
            reason: "https:// needs a client with trusted roots (MtpClient::with_tls)".into(),
        })?;
        let name =
            ServerName::try_from(target.host.clone()).map_err(|source| Error::ServerName {
                address: target.to_string(),
                source,
            })?;
        let handshake = TlsConnector::from(config).connect(name, tcp);
        let tls = tokio::time::timeout(ANSWER_TIMEOUT, handshake)
            .await
            .map_err(|_| timeout(&peer))?
            .map_err(|source| Error::Handshake {
                peer: peer.to_string(),
                source,
            })?;
        Ok(Box::new(tls))
    }

    fn take_idle(&self, key: &str) -> Option<BoxedIo> {
        self.idle
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get_mut(key)
            .and_then(Vec::pop)
    }

    fn put_idle(&self, key: String, stream: BoxedIo) {
        let mut idle = self.idle.lock().unwrap_or_else(PoisonError::into_inner);
        let streams = idle.entry(key).or_default();
        if streams.len() < IDLE_PER_PEER {
            streams.push(stream);
        }
    }
}

fn timeout(peer: &str) -> Error {
    Error::Timeout {
        peer: peer.to_owned(),
        seconds: ANSWER_TIMEOUT.as_secs(),
    }
}

/// Writes one request and reads the answer's head (and its body, so the connection can be
/// reused).
async fn exchange(
    stream: &mut BoxedIo,
    request: &[u8],
    url: &str,
) -> Result<wire::ResponseHead, Error> {
    let io = |source| Error::Io {
        peer: url.to_owned(),
        source,
    };
    stream.write_all(request).await.map_err(io)?;
    stream.flush().await.map_err(io)?;
    let mut buf = Vec::with_capacity(256);
    let mut chunk = [0u8; 1024];
    let read = async {
        let head_end = loop {
            if let Some(i) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
                break i + 4;
            }
            if buf.len() > wire::MAX_HEAD_LEN {
                return Err(Error::TooLarge {
                    what: "response head",
                    len: buf.len(),
                    max: wire::MAX_HEAD_LEN,
                });
            }
            let n = stream.read(&mut chunk).await.map_err(io)?;
            if n == 0 {
                return Err(Error::Http {
                    reason: format!("{url} closed the connection without an answer"),
                });
            }
            buf.extend_from_slice(&chunk[..n]);
        };
        let head = wire::parse_response_head(&buf[..head_end])?;
        if !head.close {
            let body = head.content_length.unwrap_or(0);
            while buf.len() < head_end + body {
                let n = stream.read(&mut chunk).await.map_err(io)?;
                if n == 0 {
                    return Ok(wire::ResponseHead {
                        close: true,
                        ..head
                    });
                }
                buf.extend_from_slice(&chunk[..n]);
            }
        }
        Ok(head)
    };
    tokio::time::timeout(ANSWER_TIMEOUT, read)
        .await
        .map_err(|_| timeout(url))?
}

/// Wall-clock time for envelope dates (a stamp for the receiver, not used in any decision).
fn now_unix_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}
