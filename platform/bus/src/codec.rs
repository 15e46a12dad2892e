//! The binary frame codec: one [`Envelope`] per frame, big-endian, versioned.
//!
//! ```text
//!  0       2       3       4                 12                20                28                36
//!  +-------+-------+-------+-----------------+-----------------+-----------------+-----------------+
//!  | magic |version| flags | message id      | sequence number | timestamp       | reply-by        |
//!  | "IW"  | u8 =1 |  u8   | u64             | u64             | u64 ns          | u64 ns (0=none) |
//!  +-------+-------+-------+-----------------+-----------------+-----------------+-----------------+
//!  36      37      38              42
//!  +-------+-------+---------------+----------+------------+----------------+---------------------+
//!  | s_len | r_len | payload len   | sender   | receiver   | payload        | signature           |
//!  | u8    | u8    | u32           | s_len B  | r_len B    | payload len B  | 64 B iff SIGNED and |
//!  |       |       |               | UTF-8    | UTF-8      |                | not SEALED          |
//!  +-------+-------+---------------+----------+------------+----------------+---------------------+
//! ```
//!
//! Everything before the payload length, plus the two names, is the header the security layer
//! binds as associated data ([`write_aad`]): altering any of it breaks the AEAD tag.
//! Frames longer than the codec's limit (64 KiB by default) are rejected before any allocation.

use crate::BusError;
use crate::envelope::{Envelope, Flags, Header, MsgId, SIGNATURE_LEN};
use crate::time::Time;

/// The two magic bytes opening every frame.
pub const MAGIC: [u8; 2] = *b"IW";
/// The wire version this codec writes and reads.
pub const WIRE_VERSION: u8 = 1;
/// Length of the fixed part of the header, bytes.
pub const FIXED_LEN: usize = 42;

/// Encodes and decodes frames, with a size limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameCodec {
    max_frame_len: usize,
}

impl Default for FrameCodec {
    fn default() -> Self {
        FrameCodec {
            max_frame_len: FrameCodec::DEFAULT_MAX_FRAME_LEN,
        }
    }
}

impl FrameCodec {
    /// Default limit on a whole frame: 64 KiB, the UDP datagram ceiling.
    pub const DEFAULT_MAX_FRAME_LEN: usize = 64 * 1024;

    /// A codec with the default 64 KiB limit.
    pub fn new() -> FrameCodec {
        FrameCodec::default()
    }
    /// A codec accepting frames up to `max_frame_len` bytes.
    pub fn with_max_frame_len(max_frame_len: usize) -> FrameCodec {
        FrameCodec { max_frame_len }
    }
    /// The frame size limit, bytes.
    pub fn max_frame_len(&self) -> usize {
        self.max_frame_len
    }

    /// Appends the frame of `env` to `out`.
    pub fn encode(&self, env: &Envelope, out: &mut Vec<u8>) -> Result<(), BusError> {
        let h = &env.header;
        let trailer = signature_on_wire(h.flags);
        let len = frame_len(h, env.payload.len(), trailer);
        if len > self.max_frame_len {
            return Err(BusError::FrameTooLarge {
                len,
                max: self.max_frame_len,
            });
        }
        let payload_len =
            u32::try_from(env.payload.len()).map_err(|_| BusError::FrameTooLarge {
                len,
                max: self.max_frame_len,
            })?;
        let (s_len, r_len) = name_lens(h)?;
        out.reserve(len);
        write_fixed(h, s_len, r_len, out);
        out.extend_from_slice(&payload_len.to_be_bytes());
        out.extend_from_slice(h.sender.as_bytes());
        out.extend_from_slice(h.receiver.as_bytes());
        out.extend_from_slice(&env.payload);
        if trailer {
            let sig = env
                .signature
                .as_deref()
                .ok_or(BusError::MissingSignature { id: h.id })?;
            out.extend_from_slice(sig);
        }
        Ok(())
    }

