//! Control frames on the wire: every [`ContainerMsg`] travels in a Noise session between the
//! sender and the receiver container ([`iw_layer_security::PeerSessions`]: the data plane's
//! handshake, each static key bound to the container's Ed25519 identity, the identity its
//! agents' list entries carry), with the sender's sequence number.
//!
//! A session's frame: the sequence number (8 bytes, big-endian), then the message as JSON. The
//! session authenticates the identity and refuses a frame replayed within it; the sequence
//! number grows across all the sender's sessions in one life, so a frame of an earlier session
//! (a re-keyed one) is refused by the container as a replay too.

use std::sync::Arc;

use iw_bus::Time;
use iw_bus::transport::PeerAddr;
use iw_layer_security::{Identity, PeerSessions, PublicKey, SecurityConfig};

use crate::{ContainerError, ContainerMsg};

pub(crate) const SEQ_LEN: usize = 8;

/// A control message from an identity a session authenticated: whose it is, its sequence
/// number, what it says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Authenticated {
    /// The Ed25519 public key of the identity the session was agreed with.
    pub key: PublicKey,
    /// The sender's sequence number (grows by one per frame it sends in one life).
    pub seq: u64,
    /// The message.
    pub msg: ContainerMsg,
}

/// One container's end of the control channel: its sessions with every peer, sans I/O.
#[derive(Debug)]
pub struct ControlChannel {
    sessions: PeerSessions,
    seq: u64,
}

impl ControlChannel {
    /// The channel of the container speaking as `identity`.
    pub fn new(identity: Arc<Identity>) -> Result<Self, ContainerError> {
        let config = SecurityConfig {
            // Control frames repeat (heartbeats): a few held while a session is agreed suffice.
            max_queued: 64,
            ..SecurityConfig::default()
        };
        let sessions = PeerSessions::new(identity, config)
            .map_err(|source| ContainerError::Sessions { source })?;
        Ok(Self { sessions, seq: 0 })
    }

    /// The datagrams to send to `to` now for `msg`: the message sealed under the session, or
    /// a hello when none is agreed (the message then goes with the reply, see
    /// [`ControlChannel::open`]).
    pub fn seal(
        &mut self,
        to: &PeerAddr,
        msg: &ContainerMsg,
        now: Time,
    ) -> Result<Vec<Vec<u8>>, ContainerError> {
        self.seq += 1;
        let mut frame = self.seq.to_be_bytes().to_vec();
        frame.extend_from_slice(&msg.encode()?);
        self.sessions
            .seal(&to.0, &frame, now)
            .map_err(|source| ContainerError::Sessions { source })
    }

