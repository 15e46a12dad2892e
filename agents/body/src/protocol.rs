//! The framed binary protocol between the computer and the interface board (thesis figure 3.3).
//!
//! Every frame, both directions:
//!
//! ```text
//!  0      1      2      3      4 ..            4+len .. 4+len+3
//! +------+------+------+------+--------------+------------------------------+
//! | 0xA5 | 0x5A | kind | len  | payload      | CRC-32 LE over kind,len,payload |
//! +------+------+------+------+--------------+------------------------------+
//! ```
//!
//! Kinds (all integers little endian):
//! - `0x01` request sensors, host to board, empty payload; the board answers with `0x81`.
//! - `0x02` wheel speed references, host to board: `left_mmps: i16`, `right_mmps: i16`.
//! - `0x81` sensors, board to host: `time_ns: u64`, `left_ticks: i64`, `right_ticks: i64`, then
//!   16 sonar ranges `u16` in mm (0 = no echo), S1 first.
//!
//! The decoder resynchronises on the two sync bytes, so a corrupt frame costs that frame only.
//! Payloads are at most [`MAX_PAYLOAD`] bytes; a larger `len` is rejected before waiting for it.
//! Known limit: line noise that mimics a header with a plausible `len` holds the decoder until
//! that many bytes arrived (at most one sensor frame later), then the checksum rejects it.

use crate::{SONAR_COUNT, SensorFrame};

/// First sync byte.
pub const SYNC0: u8 = 0xA5;
/// Second sync byte.
pub const SYNC1: u8 = 0x5A;
/// Largest payload any kind uses; longer `len` fields are corruption.
pub const MAX_PAYLOAD: usize = SENSORS_LEN;
const HEADER: usize = 4;
const TRAILER: usize = 4;
const SENSORS_LEN: usize = 8 + 8 + 8 + 2 * SONAR_COUNT;
/// Bytes kept while searching for a sync pattern before old garbage is dropped.
const MAX_BUFFERED: usize = 4096;

/// Frame kind byte values.
mod kind {
    pub const REQUEST_SENSORS: u8 = 0x01;
    pub const SPEED_REF: u8 = 0x02;
    pub const SENSORS: u8 = 0x81;
}

/// One decoded frame.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)] // decoded one at a time and consumed at once: boxing buys nothing
pub enum Message {
    /// Host asks for a sensor frame.
    RequestSensors,
    /// Host sets the wheel speed references, mm/s.
    SpeedRef {
        /// Left wheel, mm/s.
        left_mmps: i16,
        /// Right wheel, mm/s.
        right_mmps: i16,
    },
    /// Board reports encoders and sonars (the laser is not on the board: `laser_m` is empty).
    Sensors(SensorFrame),
}

/// Why a frame was rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ProtocolError {
    /// The CRC-32 did not match: the frame was corrupted on the line.
    #[error(
        "checksum mismatch on frame kind {kind:#04x}: frame says {expected:#010x}, bytes give {actual:#010x}"
    )]
    Checksum {
        /// Kind byte as received.
        kind: u8,
        /// CRC carried by the frame.
        expected: u32,
        /// CRC computed over the received bytes.
        actual: u32,
    },
    /// The length byte exceeds [`MAX_PAYLOAD`].
    #[error("frame kind {kind:#04x} claims {len} payload bytes, more than the {max} allowed")]
    Oversized {
        /// Kind byte as received.
        kind: u8,
        /// Length byte as received.
        len: usize,
        /// [`MAX_PAYLOAD`].
        max: usize,
    },
    /// The kind byte is not one of the protocol's kinds.
    #[error("unknown frame kind {kind:#04x}")]
    UnknownKind {
        /// Kind byte as received.
        kind: u8,
    },
    /// The payload length does not fit the kind.
    #[error("frame kind {kind:#04x} needs {expected} payload bytes, got {actual}")]
    Length {
        /// Kind byte.
        kind: u8,
        /// Payload size this kind requires.
        expected: usize,
        /// Payload size received.
        actual: usize,
    },
}

