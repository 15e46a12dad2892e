//! The wheelchair body: one trait with real (serial interface board), virtual (simulator) and
//! mixed implementations, so no agent knows which one it drives.
//!
//! # Organization
//! - [`Body`]: read a [`SensorFrame`], command [`WheelSpeeds`], stop. Implemented by
//!   [`SerialBody`] (the interface board of thesis figure 3.3 on a serial port), by the
//!   simulator's `VirtualBody` (crate `iw-sim`) and by [`MixedBody`] (real readings merged with
//!   virtual ones, nearest wins per sonar).
//! - [`protocol`]: the framed binary protocol spoken with the interface board (CRC-32 per frame).
//! - [`BoardEmulator`]: the interface board emulated on a pseudo-terminal, so tests and demos
//!   run the real [`SerialBody`] driver over a real tty.
//! - [`layout`]: the chair's [`layout::Footprint`] and its sonar poses (figure 3.4), shared by the
//!   simulator and the control agent.
//! - [`WheelGeometry`] and [`Odometry`]: ticks to metres, dead reckoning of `t_world_body`.
//! - [`BodyWorker`]: any body's blocking I/O on its own thread, so a control period never waits
//!   for the serial link.
//!
//! # Guarantees
//! - No input from the serial line panics: corrupt, truncated or oversized frames are rejected
//!   with a [`BodyError`] naming what was wrong.
//! - [`Body::stop`] always sends zero wheel speeds; it is the watchdog's last resort.
#![warn(missing_docs)]

mod emulator;
pub mod layout;
mod mixed;
mod odometry;
pub mod protocol;
mod serial;
mod worker;

pub use emulator::{BoardEmulator, BoardHandle, BoardState};
pub use mixed::{MixedBody, VirtualSensors, merge_nearest};
pub use odometry::{Odometry, TRACK_M, WheelGeometry, WheelTravel};
pub use serial::SerialBody;
pub use worker::BodyWorker;

/// Number of sonars on the IntellWheels prototype (thesis figure 3.4).
pub const SONAR_COUNT: usize = 16;

/// What the body senses in one control period.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorFrame {
    /// Body time of the reading, ns.
    pub time_ns: u64,
    /// Cumulative encoder ticks, left wheel.
    pub left_ticks: i64,
    /// Cumulative encoder ticks, right wheel.
    pub right_ticks: i64,
    /// Sonar ranges in metres, `None` where nothing echoed within range.
    pub sonar_m: [Option<f64>; SONAR_COUNT],
    /// Laser ranges in metres, if a laser is fitted (empty otherwise).
    pub laser_m: Vec<f64>,
    /// When the range readings (sonars and laser) were taken, in the clock of `time_ns`:
    /// `time_ns` for a body that reads them with its encoders, earlier for one whose ranges
    /// come from where it was a while ago (a mixed chair's ghost in a world process). The
    /// localizer matches a scan where the chair was at that time.
    pub ranges_time_ns: u64,
    /// When the encoder ticks were counted, in the body's own clock, which may differ from
    /// `time_ns`'s and restart with the body (a world process's simulated time): only the
    /// difference between two frames' is meant, as the time the ticks between them took. A
    /// chair's frames from a world process arrive at the chair's reads, while the world moved
    /// it by the time its own steps took (40 or 60 ms for a 50 ms period).
    pub ticks_time_ns: u64,
}

impl SensorFrame {
    /// A frame at `time_ns` with no echoes, no laser and zero ticks.
    pub fn empty(time_ns: u64) -> Self {
        Self {
            time_ns,
            left_ticks: 0,
            right_ticks: 0,
            sonar_m: [None; SONAR_COUNT],
            laser_m: Vec::new(),
            ranges_time_ns: time_ns,
            ticks_time_ns: time_ns,
        }
    }
}

/// Wheel speed references, m/s at the tyre.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct WheelSpeeds {
    /// Left wheel, m/s.
    pub left_mps: f64,
    /// Right wheel, m/s.
    pub right_mps: f64,
}