    /// The frame of `env` as a new vector.
    pub fn encode_to_vec(&self, env: &Envelope) -> Result<Vec<u8>, BusError> {
        let mut out = Vec::new();
        self.encode(env, &mut out)?;
        Ok(out)
    }

    /// Decodes the frame at the start of `buf` (a stream): `Ok(Some((envelope, bytes used)))`,
    /// `Ok(None)` if `buf` holds only part of a frame, `Err` if the bytes cannot be a frame
    /// (the stream is then corrupt and should be closed).
    pub fn decode(&self, buf: &[u8]) -> Result<Option<(Envelope, usize)>, BusError> {
        let Some((env, range)) = self.decode_header(buf)? else {
            return Ok(None);
        };
        let len = range.end + env.trailer_len();
        Ok(Some((
            Envelope {
                payload: buf[range].to_vec(),
                ..env
            },
            len,
        )))
    }

    /// Decodes one whole datagram: exactly one frame, nothing missing, nothing after it.
    pub fn decode_datagram(&self, buf: &[u8]) -> Result<Envelope, BusError> {
        match self.decode(buf)? {
            Some((env, used)) if used == buf.len() => Ok(env),
            Some((_, used)) => Err(BusError::TrailingBytes {
                extra: buf.len() - used,
            }),
            None => Err(BusError::Truncated { have: buf.len() }),
        }
    }

    /// As [`FrameCodec::decode_datagram`], keeping the frame's buffer as the payload's (moved to
    /// its front): no allocation for a frame the transport handed over as its own.
    pub fn decode_datagram_owned(&self, mut buf: Vec<u8>) -> Result<Envelope, BusError> {
        let Some((env, range)) = self.decode_header(&buf)? else {
            return Err(BusError::Truncated { have: buf.len() });
        };
        let used = range.end + env.trailer_len();
        if used != buf.len() {
            return Err(BusError::TrailingBytes {
                extra: buf.len() - used,
            });
        }
        let payload_len = range.len();
        buf.copy_within(range, 0);
        buf.truncate(payload_len);
        Ok(Envelope {
            payload: buf,
            ..env
        })
    }

    /// Decodes everything but the payload, which is left empty: `Ok(Some((envelope, payload
    /// range in buf)))`; the signature trailer, if any, follows the range.
    fn decode_header(
        &self,
        buf: &[u8],
    ) -> Result<Option<(Envelope, std::ops::Range<usize>)>, BusError> {
        if buf.len() >= 2 && buf[..2] != MAGIC {
            return Err(BusError::BadMagic {
                found: [buf[0], buf[1]],
            });
        }
        let Some(fixed) = buf.get(..FIXED_LEN) else {
            return Ok(None);
        };
        let version = fixed[2];
        if version != WIRE_VERSION {
            return Err(BusError::UnsupportedVersion { found: version });
        }
        let flags = Flags(fixed[3]);
        if flags.without(Flags::ALL) != Flags::NONE {
            return Err(BusError::UnknownFlags { bits: flags.0 });
        }
        let s_len = usize::from(fixed[36]);
        let r_len = usize::from(fixed[37]);
        let payload_len = usize::try_from(be_u32(&fixed[38..42])).unwrap_or(usize::MAX);
        let trailer = if signature_on_wire(flags) {
            SIGNATURE_LEN
        } else {
            0
        };
        let len = FIXED_LEN
            .saturating_add(s_len)
            .saturating_add(r_len)
            .saturating_add(payload_len)
            .saturating_add(trailer);
        if len > self.max_frame_len {
            return Err(BusError::FrameTooLarge {
                len,
                max: self.max_frame_len,
            });
        }
        let Some(frame) = buf.get(..len) else {
            return Ok(None);
        };
        let mut at = FIXED_LEN;
        let sender = name(frame, &mut at, s_len, "sender")?;
        let receiver = name(frame, &mut at, r_len, "receiver")?;
        let payload = at..at + payload_len;
        at += payload_len;
        let signature = if trailer > 0 {
            let mut sig = [0u8; SIGNATURE_LEN];
            sig.copy_from_slice(&frame[at..at + SIGNATURE_LEN]);
            Some(Box::new(sig))
        } else {
            None
        };
        let header = Header {
            id: MsgId(be_u64(&fixed[4..12])),
            seq: be_u64(&fixed[12..20]),
            timestamp: Time(be_u64(&fixed[20..28])),
            reply_by: Time(be_u64(&fixed[28..36])),
            flags,
            sender,
            receiver,
        };
        Ok(Some((
            Envelope {
                header,
                payload: Vec::new(),
                signature,
                authenticated: None,
            },
            payload,
        )))
    }
}

