//! Security layer (thesis 3.3.3): nobody can read, forge or alter a message.
//!
//! # Organization
//! - [`SecurityLayer`], [`SecurityConfig`]: the [`iw_bus::Layer`] and its settings.
//! - [`Identity`]: an Ed25519 key pair per agent or container; [`KeyDirectory`] / [`Directory`]:
//!   the agents' public keys as the agent lists carry them.
//! - [`verify_envelope`]: third-party check of a signed message; [`SealInfo`]: a sealed frame's
//!   key id and nonce.
//! - [`PeerSessions`]: the same key agreement for a channel of byte frames between identities
//!   known by address (the containers' control channel), with the peer's identity key carried
//!   in the handshake; [`Opened`]: a frame it opened.
//!
//! # Modes, chosen per destination (as the thesis says)
//! - **Public key** (default): the first message from agent A to agent B starts a key agreement,
//!   a vetted Noise handshake (`Noise_IX_25519_AESGCM_SHA256`, the `snow` crate): A's *hello*
//!   is IX's first message (ephemeral and static X25519 keys), B's *reply* the second. Each side's
//!   static key is bound to its Ed25519 identity: the handshake payload is the identity's
//!   signature over the static key, the session id, both names and (hello) the hello's time or
//!   (reply) the handshake hash, checked against the key the directory lists for that agent. The
//!   prologue carries the session id and both names. The split's A-to-B key becomes the
//!   session's AES-256-GCM key, cached: agreement once per peer and direction, not per message.
//!   Messages wait in the layer until the key exists. Crypto: `ring` for Ed25519, SHA-256,
//!   AES-256-GCM, HKDF and randomness (also inside snow, through its ring resolver);
//!   curve25519-dalek for X25519, because ring has no static X25519 keys.
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
//! # Threat model
//! The attacker reads, drops, delays, replays, alters and injects any frame on any link, and may
//! hold an identity of her own that the directory lists under her own agent names, and may hold
//! the containers' group key (she is then a member of the deployment); she does not hold another
//! agent's or container's identity key, nor a pre-shared key she is not meant to have. What
//! stops what:
//!
//! | attack | defended by |
//! | --- | --- |
//! | read a message | AES-256-GCM under a session key only the two ends derive (here) |
//! | alter any byte of a frame, header included | AEAD tag over payload, header as associated data (here) |
//! | speak as another agent (masquerade) | handshake signed by the identity the directory lists; session keys bound to both names (here); ACL sender matched to the authenticated one (parser layer) |
//! | swap a static key in the handshake (man in the middle) | identity signature over the static key; Noise's DH over both static keys (here) |
//! | replay a hello | hellos remembered per sender and session id, and a hello older than `handshake_max_age` refused (here); a replayed hello yields no key the attacker can use anyway |
//! | replay or repeat a message | message ids (communication layer), sequence numbers and age (temporal layer) |
//! | delay, reorder | timestamps and sequence windows (temporal layer) |
//! | drop frames | retransmission until acknowledged, then counted undeliverable (communication layer) |
//! | join the containers at all, or forge, alter or replay control traffic without the group key | admission: the containers' group key in pre-shared-key mode, with the temporal layer (`iw_stack::GuardedTransport`) |
//! | holding the group key, speak as another live container (its heartbeat, its agent list, the leader's list), even from its address | identity: every control frame travels in a Noise session between the two containers ([`PeerSessions`], `iw_container::ControlChannel`): the data plane's handshake, each static key bound by a signature to the container's Ed25519 identity (the identity whose key its agents' entries carry); a frame outside a session, altered or replayed within it is refused; a live container id is bound to the identity its heartbeats' session was agreed with, lists are taken only under the bound identity of their container or of the elected leader, with a growing sequence number (`iw_container::Container`) |
//! | speak from another container's address (a spoofed source, a TCP hello naming it) | the handshake's reply goes to the address claimed, not to her: she agrees no session ([`PeerSessions`]) |
//! | replay a control frame of a restarted container's earlier life | a new session from the same identity and address drops the older ones; the container refuses an older incarnation or a sequence number not above the last (`iw_container`) |
//! | pin a route with a huge list generation | followers mirror the leader's list, the leader takes each container's part as its container says (`iw_container`) |
//! | holding the group key, list agents under her own container that carry another container's key | every list entry must carry the key of the container whose part it is in: the signer's for its own list, the bound key at a follower (`iw_container`) |
//! | holding the group key, with a deployment roster (`security.roster`): claim an id nobody holds (a low one to lead), a listed id under her own key, or another container's agent names; stop a container with a forged `Duplicate` | pinning: the roster pins each id to one key and one name in advance; a frame speaks for an id only under its pinned key (an unlisted id is nobody's), a container's part carries only `ROLE@NAME` for its pinned name, and a `Duplicate` is believed only under the receiver's own pinned key; a container whose key is not pinned for its id refuses to start (`iw_container::Roster`) |
//! | make a sender drop its session and agree another (a forged re-key request), knowing the session id from a log or an old capture | the request must echo the nonce and tag of one of the last 64 frames sealed under the current session; otherwise refused as `bad_handshake` and counted (here, [`PeerSessions`]) |
//! | flood | size caps and rate-limited warnings per reason; rejections counted per kind |
//!
//! Not defended: an attacker holding an agent's or a container's identity key (she is that
//! agent or container: with a roster she may say all it may, nothing more). Without a roster
//! (the weaker mode, warned at start) a group-key holder is a container of her choosing: she can
//! join under an id nobody holds (a low one leads the election) and list agent names of her
//! choosing, since ids are bound to keys first come, first served while their lease holds; and
//! a forged `Duplicate` from her makes a container refuse to run. Traffic analysis (who talks to whom, when, how much);
//! denial of service by an attacker on the path (she can always drop). IX sends the initiator's
//! static key in clear: it is a fresh key per layer, not the identity, so nothing long-lived is
//! exposed, but a listener can link an agent's handshakes while the layer lives.
//!
//! The control channel's sessions ([`PeerSessions`]) are re-agreed the same way, without taking
//! frames back: a restarted receiver answers a frame of a session it lost with a re-key request
//! (bound to the session as below: the frame's counter and tag echoed), its sender agrees a new
//! session at its next frame, and heartbeats repeat.
//!
//! A receiver that restarts loses its sessions; it answers the next sealed frame with a re-key
//! request. It cannot seal it (it lost the key), so the request is bound to the session
//! instead: it names the session and echoes the nonce and tag of the frame it could not open,
//! and the sender takes it only if that is one of the last 64 frames it sealed under its current
//! session towards that receiver. The session id alone (in clear in every frame, in logs) is no
//! longer enough: a request that names the current session without such a frame is refused as
//! `bad_handshake` and counted. One naming a session the sender no longer holds (a repeat, an
//! earlier life's) changes nothing. An attacker on the path who sees the frames can still ask
//! for an extra agreement (she can also just drop frames). The sender retires every session towards
//! that receiver, takes back the frames still held for it below (the communication layer's
//! retransmission copies, see `iw_bus::Layer::reclaim`), opens them with the retired key and
//! queues them for a new key agreement: they are delivered under the new session, not
//! retransmitted forever under one the receiver no longer holds. Known limit: a frame keeps its
//! original timestamp, so one older than the temporal layer's age limit by then is refused as
//! stale by the receiver.
#![warn(missing_docs)]

mod identity;
mod layer;
mod peer;

pub use identity::{
    Directory, Identity, KeyDirectory, PublicKey, signed_bytes, verify, verify_envelope,
};
pub use layer::{PreSharedKey, SealInfo, SecurityConfig, SecurityLayer};
pub use peer::{Opened, PeerSessions};

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
    #[error("bad {what}: {source}")]
    BadKey {
        /// What was being read.
        what: &'static str,
        /// Why ring refused it.
        #[source]
        source: ring::error::KeyRejected,
    },
}

#[cfg(test)]
mod tests;