impl WheelSpeeds {
    /// Both wheels stopped.
    pub const STOP: Self = Self {
        left_mps: 0.0,
        right_mps: 0.0,
    };

    /// Wheel speeds for a linear speed `v_mps` and an angular speed `w_radps` (counter-clockwise
    /// positive) on a differential drive whose wheels are `track_m` apart.
    pub fn from_twist(v_mps: f64, w_radps: f64, track_m: f64) -> Self {
        Self {
            left_mps: v_mps - w_radps * track_m / 2.0,
            right_mps: v_mps + w_radps * track_m / 2.0,
        }
    }
}

/// A wheelchair body as the agents see it: real, virtual or mixed, they cannot tell.
pub trait Body {
    /// The latest sensor reading (blocks at most one control period on real hardware).
    fn read(&mut self) -> Result<SensorFrame, BodyError>;
    /// Sets the wheel speed references; the body applies its own acceleration limits.
    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError>;
    /// Commands zero wheel speeds.
    fn stop(&mut self) -> Result<(), BodyError> {
        self.command(WheelSpeeds::STOP)
    }
}

/// One [`BodyError`] reported more than once: a [`BodyWorker`] reports a failed read on every
/// read until the next one. `source()` of a [`BodyError::Link`] is that [`BodyError`].
pub type SharedBodyError = iw_cause::Cause<BodyError>;

/// Why the body could not read or command.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BodyError {
    /// The serial port could not be opened or configured.
    #[error("serial port `{port}`: {source}")]
    Port {
        /// Port path, e.g. `/dev/ttyUSB0`.
        port: String,
        /// What the OS said.
        source: serialport::Error,
    },
    /// Reading or writing the link failed.
    #[error("serial i/o on `{port}`: {source}")]
    Io {
        /// Port path.
        port: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A frame on the link was malformed (bad checksum, unknown type, wrong length).
    #[error("interface board frame rejected: {0}")]
    Protocol(#[from] protocol::ProtocolError),
    /// No complete sensor frame arrived within the timeout. The byte counts tell a silent link
    /// (0 received) from a garbled one (bytes received, skipped as noise).
    #[error(
        "no sensor frame from `{port}` within {} ms ({received} bytes received, {skipped} skipped as noise)",
        timeout.as_millis()
    )]
    Timeout {
        /// Port path.
        port: String,
        /// How long we waited.
        timeout: std::time::Duration,
        /// Bytes read from the port during this wait.
        received: u64,
        /// Bytes the decoder discarded during this wait.
        skipped: u64,
    },
    /// A wheel speed reference cannot be encoded (not finite or beyond the wire range).
    #[error("wheel speed {value_mps} m/s is not finite or beyond +-{limit_mps} m/s")]
    SpeedOutOfRange {
        /// The offending reference.
        value_mps: f64,
        /// The wire limit.
        limit_mps: f64,
    },
    /// The I/O thread of a [`BodyWorker`] has no frame yet, or its frame is stale.
    #[error("body i/o: {reason}")]
    Worker {
        /// What went wrong.
        reason: String,
    },
    /// The body behind a [`BodyWorker`] failed a read or a command: its error, shared because
    /// the worker reports one failed read on every `read` until the next read.
    #[error("body i/o: {source}")]
    Link {
        /// What the body said.
        #[source]
        source: SharedBodyError,
    },
    /// The I/O thread of a [`BodyWorker`] could not be started.
    #[error("body i/o: starting the body i/o thread: {source}")]
    Thread {
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// The virtual side failed with nothing underneath to pass on (an injected fault, a
    /// world link gone silent); the message says why.
    #[error("virtual body: {reason}")]
    Virtual {
        /// What went wrong.
        reason: String,
    },
    /// The world a virtual body lives in refused a read or a command: the simulator (no such
    /// chair), or the bus to the world's container. The world's error is kept whole as the
    /// source; this crate does not know its type (the simulator sits above the agents).
    #[error("virtual body: {what}: {source}")]
    World {
        /// Which part refused, e.g. `world unreachable`.
        what: &'static str,
        /// What it said.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
}
