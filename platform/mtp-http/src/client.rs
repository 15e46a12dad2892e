//! The sending side: posts one message to a foreign platform's address.

use std::time::{SystemTime, UNIX_EPOCH};

use iw_acl::codec::{PrintOptions, print_with};
use iw_acl::{AclMessage, AgentId, FipaDateTime};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::envelope::Envelope;
use crate::wire::{self, Url};
use crate::Error;

/// Posts messages over HTTP/1.1, one connection per message (as JADE's `Connection: close`).
#[derive(Clone, Debug, Default)]
pub struct MtpClient;

impl MtpClient {
    /// The exact bytes of a POST of `message` to `url` for the receivers `to`.
    pub fn encode(url: &str, message: &AclMessage, to: Vec<AgentId>) -> Result<Vec<u8>, Error> {
        let url = Url::parse(url)?;
        let payload = print_with(message, &PrintOptions::jade())?;
        let from = message.sender.clone().unwrap_or_default();
        let envelope = Envelope::for_payload(from, to, &payload, FipaDateTime::from_unix_ms(now_unix_ms()));
        let boundary = format!("{:031x}", rand::random::<u128>() >> 4);
        Ok(wire::encode_request(&url, &envelope.to_xml(), &payload, &boundary, true))
    }

    /// Sends `message` to the receivers `to` at `url`; Ok once the platform answered 200.
    pub async fn send(&self, url: &str, message: &AclMessage, to: Vec<AgentId>) -> Result<(), Error> {
        let bytes = Self::encode(url, message, to)?;
        let target = Url::parse(url)?;
        let io = |source| Error::Io { peer: url.to_owned(), source };
        let mut stream = TcpStream::connect((target.host.as_str(), target.port)).await.map_err(io)?;
        stream.set_nodelay(true).map_err(io)?;
        stream.write_all(&bytes).await.map_err(io)?;
        let mut head = Vec::with_capacity(256);
        let mut chunk = [0u8; 1024];
        loop {
            let n = stream.read(&mut chunk).await.map_err(io)?;
            if n == 0 {
                return Err(Error::Http { reason: format!("{url} closed the connection without an answer") });
            }
            head.extend_from_slice(&chunk[..n]);
            if head.windows(4).any(|w| w == b"\r\n\r\n") {
                break;
            }
            if head.len() > wire::MAX_HEAD_LEN {
                return Err(Error::TooLarge { what: "response head", len: head.len(), max: wire::MAX_HEAD_LEN });
            }
        }
        match wire::parse_status(&head)? {
            200 => Ok(()),
            status => Err(Error::Rejected { url: url.to_owned(), status }),
        }
    }
}

/// Wall-clock time for envelope dates (a stamp for the receiver, not used in any decision).
fn now_unix_ms() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_millis() as i64)
}
