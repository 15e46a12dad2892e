//! The platform side of the transport: local agents by name, routing by receiver address, and
//! the AMS's FAILURE for receivers this platform does not host (as JADE's AMS answers).

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use iw_acl::{AclMessage, AgentId, Performative};
use tokio::sync::mpsc;

use crate::server::{Delivery, MtpServer};
use crate::{Error, MtpClient};

/// Messages queued per local agent before the server waits for it.
const AGENT_QUEUE: usize = 64;

/// A platform reachable over HTTP: owns the server, the local agents' inboxes and the client.
#[derive(Debug)]
pub struct Gateway {
    platform: String,
    server: MtpServer,
    agents: Mutex<HashMap<String, mpsc::Sender<AclMessage>>>,
    client: MtpClient,
}

impl Gateway {
    /// Starts platform `platform` listening on `bind` (use [`crate::server::LOOPBACK`] unless the
    /// platform must be reachable from other hosts).
    pub async fn start(platform: impl Into<String>, bind: SocketAddr) -> Result<Arc<Self>, Error> {
        let (tx, mut rx) = mpsc::channel::<Delivery>(AGENT_QUEUE);
        let server = MtpServer::bind(bind, tx).await?;
        let gateway = Arc::new(Self {
            platform: platform.into(),
            server,
            agents: Mutex::new(HashMap::new()),
            client: MtpClient,
        });
        let weak = Arc::downgrade(&gateway);
        tokio::spawn(async move {
            while let Some(delivery) = rx.recv().await {
                let Some(gateway) = weak.upgrade() else { return };
                gateway.dispatch(delivery).await;
            }
        });
        Ok(gateway)
    }

    /// This platform's transport address.
    pub fn url(&self) -> String {
        self.server.url()
    }

    /// The full identifier (`local@platform` with our address) of a local agent name.
    pub fn aid(&self, local_name: &str) -> AgentId {
        AgentId::new(format!("{local_name}@{}", self.platform)).with_address(self.url())
    }

    /// Hosts agent `local_name`; its messages arrive on the returned inbox.
    pub fn register(&self, local_name: &str) -> mpsc::Receiver<AclMessage> {
        let (tx, rx) = mpsc::channel(AGENT_QUEUE);
        self.lock().insert(format!("{local_name}@{}", self.platform), tx);
        rx
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, mpsc::Sender<AclMessage>>> {
        self.agents.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Sends `message`: local receivers get it directly, foreign ones by a POST to their first
    /// address. Returns the first failure after trying every receiver.
    pub async fn send(&self, message: AclMessage) -> Result<(), Error> {
        let mut result = Ok(());
        for receiver in &message.receivers {
            if let Err(e) = self.route(receiver, &message).await {
                tracing::warn!(receiver = %receiver, error = %e, "delivery failed");
                if result.is_ok() {
                    result = Err(e);
                }
            }
        }
        result
    }

    async fn route(&self, receiver: &AgentId, message: &AclMessage) -> Result<(), Error> {
        let local = self.lock().get(&receiver.name).cloned();
        if let Some(inbox) = local {
            return inbox
                .send(message.clone())
                .await
                .map_err(|_| Error::Unreachable { agent: receiver.name.clone(), reason: "agent stopped".into() });
        }
        let url = receiver.addresses.first().ok_or_else(|| Error::Unreachable {
            agent: receiver.name.clone(),
            reason: "Foreign agent unreachable: no transport address".into(),
        })?;
        self.client.send(url, message, vec![receiver.clone()]).await
    }

    /// Delivers a received message to its local receivers; the AMS answers FAILURE for others.
    async fn dispatch(&self, delivery: Delivery) {
        let receivers = delivery.envelope.receivers().to_vec();
        for receiver in receivers {
            let inbox = self.lock().get(&receiver.name).cloned();
            match inbox {
                Some(inbox) => {
                    let _ = inbox.send(delivery.message.clone()).await;
                }
                None => {
                    let failure = self.not_found(&delivery.message, &receiver);
                    if let Err(e) = self.send(failure).await {
                        tracing::warn!(receiver = %receiver, error = %e, "could not report unknown receiver");
                    }
                }
            }
        }
    }

    /// The AMS's FAILURE for a message to an agent this platform does not host, in JADE's words.
    fn not_found(&self, message: &AclMessage, receiver: &AgentId) -> AclMessage {
        let sender = message.sender.clone().unwrap_or_default();
        let content = format!(
            "((action {} (ACLMessage)) (MTS-error {} (internal-error \"Agent not found: {}\")))",
            sl_aid(&sender),
            sl_aid(receiver),
            receiver.name.replace('"', "\\\"")
        );
        message
            .create_reply()
            .with_performative(Performative::Failure)
            .with_sender(self.aid("ams"))
            .with_content(content)
            .with_language("fipa-sl")
    }
}

/// An agent identifier as an SL term (name and addresses).
fn sl_aid(aid: &AgentId) -> String {
    let mut out = format!("(agent-identifier :name {}", sl_word(&aid.name));
    if !aid.addresses.is_empty() {
        let urls: Vec<String> = aid.addresses.iter().map(|u| sl_word(u)).collect();
        out.push_str(&format!(" :addresses (sequence {})", urls.join(" ")));
    }
    out.push(')');
    out
}

fn sl_word(text: &str) -> String {
    let plain = !text.is_empty()
        && !text.starts_with(|c: char| c == '#' || c.is_ascii_digit() || c == '-' || c == '@')
        && text.chars().all(|c| !c.is_whitespace() && !"()\"".contains(c));
    if plain { text.to_owned() } else { format!("\"{}\"", text.replace('"', "\\\"")) }
}
