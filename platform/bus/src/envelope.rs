//! The envelope every layer sees: a small fixed header and the payload (the ACL string, or its
//! ciphertext once the security layer has sealed it).

use crate::time::Time;

/// Unique identity of one message from one sender (the communication layer de-duplicates and
/// acknowledges by it). See [`IdGen`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct MsgId(pub u64);

impl std::fmt::Display for MsgId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:016x}", self.0)
    }
}

/// Makes message ids unique per sender: a random 32-bit session prefix and a 32-bit counter.
///
/// A restarted process draws a new prefix, so its ids do not collide with those it used before
/// (collision probability 2^-32 per restart); within a session ids never repeat for 2^32 messages.
#[derive(Debug, Clone)]
pub struct IdGen {
    prefix: u64,
    next: u32,
}

impl IdGen {
    /// A generator with a random session prefix.
    pub fn new() -> IdGen {
        IdGen::with_prefix(rand::random::<u32>())
    }
    /// A generator with a chosen prefix (deterministic tests).
    pub fn with_prefix(prefix: u32) -> IdGen {
        IdGen {
            prefix: u64::from(prefix) << 32,
            next: 0,
        }
    }
    /// The next id.
    pub fn next_id(&mut self) -> MsgId {
        let id = MsgId(self.prefix | u64::from(self.next));
        self.next = self.next.wrapping_add(1);
        id
    }
}

impl Default for IdGen {
    fn default() -> Self {
        IdGen::new()
    }
}

/// Header flags: one bit each. Unknown bits are rejected by the codec.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Flags(pub u8);

impl Flags {
    /// No flag.
    pub const NONE: Flags = Flags(0);
    /// An acknowledgement of the communication layer; the payload names the acknowledged id.
    pub const ACK: Flags = Flags(1 << 0);
    /// The payload is sealed by the security layer (AEAD).
    pub const SEALED: Flags = Flags(1 << 1);
    /// A security-layer key-agreement frame (hello or hello-reply), never delivered to agents.
    pub const HANDSHAKE: Flags = Flags(1 << 2);
    /// The sender signed the content (Ed25519) so third parties can verify it.
    pub const SIGNED: Flags = Flags(1 << 3);
    /// A frame of the pre-shared-key mode (as opposed to public-key mode).
    pub const PRE_SHARED: Flags = Flags(1 << 4);
    /// Every defined bit.
    pub const ALL: Flags = Flags(0b1_1111);

    /// True if all bits of `other` are set.
    pub const fn contains(self, other: Flags) -> bool {
        self.0 & other.0 == other.0
    }
    /// `self` with the bits of `other` set.
    #[must_use]
    pub const fn with(self, other: Flags) -> Flags {
        Flags(self.0 | other.0)
    }
    /// `self` with the bits of `other` cleared.
    #[must_use]
    pub const fn without(self, other: Flags) -> Flags {
        Flags(self.0 & !other.0)
    }
}

/// The fields every layer reads; all of them are bound to the payload by the security layer.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Header {
    /// Unique per sender (communication layer).
    pub id: MsgId,
    /// Sending agent's name (the ACL `:sender` name).
    pub sender: String,
    /// Receiving agent's name (one of the ACL `:receiver` names).
    pub receiver: String,
    /// When the sender's temporal layer stamped it.
    pub timestamp: Time,
    /// Per-sender sequence number (temporal layer).
    pub seq: u64,
    /// Deadline for a useful reply or delivery; [`Time::ZERO`] means none.
    pub reply_by: Time,
    /// See [`Flags`].
    pub flags: Flags,
}

/// Length of an Ed25519 signature, bytes.
pub const SIGNATURE_LEN: usize = 64;

/// One message on the bus. The default (id 0, no names, empty payload) is what a layer leaves
/// behind when it takes an envelope it keeps ([`std::mem::take`]).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Envelope {
    /// Routing, ordering and freshness fields.
    pub header: Header,
    /// The ACL string (or its ciphertext while sealed).
    pub payload: Vec<u8>,
    /// The sender's Ed25519 signature over header and plaintext, when [`Flags::SIGNED`]; it is
    /// carried inside the ciphertext and restored by the security layer so it can be forwarded.
    pub signature: Option<Box<[u8; SIGNATURE_LEN]>>,
    /// Local only, never on the wire: the sender identity the security layer authenticated
    /// (`None` until a security layer has verified the frame).
    pub authenticated: Option<String>,
}

impl Envelope {
    /// A new message from `sender` to `receiver`; timestamp and sequence number are the temporal
    /// layer's to fill in.
    pub fn new(
        id: MsgId,
        sender: impl Into<String>,
        receiver: impl Into<String>,
        payload: Vec<u8>,
    ) -> Envelope {
        Envelope {
            header: Header {
                id,
                sender: sender.into(),
                receiver: receiver.into(),
                timestamp: Time::ZERO,
                seq: 0,
                reply_by: Time::ZERO,
                flags: Flags::NONE,
            },
            payload,
            signature: None,
            authenticated: None,
        }
    }

    /// Sets the reply-by deadline.
    #[must_use]
    pub fn with_reply_by(mut self, reply_by: Time) -> Envelope {
        self.header.reply_by = reply_by;
        self
    }

    /// The payload as text, if it is UTF-8.
    pub fn payload_str(&self) -> Option<&str> {
        std::str::from_utf8(&self.payload).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_unique_and_prefixed() {
        let mut g = IdGen::with_prefix(7);
        let a = g.next_id();
        let b = g.next_id();
        assert_ne!(a, b);
        assert_eq!(a.0 >> 32, 7);
    }

    #[test]
    fn flags_ops() {
        let f = Flags::ACK.with(Flags::SEALED);
        assert!(f.contains(Flags::ACK) && f.contains(Flags::SEALED));
        assert!(!f.without(Flags::ACK).contains(Flags::ACK));
    }
}