/// Encodes `message` as one complete frame.
pub fn encode(message: &Message) -> Vec<u8> {
    let (kind, payload) = match message {
        Message::RequestSensors => (kind::REQUEST_SENSORS, Vec::new()),
        Message::SpeedRef {
            left_mmps,
            right_mmps,
        } => {
            let mut p = left_mmps.to_le_bytes().to_vec();
            p.extend_from_slice(&right_mmps.to_le_bytes());
            (kind::SPEED_REF, p)
        }
        Message::Sensors(frame) => {
            let mut p = Vec::with_capacity(SENSORS_LEN);
            p.extend_from_slice(&frame.time_ns.to_le_bytes());
            p.extend_from_slice(&frame.left_ticks.to_le_bytes());
            p.extend_from_slice(&frame.right_ticks.to_le_bytes());
            for range in &frame.sonar_m {
                p.extend_from_slice(&sonar_to_mm(*range).to_le_bytes());
            }
            (kind::SENSORS, p)
        }
    };
    let len = payload.len() as u8; // every kind's payload is at most MAX_PAYLOAD < 256
    let mut out = Vec::with_capacity(HEADER + payload.len() + TRAILER);
    out.extend_from_slice(&[SYNC0, SYNC1, kind, len]);
    out.extend_from_slice(&payload);
    let crc = crc32fast::hash(&out[2..]);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Sonar range on the wire: mm, 0 for no echo, saturating at 65.535 m.
fn sonar_to_mm(range_m: Option<f64>) -> u16 {
    match range_m {
        Some(r) if r.is_finite() && r > 0.0 => {
            (r * 1000.0).round().clamp(1.0, u16::MAX as f64) as u16
        }
        _ => 0,
    }
}

/// Incremental decoder: push bytes as they arrive, pull frames.
#[derive(Debug, Default)]
pub struct Decoder {
    buf: Vec<u8>,
    skipped: u64,
}

impl Decoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
        if self.buf.len() > MAX_BUFFERED {
            let excess = self.buf.len() - MAX_BUFFERED;
            self.buf.drain(..excess);
            self.skipped += excess as u64;
        }
    }

    /// Bytes discarded so far while hunting for a frame start (line noise).
    pub fn skipped_bytes(&self) -> u64 {
        self.skipped
    }

    /// `Ok(Some)` a frame, `Ok(None)` more bytes needed, `Err` one corrupt frame was dropped
    /// (call again: later frames are still decodable).
    pub fn decode(&mut self) -> Result<Option<Message>, ProtocolError> {
        let start = self.buf.windows(2).position(|w| w == [SYNC0, SYNC1]);
        let drop_to = match start {
            Some(i) => i,
            // keep a trailing SYNC0: it may begin a frame
            None => self
                .buf
                .len()
                .saturating_sub(usize::from(self.buf.last() == Some(&SYNC0))),
        };
        self.skipped += drop_to as u64;
        self.buf.drain(..drop_to);
        if start.is_none() || self.buf.len() < HEADER {
            return Ok(None);
        }
        let (kind, len) = (self.buf[2], usize::from(self.buf[3]));
        if len > MAX_PAYLOAD {
            self.buf.drain(..2);
            return Err(ProtocolError::Oversized {
                kind,
                len,
                max: MAX_PAYLOAD,
            });
        }
        let total = HEADER + len + TRAILER;
        let Some(frame) = self.buf.get(..total) else {
            return Ok(None);
        };
        let actual = crc32fast::hash(&frame[2..HEADER + len]);
        let mut crc_bytes = [0u8; 4];
        crc_bytes.copy_from_slice(&frame[HEADER + len..]);
        let expected = u32::from_le_bytes(crc_bytes);
        if expected != actual {
            // the length byte itself may be corrupt: resync just past this sync pattern
            self.buf.drain(..2);
            return Err(ProtocolError::Checksum {
                kind,
                expected,
                actual,
            });
        }
        let payload: Vec<u8> = frame[HEADER..HEADER + len].to_vec();
        self.buf.drain(..total);
        parse_payload(kind, &payload).map(Some)
    }
}