impl Envelope {
    /// Length of the signature trailer this envelope's frame carries, bytes.
    fn trailer_len(&self) -> usize {
        if signature_on_wire(self.header.flags) {
            SIGNATURE_LEN
        } else {
            0
        }
    }
}

/// Appends the associated data the security layer binds: the fixed header without the payload
/// length (which differs between plaintext and ciphertext), then both names.
pub fn write_aad(h: &Header, out: &mut Vec<u8>) -> Result<(), BusError> {
    let (s_len, r_len) = name_lens(h)?;
    write_fixed(h, s_len, r_len, out);
    out.extend_from_slice(h.sender.as_bytes());
    out.extend_from_slice(h.receiver.as_bytes());
    Ok(())
}

fn signature_on_wire(flags: Flags) -> bool {
    flags.contains(Flags::SIGNED) && !flags.contains(Flags::SEALED)
}

fn frame_len(h: &Header, payload: usize, trailer: bool) -> usize {
    FIXED_LEN
        + h.sender.len()
        + h.receiver.len()
        + payload
        + if trailer { SIGNATURE_LEN } else { 0 }
}

fn name_lens(h: &Header) -> Result<(u8, u8), BusError> {
    let s = u8::try_from(h.sender.len()).map_err(|_| BusError::NameTooLong {
        field: "sender",
        len: h.sender.len(),
    })?;
    let r = u8::try_from(h.receiver.len()).map_err(|_| BusError::NameTooLong {
        field: "receiver",
        len: h.receiver.len(),
    })?;
    Ok((s, r))
}

/// Appends the fixed header up to the names' lengths (assembled in place, appended at once).
fn write_fixed(h: &Header, s_len: u8, r_len: u8, out: &mut Vec<u8>) {
    let mut fixed = [0u8; FIXED_LEN - 4];
    fixed[..2].copy_from_slice(&MAGIC);
    fixed[2] = WIRE_VERSION;
    fixed[3] = h.flags.0;
    fixed[4..12].copy_from_slice(&h.id.0.to_be_bytes());
    fixed[12..20].copy_from_slice(&h.seq.to_be_bytes());
    fixed[20..28].copy_from_slice(&h.timestamp.0.to_be_bytes());
    fixed[28..36].copy_from_slice(&h.reply_by.0.to_be_bytes());
    fixed[36] = s_len;
    fixed[37] = r_len;
    out.extend_from_slice(&fixed);
}

fn name(frame: &[u8], at: &mut usize, len: usize, field: &'static str) -> Result<String, BusError> {
    let bytes = &frame[*at..*at + len];
    *at += len;
    String::from_utf8(bytes.to_vec()).map_err(|_| BusError::BadName { field })
}

fn be_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(b);
    u64::from_be_bytes(a)
}

