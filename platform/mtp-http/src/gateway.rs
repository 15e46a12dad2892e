//! The platform side of the transport (the Agent Communication Channel): messages arriving over
//! HTTP are delivered to local agents on the platform's [`Bus`] by agent identifier, and what
//! local agents send to foreign agents is posted to those agents' addresses.
//!
//! Each foreign agent the gateway knows is a proxy mailbox on the bus under the agent's full
//! name: local agents simply send to `wheelchair1@RustPlatform`, and the proxy's task posts
//! what arrives there, adding this platform's address to the sender so replies find their way
//! back. A message for a receiver this platform does not host gets the AMS's FAILURE with an
//! `MTS-error`, as JADE's AMS answers.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, PoisonError, Weak};

use iw_acl::{AclMessage, AgentId};
use iw_bus::{Bus, BusError, Mailbox};
use tokio::sync::mpsc;
use tokio_rustls::rustls::ServerConfig;

use crate::server::{Delivery, LOOPBACK, MtpServer};
use crate::{Error, MtpClient};

/// Messages received but not yet delivered before the server waits.
const INBOUND_QUEUE: usize = 256;

/// Default most foreign agents with a proxy at once.
pub const DEFAULT_MAX_FOREIGN: usize = 1024;

/// Called with a foreign agent's name when it gets a proxy, so the platform can admit it to its
/// agent registry (the parser layer lets through only registered senders).
pub type Admit = Arc<dyn Fn(&str) + Send + Sync>;

/// How a gateway runs.
#[derive(Clone)]
pub struct GatewayConfig {
    /// This platform's name (the part after `@` in its agents' names).
    pub platform: String,
    /// Where the server listens: loopback ([`LOOPBACK`]) unless the platform must be reachable
    /// from other hosts.
    pub bind: SocketAddr,
    /// Serve `https://` with this configuration ([`crate::tls::server_config`]).
    pub tls: Option<Arc<ServerConfig>>,
    /// The client posting to foreign platforms (give it roots to reach `https://` ones).
    pub client: MtpClient,
    /// Most foreign agents with a proxy; messages from further ones are refused.
    pub max_foreign: usize,
    /// Admits foreign agents to the platform's registry.
    pub admit: Option<Admit>,
}

impl std::fmt::Debug for GatewayConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GatewayConfig")
            .field("platform", &self.platform)
            .field("bind", &self.bind)
            .field("tls", &self.tls.is_some())
            .field("max_foreign", &self.max_foreign)
            .finish_non_exhaustive()
    }
}

impl GatewayConfig {
    /// Platform `platform` on loopback, plain HTTP, no admission hook.
    pub fn new(platform: impl Into<String>) -> Self {
        Self {
            platform: platform.into(),
            bind: LOOPBACK,
            tls: None,
            client: MtpClient::new(),
            max_foreign: DEFAULT_MAX_FOREIGN,
            admit: None,
        }
    }
}

/// A platform reachable over HTTP: the server, the bus it delivers on, the proxies of foreign
/// agents and the client.
pub struct Gateway {
    platform: String,
    server: MtpServer,
    bus: Arc<Bus>,
    client: MtpClient,
    foreign: Mutex<HashMap<String, AgentId>>,
    max_foreign: usize,
    admit: Option<Admit>,
}

impl std::fmt::Debug for Gateway {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gateway")
            .field("platform", &self.platform)
            .field("url", &self.url())
            .finish_non_exhaustive()
    }
}

impl Gateway {
    /// Starts the server of `config` delivering on `bus` (must run inside a tokio runtime).
    pub async fn start(config: GatewayConfig, bus: Arc<Bus>) -> Result<Arc<Self>, Error> {
        let (tx, mut rx) = mpsc::channel::<Delivery>(INBOUND_QUEUE);
        let server = MtpServer::bind(config.bind, config.tls, tx).await?;
        let gateway = Arc::new(Self {
            platform: config.platform,
            server,
            bus,
            client: config.client,
            foreign: Mutex::new(HashMap::new()),
            max_foreign: config.max_foreign,
            admit: config.admit,
        });
        let weak = Arc::downgrade(&gateway);
        tokio::spawn(async move {
            // One message at a time, so a conversation's messages keep their order.
            while let Some(delivery) = rx.recv().await {
                let Some(gateway) = weak.upgrade() else {
                    return;
                };
                gateway.dispatch(delivery).await;
            }
        });
        Ok(gateway)
    }

    /// This platform's transport address.
    pub fn url(&self) -> String {
        self.server.url()
    }

    /// This platform's name.
    pub fn platform(&self) -> &str {
        &self.platform
    }

    /// The full identifier of local agent `local_name` (`local_name@platform` with our address).
    pub fn aid(&self, local_name: &str) -> AgentId {
        AgentId::new(format!("{local_name}@{}", self.platform)).with_address(self.url())
    }

