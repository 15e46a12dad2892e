//! Security layer (thesis 3.3.3): nobody can read, forge or alter a message.
//!
//! # Organization
//! - [`SecurityLayer`], [`SecurityConfig`]: the [`iw_bus::Layer`] and its settings.
//! - [`Identity`]: an Ed25519 key pair per agent or container; [`KeyDirectory`] / [`Directory`]:
//!   the agents' public keys as the agent lists carry them.
//! - [`verify_envelope`]: third-party check of a signed message; [`SealInfo`]: a sealed frame's
//!   key id and nonce.
//!
//! # Modes, chosen per destination (as the thesis says)
//! - **Public key** (default): the first message from agent A to agent B starts a key agreement:
//!   A sends a *hello* (fresh X25519 ephemeral key and session id, signed with A's Ed25519
//!   identity), B answers with its own ephemeral key, signed by B. Both derive the AES-256-GCM
//!   key with HKDF-SHA256 over the X25519 secret (salt: both ephemeral keys; info: both names)
//!   and cache it: agreement once per peer and direction, not per message. Messages wait in
//!   the layer until the key exists (ring: X25519, Ed25519, HKDF, AES-256-GCM).
//! - **Pre-shared key**: for peers configured with a 256-bit key; each sending session draws a
//!   random 128-bit salt and derives its AES-256-GCM key with HKDF(psk, salt, names) (the
//!   `aes-gcm` crate seals).
//!
//! Signatures (Ed25519 over header and plaintext) are added for receivers that need to prove to
//! third parties who said what ([`SecurityConfig::sign_all`], [`SecurityConfig::sign_for`]).
//!
//! # Guarantees
//! - Confidentiality and integrity: every message is AEAD-sealed; the whole header (ids,
//!   names, timestamp, sequence number, reply-by, flags) is the associated data, so a changed
//!   byte anywhere in a frame is rejected ([`iw_bus::Reason::BadTag`]; EN 50159 *corruption*).
//! - Authenticity (EN 50159 *masquerade*, *insertion*): keys are bound to the names of both
//!   agents and to the identity keys the directory lists for them; unsealed frames are never
//!   delivered ([`iw_bus::Reason::NotSealed`]); a delivered envelope says who was
//!   authenticated (`Envelope::authenticated`), which the parser layer matches to the ACL sender.
//! - Nonces never repeat under one key: every key is new per sending session (fresh ephemeral
//!   keys, or a fresh random 128-bit salt), and within a session the 96-bit nonce is a counter.
//!   A restarted sender therefore never reuses a (key, nonce) pair, without any stored state
//!   (a random 32-bit nonce prefix would collide after ~2^16 restarts; new keys do not).
//!
//! Not covered here: replay of a whole valid frame (communication and temporal layers), delay
//! (temporal layer).
//!
//! A receiver that restarts loses its sessions; it answers the next sealed frame with an
//! unauthenticated re-key request naming the session. The sender retires every session towards
//! that receiver, takes back the frames still held for it below (the communication layer's
//! retransmission copies, see `iw_bus::Layer::reclaim`), opens them with the retired key and
//! queues them for a new key agreement: they are delivered under the new session, not
//! retransmitted forever under one the receiver no longer holds. Known limit: a frame keeps its
//! original timestamp, so one older than the temporal layer's age limit by then is refused as
//! stale by the receiver.
#![warn(missing_docs)]

mod identity;
mod layer;

pub use identity::{
    Directory, Identity, KeyDirectory, PublicKey, signed_bytes, verify, verify_envelope,
};
pub use layer::{PreSharedKey, SealInfo, SecurityConfig, SecurityLayer};

/// Failures of key handling (never of message checks, which are drop verdicts).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SecurityError {
    /// The system random generator failed.
    #[error("the system random number generator failed")]
    Rng,
    /// A key could not be derived or loaded into the cipher.
    #[error("key derivation or cipher setup failed")]
    KeyDerivation,
    /// A stored key does not parse.
    #[error("bad {what}: {reason}")]
    BadKey {
        /// What was being read.
        what: &'static str,
        /// Why it was refused.
        reason: String,
    },
}

#[cfg(test)]
mod tests;
