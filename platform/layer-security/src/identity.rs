//! Identities (Ed25519 key pairs), the directory of agents' public keys, and signatures that
//! third parties can verify.

use std::collections::HashMap;
use std::sync::{Arc, PoisonError, RwLock};

use iw_bus::{Envelope, Flags, SIGNATURE_LEN, write_aad};
use ring::rand::SystemRandom;
use ring::signature::{ED25519, Ed25519KeyPair, KeyPair, UnparsedPublicKey};

use crate::SecurityError;

/// An Ed25519 public key, 32 bytes.
pub type PublicKey = [u8; 32];

/// Domain separation of message signatures.
const SIG_CONTEXT: &[u8] = b"iw-sig-v1";

/// The Ed25519 identity of an agent or container: signs handshakes and, on request, messages.
pub struct Identity {
    pair: Ed25519KeyPair,
    public: PublicKey,
    pkcs8: Vec<u8>,
}

impl std::fmt::Debug for Identity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Identity")
            .field("public", &hex::encode(self.public))
            .finish_non_exhaustive()
    }
}

impl Identity {
    /// A fresh random identity.
    pub fn generate() -> Result<Identity, SecurityError> {
        let doc =
            Ed25519KeyPair::generate_pkcs8(&SystemRandom::new()).map_err(|_| SecurityError::Rng)?;
        Identity::from_pkcs8(doc.as_ref())
    }

    /// The identity stored as a PKCS#8 document (as [`Identity::pkcs8`] wrote it).
    pub fn from_pkcs8(pkcs8: &[u8]) -> Result<Identity, SecurityError> {
        let pair = Ed25519KeyPair::from_pkcs8(pkcs8).map_err(|source| SecurityError::BadKey {
            what: "Ed25519 PKCS#8 document",
            source,
        })?;
        let mut public = [0u8; 32];
        public.copy_from_slice(pair.public_key().as_ref());
        Ok(Identity {
            pair,
            public,
            pkcs8: pkcs8.to_vec(),
        })
    }

    /// The public key, to publish in the agent lists.
    pub fn public_key(&self) -> PublicKey {
        self.public
    }

    /// The private key as PKCS#8, to store (keep it secret).
    pub fn pkcs8(&self) -> &[u8] {
        &self.pkcs8
    }

    /// Signs `msg`.
    pub fn sign(&self, msg: &[u8]) -> [u8; SIGNATURE_LEN] {
        let mut out = [0u8; SIGNATURE_LEN];
        out.copy_from_slice(self.pair.sign(msg).as_ref());
        out
    }
}

/// Verifies an Ed25519 signature.
pub fn verify(public: &PublicKey, msg: &[u8], sig: &[u8]) -> bool {
    UnparsedPublicKey::new(&ED25519, public)
        .verify(msg, sig)
        .is_ok()
}

/// The bytes a message signature covers: the header with only the SIGNED flag (so the delivered,
/// unsealed envelope verifies the same) and the plaintext payload.
pub fn signed_bytes(env: &Envelope) -> Vec<u8> {
    let mut header = env.header.clone();
    header.flags = Flags::SIGNED;
    let mut out = Vec::with_capacity(SIG_CONTEXT.len() + 64 + env.payload.len());
    out.extend_from_slice(SIG_CONTEXT);
    // Names are at most 255 bytes in every envelope that went through the codec or a layer;
    // an over-long name simply yields bytes no signature covers.
    let _ = write_aad(&header, &mut out);
    out.extend_from_slice(&env.payload);
    out
}

/// Checks the signature a delivered envelope carries against the sender's public key: what a
/// third party does with a forwarded message.
pub fn verify_envelope(env: &Envelope, sender_key: &PublicKey) -> bool {
    env.header.flags.contains(Flags::SIGNED)
        && env
            .signature
            .as_ref()
            .is_some_and(|sig| verify(sender_key, &signed_bytes(env), &sig[..]))
}

/// Where the security layer looks up agents' public keys: fed by the Local and Global Agent
/// Lists, which carry each agent's key.
pub trait KeyDirectory: Send + Sync {
    /// The Ed25519 public key of the identity speaking for `agent`, if it is known.
    fn public_key(&self, agent: &str) -> Option<PublicKey>;
}

/// A shared, updatable [`KeyDirectory`] (clones share the same table).
#[derive(Debug, Clone, Default)]
pub struct Directory(Arc<RwLock<HashMap<String, PublicKey>>>);

impl Directory {
    /// An empty directory.
    pub fn new() -> Directory {
        Directory::default()
    }
    /// Records (or replaces) `agent`'s key.
    pub fn insert(&self, agent: &str, key: PublicKey) {
        self.0
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(agent.to_string(), key);
    }
    /// Forgets `agent`.
    pub fn remove(&self, agent: &str) {
        self.0
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(agent);
    }
}

impl KeyDirectory for Directory {
    fn public_key(&self, agent: &str) -> Option<PublicKey> {
        self.0
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(agent)
            .copied()
    }
}