    /// Takes a datagram from `from`: the message it carries, if it is a session's frame
    /// (`Ok(None)` for a handshake). What must go back to `from` (a handshake reply, messages
    /// that waited for its reply, a re-key request) is appended to `back`. A refused datagram
    /// is [`ContainerError::Refused`] with the reason; a frame that opens but is not a container
    /// message is [`ContainerError::ShortFrame`] or [`ContainerError::BadMessage`].
    pub fn open(
        &mut self,
        from: &PeerAddr,
        datagram: &[u8],
        now: Time,
        back: &mut Vec<Vec<u8>>,
    ) -> Result<Option<Authenticated>, ContainerError> {
        let opened = self
            .sessions
            .open(&from.0, datagram, now, back)
            .map_err(|reason| ContainerError::Refused {
                len: datagram.len(),
                reason,
            })?;
        let Some(opened) = opened else {
            return Ok(None);
        };
        let Some((seq, body)) = opened.frame.split_first_chunk::<SEQ_LEN>() else {
            return Err(ContainerError::ShortFrame {
                len: opened.frame.len(),
            });
        };
        Ok(Some(Authenticated {
            key: opened.key,
            seq: u64::from_be_bytes(*seq),
            msg: ContainerMsg::decode(body)?,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ContainerId;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn any_datagram_opens_or_is_refused_never_a_panic(
            datagram in proptest::collection::vec(any::<u8>(), 0..300),
            kind in 0u8..6,
        ) {
            let mut channel = ControlChannel::new(Arc::new(Identity::generate().unwrap())).unwrap();
            let mut back = Vec::new();
            // as is, and behind a valid head of each kind
            let headed = [&b"IWN1"[..], &[kind], &datagram].concat();
            for d in [datagram.as_slice(), &headed] {
                match channel.open(&PeerAddr("x".into()), d, Time(1), &mut back) {
                    Ok(m) => prop_assert!(m.is_none(), "a message out of random bytes"),
                    Err(e) => prop_assert!(!e.to_string().is_empty()),
                }
            }
        }
    }

    #[test]
    fn a_message_goes_after_the_handshake_with_its_sender_key_and_sequence_number() {
        let identity = Arc::new(Identity::generate().unwrap());
        let mut a = ControlChannel::new(identity.clone()).unwrap();
        let mut b = ControlChannel::new(Arc::new(Identity::generate().unwrap())).unwrap();
        let (a_addr, b_addr) = (PeerAddr("a".into()), PeerAddr("b".into()));
        let msg = ContainerMsg::Heartbeat {
            id: ContainerId(3),
            incarnation: 9,
            leader: ContainerId(1),
            lal_generation: 4,
            gal_versions: Default::default(),
        };
        let now = Time(1);
        let hello = a.seal(&b_addr, &msg, now).unwrap();
        let mut back = Vec::new();
        assert_eq!(b.open(&a_addr, &hello[0], now, &mut back).unwrap(), None);
        let mut to_b = Vec::new();
        assert_eq!(a.open(&b_addr, &back[0], now, &mut to_b).unwrap(), None);
        let opened = b.open(&a_addr, &to_b[0], now, &mut back).unwrap().unwrap();
        assert_eq!(
            (opened.key, opened.seq, opened.msg),
            (identity.public_key(), 1, msg.clone())
        );
        let next = a.seal(&b_addr, &msg, now).unwrap();
        let opened = b.open(&a_addr, &next[0], now, &mut back).unwrap().unwrap();
        assert_eq!(opened.seq, 2);
        let err = b.open(&a_addr, &next[0], now, &mut back).unwrap_err();
        assert!(
            matches!(
                err,
                ContainerError::Refused {
                    reason: iw_bus::Reason::Duplicate,
                    ..
                }
            ),
            "{err}"
        );
        let err = b
            .open(&a_addr, &msg.encode().unwrap(), now, &mut back)
            .unwrap_err();
        assert!(err.to_string().contains("not_sealed"), "{err}");
    }

    /// A frame that the session opens but that holds no container message keeps the JSON
    /// decoder's error as its source; one too short for the sequence number says so.
    #[test]
    fn a_sealed_frame_that_is_no_message_keeps_the_decoder_error() {
        let mut a = ControlChannel::new(Arc::new(Identity::generate().unwrap())).unwrap();
        let mut b = ControlChannel::new(Arc::new(Identity::generate().unwrap())).unwrap();
        let (a_addr, b_addr) = (PeerAddr("a".into()), PeerAddr("b".into()));
        let now = Time(1);
        let msg = ContainerMsg::Duplicate {
            id: ContainerId(2),
            holder: PeerAddr("h".into()),
            holder_incarnation: 1,
            holder_uptime_ms: 5,
        };
        // agree a session the ordinary way
        let hello = a.seal(&b_addr, &msg, now).unwrap();
        let mut back = Vec::new();
        b.open(&a_addr, &hello[0], now, &mut back).unwrap();
        let mut to_b = Vec::new();
        a.open(&b_addr, &back[0], now, &mut to_b).unwrap();
        b.open(&a_addr, &to_b[0], now, &mut back).unwrap().unwrap();

        let mut seal = |frame: &[u8]| a.sessions.seal(&b_addr.0, frame, now).unwrap().remove(0);
        let not_json = seal(&[&7u64.to_be_bytes()[..], b"{not json"].concat());
        let err = b.open(&a_addr, &not_json, now, &mut back).unwrap_err();
        let source = std::error::Error::source(&err).expect("a source");
        let json = source
            .downcast_ref::<serde_json::Error>()
            .expect("the JSON decoder's error");
        assert!(json.is_syntax(), "{json}");
        assert!(
            matches!(err, ContainerError::BadMessage { len: 9, .. }),
            "{err}"
        );

        let short = seal(&[1, 2, 3]);
        let err = b.open(&a_addr, &short, now, &mut back).unwrap_err();
        assert!(
            matches!(err, ContainerError::ShortFrame { len: 3 }),
            "{err}"
        );
        assert!(err.to_string().contains("8-byte sequence number"), "{err}");
    }
}
