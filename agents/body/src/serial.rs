//! The driver for the interface board on a serial port (thesis figure 3.3): encoders and 16
//! sonars in, wheel speed references out, in the frames of [`crate::protocol`].

use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use crate::protocol::{Decoder, Message, encode};
use crate::{Body, BodyError, SensorFrame, WheelSpeeds};

/// Largest wheel speed reference the wire can carry (i16 mm/s).
const WIRE_LIMIT_MPS: f64 = i16::MAX as f64 / 1000.0;

/// A real body: the interface board behind a serial port.
pub struct SerialBody {
    port: Box<dyn serialport::SerialPort>,
    name: String,
    decoder: Decoder,
    timeout: Duration,
}

impl SerialBody {
    /// Opens `path` (e.g. `/dev/ttyUSB0`) at `baud`, 8N1; each read waits at most `timeout` for the
    /// board's answer.
    pub fn open(path: &str, baud: u32, timeout: Duration) -> Result<Self, BodyError> {
        let port = serialport::new(path, baud)
            .timeout(timeout)
            .open()
            .map_err(|source| BodyError::Port {
                port: path.to_string(),
                source,
            })?;
        Ok(Self::from_port(port, timeout))
    }

    /// Wraps an already open port.
    pub fn from_port(port: Box<dyn serialport::SerialPort>, timeout: Duration) -> Self {
        let name = port.name().unwrap_or_else(|| "<unnamed>".to_string());
        Self {
            port,
            name,
            decoder: Decoder::new(),
            timeout,
        }
    }

    /// Bytes of line noise discarded so far.
    pub fn skipped_bytes(&self) -> u64 {
        self.decoder.skipped_bytes()
    }

    fn send(&mut self, message: &Message) -> Result<(), BodyError> {
        self.port
            .write_all(&encode(message))
            .and_then(|()| self.port.flush())
            .map_err(|source| BodyError::Io {
                port: self.name.clone(),
                source,
            })
    }
}

fn to_mmps(value_mps: f64) -> Result<i16, BodyError> {
    if !value_mps.is_finite() || value_mps.abs() > WIRE_LIMIT_MPS {
        return Err(BodyError::SpeedOutOfRange {
            value_mps,
            limit_mps: WIRE_LIMIT_MPS,
        });
    }
    Ok((value_mps * 1000.0).round() as i16)
}

impl Body for SerialBody {
    /// Requests a sensor frame and waits for it; a corrupt answer is an error (the next read
    /// starts clean, the decoder having resynchronised).
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        self.send(&Message::RequestSensors)?;
        // I/O deadline of the driver itself, not control logic: wall time is what the tty obeys.
        let deadline = Instant::now() + self.timeout;
        let (mut received, skipped_before) = (0u64, self.decoder.skipped_bytes());
        let mut chunk = [0u8; 256];
        loop {
            while let Some(message) = self.decoder.decode()? {
                if let Message::Sensors(frame) = message {
                    return Ok(frame);
                }
                tracing::debug!(port = %self.name, ?message, "ignoring non-sensor frame from board");
            }
            if Instant::now() >= deadline {
                return Err(BodyError::Timeout {
                    port: self.name.clone(),
                    timeout: self.timeout,
                    received,
                    skipped: self.decoder.skipped_bytes() - skipped_before,
                });
            }
            match self.port.read(&mut chunk) {
                Ok(n) => {
                    received += n as u64;
                    self.decoder.push(&chunk[..n]);
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                    ) => {}
                Err(source) => {
                    return Err(BodyError::Io {
                        port: self.name.clone(),
                        source,
                    });
                }
            }
        }
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        let message = Message::SpeedRef {
            left_mmps: to_mmps(speeds.left_mps)?,
            right_mmps: to_mmps(speeds.right_mps)?,
        };
        self.send(&message)
    }
}
