//! The services container's FIPA HTTP MTP gateway (`[mtp.http] listen`): a foreign platform such
//! as JADE posts to `http://LISTEN/acc` and reaches the service agents by name (`df@services`,
//! `assistant@services`, ...); what they answer is posted back to the sender's address.
//!
//! The gateway delivers on the container's own bus, through its layers: each foreign sender gets
//! a proxy mailbox there and is registered under the container's key, as the container speaks
//! for it on the bus (the gateway authenticates no one: bind it where only trusted platforms
//! reach it, or behind TLS). Foreign agents reach only this container's agents; a chair's
//! container does not know them.

use std::net::SocketAddr;
use std::sync::Arc;

use iw_bus::Bus;
use iw_mtp_http::{Gateway, GatewayConfig};
use iw_stack::{Platform, PublicKey};

use crate::{NodeError, SERVICES};

/// A running gateway and the runtime its server and proxies run on.
pub(crate) struct HttpMtp {
    gateway: Arc<Gateway>,
    // dropped after the gateway: its tasks end with the runtime
    _runtime: tokio::runtime::Runtime,
}

impl HttpMtp {
    /// Starts the gateway on `listen` delivering on `bus`, admitting foreign senders to
    /// `platform` under `key` (the container's); `None` when `listen` is empty.
    pub(crate) fn start(
        listen: &str,
        bus: Arc<Bus>,
        platform: &Platform,
        key: PublicKey,
    ) -> Result<Option<HttpMtp>, NodeError> {
        if listen.is_empty() {
            return Ok(None);
        }
        let bad = |what: String, source: crate::Cause| NodeError::Value {
            key: "mtp.http.listen".into(),
            what,
            source,
        };
        let bind: SocketAddr = listen
            .parse()
            .map_err(|e| bad(format!("`{listen}`"), Box::new(e)))?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("mtp-http")
            .enable_all()
            .build()
            .map_err(|e| bad("starting its runtime".into(), e.into()))?;
        let platform = platform.clone();
        let config = GatewayConfig {
            bind,
            admit: Some(Arc::new(move |name: &str| platform.register(name, key))),
            ..GatewayConfig::new(SERVICES)
        };
        let gateway = runtime
            .block_on(Gateway::start(config, bus))
            .map_err(|e| bad(format!("binding {bind}"), e.into()))?;
        Ok(Some(HttpMtp {
            gateway,
            _runtime: runtime,
        }))
    }

    /// The transport address foreign platforms post to.
    pub(crate) fn url(&self) -> String {
        self.gateway.url()
    }
}
