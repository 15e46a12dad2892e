//! The TCP frame codec: a fixed 8-byte header, then the payload.
//!
//! ```text
//!  0        2         3        4                    8
//!  +--------+---------+--------+--------------------+------------------------+
//!  | "IW"   | version | kind   | payload length     | payload (length bytes) |
//!  | 2 B    | u8 = 1  | u8     | u32, big-endian    |                        |
//!  +--------+---------+--------+--------------------+------------------------+
//! ```
//!
//! `kind` 1 = hello (payload: the sender's listening address, UTF-8; first frame of every
//! connection, so replies can be addressed), 2 = data (an opaque bus frame). A length above the
//! codec's limit is an error before any payload byte is read or buffered.

use crate::NetError;

/// The magic bytes opening every frame.
pub const MAGIC: [u8; 2] = *b"IW";
/// The wire version this codec writes and accepts.
pub const WIRE_VERSION: u8 = 1;
/// Header length, bytes.
pub const HEADER_LEN: usize = 8;

/// What a frame carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// The sender's listening address (first frame of a connection).
    Hello,
    /// An opaque bus frame.
    Data,
}

impl FrameKind {
    fn code(self) -> u8 {
        match self {
            FrameKind::Hello => 1,
            FrameKind::Data => 2,
        }
    }
}

/// A decoded header: kind and payload length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameHeader {
    /// What the payload is.
    pub kind: FrameKind,
    /// Payload length, bytes.
    pub len: usize,
}

/// One decoded frame: its kind, its payload and how many input bytes it used.
pub type Decoded<'a> = (FrameKind, &'a [u8], usize);

/// Encoder and decoder for length-prefixed frames with a maximum payload length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameCodec {
    max_frame_len: usize,
}

impl FrameCodec {
    /// A codec refusing payloads longer than `max_frame_len` bytes (capped at `u32::MAX`).
    pub fn new(max_frame_len: usize) -> Self {
        Self {
            max_frame_len: max_frame_len.min(u32::MAX as usize),
        }
    }

    /// Largest payload, bytes.
    pub fn max_frame_len(&self) -> usize {
        self.max_frame_len
    }

    /// Appends the header and payload of one frame to `out`.
    pub fn encode(
        &self,
        kind: FrameKind,
        payload: &[u8],
        out: &mut Vec<u8>,
    ) -> Result<(), NetError> {
        let len = self.check_len(payload.len())?;
        out.reserve(HEADER_LEN + payload.len());
        out.extend_from_slice(&MAGIC);
        out.push(WIRE_VERSION);
        out.push(kind.code());
        out.extend_from_slice(&len.to_be_bytes());
        out.extend_from_slice(payload);
        Ok(())
    }

    /// Parses a header: `Ok(None)` if fewer than [`HEADER_LEN`] bytes are given.
    pub fn decode_header(&self, buf: &[u8]) -> Result<Option<FrameHeader>, NetError> {
        let Some(&[m0, m1, version, kind, l0, l1, l2, l3]) = buf.get(..HEADER_LEN) else {
            return Ok(None);
        };
        if [m0, m1] != MAGIC {
            return Err(NetError::BadMagic { found: [m0, m1] });
        }
        if version != WIRE_VERSION {
            return Err(NetError::UnsupportedVersion { found: version });
        }
        let kind = match kind {
            1 => FrameKind::Hello,
            2 => FrameKind::Data,
            other => return Err(NetError::UnknownKind { found: other }),
        };
        let len = u32::from_be_bytes([l0, l1, l2, l3]) as usize;
        if len > self.max_frame_len {
            return Err(NetError::FrameTooLong {
                len,
                max: self.max_frame_len,
            });
        }
        Ok(Some(FrameHeader { kind, len }))
    }

    /// Decodes one frame from the front of `buf`: `Ok(Some((kind, payload, consumed)))`,
    /// `Ok(None)` if more bytes are needed, `Err` if the stream is corrupt.
    pub fn decode<'a>(&self, buf: &'a [u8]) -> Result<Option<Decoded<'a>>, NetError> {
        let Some(header) = self.decode_header(buf)? else {
            return Ok(None);
        };
        let end = HEADER_LEN + header.len;
        Ok(buf
            .get(HEADER_LEN..end)
            .map(|payload| (header.kind, payload, end)))
    }

    fn check_len(&self, len: usize) -> Result<u32, NetError> {
        if len > self.max_frame_len {
            return Err(NetError::FrameTooLong {
                len,
                max: self.max_frame_len,
            });
        }
        u32::try_from(len).map_err(|_| NetError::FrameTooLong {
            len,
            max: self.max_frame_len,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn header_layout_is_as_drawn() {
        let mut out = Vec::new();
        FrameCodec::new(100)
            .encode(FrameKind::Data, b"abc", &mut out)
            .unwrap();
        assert_eq!(out, [b'I', b'W', 1, 2, 0, 0, 0, 3, b'a', b'b', b'c']);
    }

    #[test]
    fn corrupt_headers_name_the_fault() {
        let codec = FrameCodec::new(10);
        assert!(matches!(
            codec.decode(b"XW\x01\x02\0\0\0\0"),
            Err(NetError::BadMagic {
                found: [b'X', b'W']
            })
        ));
        assert!(matches!(
            codec.decode(b"IW\x07\x02\0\0\0\0"),
            Err(NetError::UnsupportedVersion { found: 7 })
        ));
        assert!(matches!(
            codec.decode(b"IW\x01\x09\0\0\0\0"),
            Err(NetError::UnknownKind { found: 9 })
        ));
        assert!(matches!(
            codec.decode(b"IW\x01\x02\0\0\0\x0b"),
            Err(NetError::FrameTooLong { len: 11, max: 10 })
        ));
        assert!(matches!(
            codec.encode(FrameKind::Data, &[0; 11], &mut Vec::new()),
            Err(NetError::FrameTooLong { len: 11, max: 10 })
        ));
    }

    proptest! {
        #[test]
        fn round_trip_and_partial_input_needs_more(payload in proptest::collection::vec(any::<u8>(), 0..300), hello in any::<bool>()) {
            let codec = FrameCodec::new(300);
            let kind = if hello { FrameKind::Hello } else { FrameKind::Data };
            let mut out = Vec::new();
            codec.encode(kind, &payload, &mut out).unwrap();
            out.extend_from_slice(b"next");
            let (k, p, used) = codec.decode(&out).unwrap().unwrap();
            prop_assert_eq!(k, kind);
            prop_assert_eq!(p, &payload[..]);
            prop_assert_eq!(used, HEADER_LEN + payload.len());
            for cut in 0..used {
                prop_assert!(codec.decode(&out[..cut]).unwrap().is_none());
            }
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let _ = FrameCodec::new(32).decode(&bytes);
        }
    }
}
