//! Control frames on the wire: every [`ContainerMsg`] travels signed by its sender container's
//! Ed25519 identity (the identity its agents' list entries carry and the data plane's Noise
//! handshake binds to its static key), with a sequence number.
//!
//! Layout: `IWC1`, the signer's public key (32 bytes), the signature (64), the sequence number
//! (8, big-endian), then the message as JSON. The signature covers a context string, the key,
//! the sequence number and the JSON, so no part can be swapped.

use iw_layer_security::{Identity, PublicKey, verify};

use crate::{ContainerError, ContainerMsg};

const MAGIC: &[u8; 4] = b"IWC1";
/// Domain separation: a control signature is never valid as any other signature.
const CONTEXT: &[u8] = b"iw-control-v1";
const KEY_AT: usize = MAGIC.len();
const SIG_AT: usize = KEY_AT + 32;
const SEQ_AT: usize = SIG_AT + 64;
const BODY_AT: usize = SEQ_AT + 8;

/// A control message whose signature checked: who signed it, its sequence number, what it says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Signed {
    /// The Ed25519 public key that signed the frame.
    pub key: PublicKey,
    /// The signer's sequence number (grows by one per frame it signs in one life).
    pub seq: u64,
    /// The message.
    pub msg: ContainerMsg,
}

impl Signed {
    /// Signs `msg` as `identity` with sequence number `seq`.
    pub fn seal(
        identity: &Identity,
        seq: u64,
        msg: &ContainerMsg,
    ) -> Result<Vec<u8>, ContainerError> {
        let body = msg.encode()?;
        let key = identity.public_key();
        let sig = identity.sign(&signed_bytes(&key, seq, &body));
        let mut frame = Vec::with_capacity(BODY_AT + body.len());
        frame.extend_from_slice(MAGIC);
        frame.extend_from_slice(&key);
        frame.extend_from_slice(&sig);
        frame.extend_from_slice(&seq.to_be_bytes());
        frame.extend_from_slice(&body);
        Ok(frame)
    }

    /// Checks a frame's signature and decodes it; anything else is
    /// [`ContainerError::BadMessage`] (unsigned, altered, or not a container message).
    pub fn open(frame: &[u8]) -> Result<Signed, ContainerError> {
        let bad = |reason: &str| ContainerError::BadMessage {
            len: frame.len(),
            reason: reason.into(),
        };
        if frame.len() < BODY_AT || &frame[..KEY_AT] != MAGIC {
            return Err(bad("not a signed control frame (no IWC1 header)"));
        }
        let mut key = [0u8; 32];
        key.copy_from_slice(&frame[KEY_AT..SIG_AT]);
        let mut seq = [0u8; 8];
        seq.copy_from_slice(&frame[SEQ_AT..BODY_AT]);
        let seq = u64::from_be_bytes(seq);
        let body = &frame[BODY_AT..];
        if !verify(&key, &signed_bytes(&key, seq, body), &frame[SIG_AT..SEQ_AT]) {
            return Err(bad("the signature does not verify"));
        }
        Ok(Signed {
            key,
            seq,
            msg: ContainerMsg::decode(body)?,
        })
    }
}

fn signed_bytes(key: &PublicKey, seq: u64, body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(CONTEXT.len() + 40 + body.len());
    out.extend_from_slice(CONTEXT);
    out.extend_from_slice(key);
    out.extend_from_slice(&seq.to_be_bytes());
    out.extend_from_slice(body);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ContainerId;

    #[test]
    fn a_signed_frame_opens_and_any_changed_byte_is_refused() {
        let identity = Identity::generate().unwrap();
        let msg = ContainerMsg::Heartbeat {
            id: ContainerId(3),
            incarnation: 9,
            leader: ContainerId(1),
            lal_generation: 4,
            gal_versions: Default::default(),
        };
        let frame = Signed::seal(&identity, 17, &msg).unwrap();
        let opened = Signed::open(&frame).unwrap();
        assert_eq!((opened.key, opened.seq), (identity.public_key(), 17));
        assert_eq!(opened.msg, msg);
        for i in 0..frame.len() {
            let mut bad = frame.clone();
            bad[i] ^= 1;
            assert!(Signed::open(&bad).is_err(), "byte {i} flipped was taken");
        }
        let err = Signed::open(&msg.encode().unwrap())
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a signed control frame"), "{err}");
    }
}
