//! TLS for the transport (rustls with the ring provider, TLS 1.2 and 1.3): the server's
//! certificate and the client's trusted roots. A platform serves `https://` only when given a
//! [`server_config`]; a client reaches `https://` addresses only with a [`client_config`].

use std::sync::Arc;

use tokio::io::{AsyncRead, AsyncWrite};
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer};
use tokio_rustls::rustls::{self, ClientConfig, RootCertStore, ServerConfig};

use crate::Error;

pub use tokio_rustls::rustls::pki_types;

/// A byte stream the transport speaks HTTP over: plain TCP or TLS.
pub(crate) trait Io: AsyncRead + AsyncWrite + Unpin + Send {}
impl<T: AsyncRead + AsyncWrite + Unpin + Send> Io for T {}

/// A boxed [`Io`].
pub(crate) type BoxedIo = Box<dyn Io>;

fn provider() -> Arc<rustls::crypto::CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

fn tls_error(what: &'static str, source: rustls::Error) -> Error {
    Error::Tls { what, source }
}

/// A server configuration presenting `chain` (leaf first) signed by `key`.
pub fn server_config(
    chain: Vec<CertificateDer<'static>>,
    key: PrivateKeyDer<'static>,
) -> Result<Arc<ServerConfig>, Error> {
    let config = ServerConfig::builder_with_provider(provider())
        .with_safe_default_protocol_versions()
        .map_err(|e| tls_error("protocol versions", e))?
        .with_no_client_auth()
        .with_single_cert(chain, key)
        .map_err(|e| tls_error("server certificate or key", e))?;
    Ok(Arc::new(config))
}

/// A client configuration trusting exactly `roots` (DER certificates).
pub fn client_config(roots: &[CertificateDer<'static>]) -> Result<Arc<ClientConfig>, Error> {
    let mut store = RootCertStore::empty();
    for root in roots {
        store
            .add(root.clone())
            .map_err(|e| tls_error("trusted root", e))?;
    }
    let config = ClientConfig::builder_with_provider(provider())
        .with_safe_default_protocol_versions()
        .map_err(|e| tls_error("protocol versions", e))?
        .with_root_certificates(store)
        .with_no_client_auth();
    Ok(Arc::new(config))
}
