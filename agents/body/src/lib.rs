//! The wheelchair body: one trait with real (serial interface board), virtual (simulator) and
//! mixed implementations, so no agent knows which one it drives.
//!
//! API CONTRACT (shared by the simulator, the control and perception agents): the body work fills
//! in the serial driver and board emulator and may extend, but keeps these names.
#![warn(missing_docs)]

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
}

/// Wheel speed references, m/s at the tyre.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct WheelSpeeds {
    /// Left wheel, m/s.
    pub left_mps: f64,
    /// Right wheel, m/s.
    pub right_mps: f64,
}