    /// Makes foreign agent `aid` reachable from the bus under its name (its addresses say where
    /// to post). Learning new addresses of a known agent replaces the old ones.
    pub fn add_foreign(self: &Arc<Self>, aid: &AgentId) -> Result<(), Error> {
        let mut foreign = self.foreign.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(known) = foreign.get_mut(&aid.name) {
            if !aid.addresses.is_empty() {
                known.addresses.clone_from(&aid.addresses);
            }
            return Ok(());
        }
        if foreign.len() >= self.max_foreign {
            return Err(Error::Unreachable {
                agent: aid.name.clone(),
                reason: format!(
                    "this platform already proxies its limit of {} foreign agents",
                    self.max_foreign
                ),
            });
        }
        let mailbox = self.bus.register(&aid.name).map_err(|e| match e {
            BusError::AgentExists { .. } => Error::Unreachable {
                agent: aid.name.clone(),
                reason: "the name is a local agent's; a foreign agent cannot take it".into(),
            },
            other => Error::Attach {
                agent: aid.name.clone(),
                what: "registering its proxy on the bus",
                source: Box::new(other),
            },
        })?;
        foreign.insert(aid.name.clone(), aid.clone());
        drop(foreign);
        if let Some(admit) = &self.admit {
            admit(&aid.name);
        }
        tokio::spawn(proxy(Arc::downgrade(self), aid.name.clone(), mailbox));
        Ok(())
    }

    /// Delivers a received message to each receiver on the bus; the AMS answers FAILURE for
    /// receivers this platform does not host.
    async fn dispatch(self: &Arc<Self>, delivery: Delivery) {
        let Delivery {
            envelope,
            mut message,
        } = delivery;
        let Some(sender) = message.sender.clone().or_else(|| envelope.from.clone()) else {
            tracing::warn!(envelope = ?envelope, "message without a sender dropped: no one to answer");
            return;
        };
        let mut sender = sender;
        if sender.addresses.is_empty()
            && let Some(from) = envelope.from.as_ref().filter(|f| f.name == sender.name)
        {
            sender.addresses.clone_from(&from.addresses);
        }
        message.sender = Some(sender.clone());
        if let Err(e) = self.add_foreign(&sender) {
            tracing::warn!(sender = %sender.name, error = %e, "message from a foreign agent refused");
            return;
        }
        let payload = iw_acl::codec::print(&message).into_bytes();
        for receiver in envelope.receivers() {
            let reason = match self.bus.send(&sender.name, &receiver.name, payload.clone()) {
                Ok(_) => continue,
                Err(BusError::NoRoute { .. }) => format!("Agent not found: {}", receiver.name),
                Err(e) => format!("Delivery failed: {e}"),
            };
            tracing::info!(receiver = %receiver.name, %reason, "undeliverable message");
            let failure = crate::delivery_failure(&message, receiver, self.aid("ams"), &reason);
            if let Err(e) = self.post(&failure, &sender).await {
                tracing::warn!(sender = %sender.name, error = %e, "could not report an undeliverable message");
            }
        }
    }

    /// Posts `message` to foreign agent `to`, trying its addresses in order (never our own).
    async fn post(&self, message: &AclMessage, to: &AgentId) -> Result<(), Error> {
        let own = self.url();
        let mut last = Error::Unreachable {
            agent: to.name.clone(),
            reason: "Foreign agent unreachable: no transport address".into(),
        };
        for url in to.addresses.iter().filter(|u| **u != own) {
            match self.client.send(url, message, vec![to.clone()]).await {
                Ok(()) => return Ok(()),
                Err(e) => last = e,
            }
        }
        Err(last)
    }

    /// Posts what a local agent sent to foreign agent `name`; tells the local sender (from the
    /// AMS) when that fails.
    async fn forward(&self, name: &str, mut message: AclMessage) {
        let Some(to) = self
            .foreign
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(name)
            .cloned()
        else {
            return;
        };
        let own = self.url();
        if let Some(sender) = message.sender.as_mut()
            && !sender.addresses.contains(&own)
        {
            sender.addresses.push(own);
        }
        if let Err(e) = self.post(&message, &to).await {
            tracing::warn!(receiver = %name, error = %e, "post to a foreign agent failed");
            let Some(sender) = message.sender.clone() else {
                return;
            };
            if self
                .foreign
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .contains_key(&sender.name)
            {
                return; // Relayed for another foreign agent: nobody local to tell.
            }
            let failure = crate::delivery_failure(
                &message,
                &to,
                self.aid("ams"),
                &format!("Foreign agent unreachable: {e}"),
            );
            let payload = iw_acl::codec::print(&failure).into_bytes();
            if let Err(e) = self
                .bus
                .send(&format!("ams@{}", self.platform), &sender.name, payload)
            {
                tracing::warn!(sender = %sender.name, error = %e, "could not report a failed post");
            }
        }
    }
}

impl Drop for Gateway {
    fn drop(&mut self) {
        // Ends the proxies' mailboxes, and so their tasks.
        for name in self
            .foreign
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner)
            .keys()
        {
            self.bus.deregister(name);
        }
    }
}

/// Posts, in order, what arrives in foreign agent `name`'s mailbox.
async fn proxy(gateway: Weak<Gateway>, name: String, mut mailbox: Mailbox) {
    while let Some(envelope) = mailbox.recv().await {
        let Some(gateway) = gateway.upgrade() else {
            return;
        };
        match envelope.payload_str().map(iw_acl::codec::parse) {
            Some(Ok(message)) => gateway.forward(&name, message).await,
            _ => {
                tracing::warn!(receiver = %name, "payload for a foreign agent is not ACL; dropped")
            }
        }
    }
}