fn parse_payload(kind: u8, p: &[u8]) -> Result<Message, ProtocolError> {
    let need = |expected: usize| {
        if p.len() == expected {
            Ok(())
        } else {
            Err(ProtocolError::Length {
                kind,
                expected,
                actual: p.len(),
            })
        }
    };
    match kind {
        kind::REQUEST_SENSORS => need(0).map(|()| Message::RequestSensors),
        kind::SPEED_REF => {
            need(4)?;
            Ok(Message::SpeedRef {
                left_mmps: i16::from_le_bytes([p[0], p[1]]),
                right_mmps: i16::from_le_bytes([p[2], p[3]]),
            })
        }
        kind::SENSORS => {
            need(SENSORS_LEN)?;
            let u64_at = |i: usize| {
                let mut b = [0u8; 8];
                b.copy_from_slice(&p[i..i + 8]);
                u64::from_le_bytes(b)
            };
            let mut sonar_m = [None; SONAR_COUNT];
            for (k, range) in sonar_m.iter_mut().enumerate() {
                let mm = u16::from_le_bytes([p[24 + 2 * k], p[25 + 2 * k]]);
                *range = (mm != 0).then(|| f64::from(mm) / 1000.0);
            }
            // the board samples its sonars with its encoders
            let time_ns = u64_at(0);
            Ok(Message::Sensors(SensorFrame {
                time_ns,
                left_ticks: u64_at(8) as i64,
                right_ticks: u64_at(16) as i64,
                sonar_m,
                laser_m: Vec::new(),
                ranges_time_ns: time_ns,
                ticks_time_ns: time_ns,
            }))
        }
        _ => Err(ProtocolError::UnknownKind { kind }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sample() -> SensorFrame {
        let mut f = SensorFrame::empty(123_456_789);
        f.left_ticks = -42;
        f.right_ticks = 1 << 40;
        f.sonar_m[0] = Some(0.27);
        f.sonar_m[15] = Some(3.0);
        f
    }

    #[test]
    fn round_trip_every_kind() {
        for m in [
            Message::RequestSensors,
            Message::SpeedRef {
                left_mmps: -1500,
                right_mmps: 32767,
            },
            Message::Sensors(sample()),
        ] {
            let mut d = Decoder::new();
            d.push(&encode(&m));
            assert_eq!(d.decode().unwrap(), Some(m));
            assert_eq!(d.decode().unwrap(), None);
        }
    }

    #[test]
    fn corrupt_frame_is_rejected_and_the_next_one_decodes() {
        let mut bytes = encode(&Message::Sensors(sample()));
        bytes[10] ^= 0x40;
        bytes.extend(encode(&Message::RequestSensors));
        let mut d = Decoder::new();
        d.push(&bytes);
        assert!(matches!(
            d.decode(),
            Err(ProtocolError::Checksum { kind: 0x81, .. })
        ));
        assert_eq!(d.decode().unwrap(), Some(Message::RequestSensors));
    }

    #[test]
    fn split_delivery_waits_for_the_rest() {
        let bytes = encode(&Message::SpeedRef {
            left_mmps: 1,
            right_mmps: 2,
        });
        let mut d = Decoder::new();
        for b in &bytes[..bytes.len() - 1] {
            d.push(&[*b]);
            assert_eq!(d.decode().unwrap(), None);
        }
        d.push(&bytes[bytes.len() - 1..]);
        assert!(d.decode().unwrap().is_some());
    }

    #[test]
    fn oversized_and_unknown_are_named() {
        let mut d = Decoder::new();
        d.push(&[SYNC0, SYNC1, 0x81, 200]);
        assert!(matches!(
            d.decode(),
            Err(ProtocolError::Oversized { len: 200, .. })
        ));
        let mut raw = vec![SYNC0, SYNC1, 0x33, 0];
        raw.extend(crc32fast::hash(&[0x33, 0]).to_le_bytes());
        d.push(&raw);
        assert_eq!(d.decode(), Err(ProtocolError::UnknownKind { kind: 0x33 }));
    }

    proptest! {
        #[test]
        fn any_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let mut d = Decoder::new();
            d.push(&bytes);
            for _ in 0..bytes.len() + 1 {
                if let Ok(None) = d.decode() { break; }
            }
        }

        #[test]
        fn noise_around_a_frame_does_not_hide_it(pre in proptest::collection::vec(any::<u8>(), 0..50), l in any::<i16>(), r in any::<i16>()) {
            let m = Message::SpeedRef { left_mmps: l, right_mmps: r };
            let mut d = Decoder::new();
            // a noise prefix may look like a frame start; the real frame must still come out
            d.push(&pre);
            d.push(&encode(&m));
            d.push(&[0u8; MAX_PAYLOAD + 8]);
            let mut found = false;
            for _ in 0..pre.len() + MAX_PAYLOAD {
                match d.decode() {
                    Ok(Some(got)) if got == m => { found = true; break; }
                    Ok(None) => break,
                    _ => {}
                }
            }
            prop_assert!(found);
        }
    }
}