fn be_u32(b: &[u8]) -> u32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(b);
    u32::from_be_bytes(a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sample() -> Envelope {
        let mut env = Envelope::new(
            MsgId(0x0102_0304_0506_0708),
            "alice",
            "bob@wheelchair",
            b"(inform)".to_vec(),
        );
        env.header.seq = 9;
        env.header.timestamp = Time(1_000);
        env.header.reply_by = Time(2_000);
        env
    }

    #[test]
    fn round_trip_and_prefixes() {
        let codec = FrameCodec::new();
        let env = sample();
        let frame = codec.encode_to_vec(&env).unwrap();
        assert_eq!(&frame[..4], b"IW\x01\x00");
        assert_eq!(codec.decode_datagram(&frame).unwrap(), env);
        for cut in 0..frame.len() {
            assert!(
                codec.decode(&frame[..cut]).unwrap().is_none(),
                "prefix {cut}"
            );
        }
        let mut two = frame.clone();
        two.extend_from_slice(&frame);
        assert_eq!(codec.decode(&two).unwrap().unwrap().1, frame.len());
        assert!(matches!(
            codec.decode_datagram(&two),
            Err(BusError::TrailingBytes { .. })
        ));
    }

    #[test]
    fn signature_trailer_round_trips() {
        let codec = FrameCodec::new();
        let mut env = sample();
        env.header.flags = Flags::SIGNED;
        assert!(matches!(
            codec.encode_to_vec(&env),
            Err(BusError::MissingSignature { .. })
        ));
        env.signature = Some(Box::new([7; SIGNATURE_LEN]));
        let frame = codec.encode_to_vec(&env).unwrap();
        assert_eq!(codec.decode_datagram(&frame).unwrap(), env);
    }

    #[test]
    fn rejects_bad_input() {
        let codec = FrameCodec::with_max_frame_len(100);
        let env = sample();
        let mut frame = FrameCodec::new().encode_to_vec(&env).unwrap();
        let mut big = env.clone();
        big.payload = vec![0; 200];
        assert!(matches!(
            codec.encode_to_vec(&big),
            Err(BusError::FrameTooLarge { .. })
        ));
        frame[3] = 0x80;
        assert!(matches!(
            codec.decode(&frame),
            Err(BusError::UnknownFlags { bits: 0x80 })
        ));
        frame[2] = 9;
        assert!(matches!(
            codec.decode(&frame),
            Err(BusError::UnsupportedVersion { found: 9 })
        ));
        frame[0] = b'X';
        assert!(matches!(
            codec.decode(&frame),
            Err(BusError::BadMagic { .. })
        ));
        let mut long = sample();
        long.header.sender = "x".repeat(300);
        assert!(matches!(
            FrameCodec::new().encode_to_vec(&long),
            Err(BusError::NameTooLong { .. })
        ));
    }

    proptest! {
        #[test]
        fn decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let _ = FrameCodec::new().decode(&bytes);
        }

        #[test]
        fn round_trip(id: u64, seq: u64, ts: u64, rb: u64, flags in 0u8..32, s in "[a-z@.]{0,20}",
                      r in "[a-z@.]{0,20}", payload in proptest::collection::vec(any::<u8>(), 0..300)) {
            let mut env = Envelope::new(MsgId(id), s, r, payload);
            env.header.seq = seq;
            env.header.timestamp = Time(ts);
            env.header.reply_by = Time(rb);
            env.header.flags = Flags(flags);
            if signature_on_wire(env.header.flags) { env.signature = Some(Box::new([1; SIGNATURE_LEN])); }
            let codec = FrameCodec::new();
            let frame = codec.encode_to_vec(&env).unwrap();
            prop_assert_eq!(&codec.decode_datagram(&frame).unwrap(), &env);
            prop_assert_eq!(codec.decode_datagram_owned(frame).unwrap(), env);
        }

        #[test]
        fn owned_decode_agrees(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let codec = FrameCodec::new();
            let by_ref = codec.decode_datagram(&bytes).map_err(|e| e.to_string());
            prop_assert_eq!(codec.decode_datagram_owned(bytes).map_err(|e| e.to_string()), by_ref);
        }
    }
}
