//! Shared-control obstacle avoidance for a powered wheelchair (thesis 3.6), a VFH+ shared controller
//! as a baseline, the tactical and basic control layers of the control agent (thesis 3.3), and a
//! driver model for simulated experiments (thesis 3.7.1). The Wilcoxon signed-rank test the thesis
//! evaluates with lives in `iw-stats`.
//!
//! Pure library: no bus, no simulator. Every function takes its inputs (sensor ranges, pose, time in
//! ns) explicitly, so the same code runs on the real chair, in the simulator and in tests.
//!
//! Organization:
//! - [`VelocityCommand`]: linear and angular speed, the currency of all layers; [`MotionIntent`] maps
//!   it to the direction the chair is about to travel and back.
//! - [`SharedController`]: one trait, `step(&SharedInput) -> SharedOutput`, with
//!   [`ThesisField`] (thesis equations 3.1-3.4 as a filter on the joystick's input vector, through
//!   [`JoystickMapping`]), [`PotentialField`] (the same equations with an arc-chord mapping of
//!   our own), [`Vfh`] (VFH+), [`ArcGuard`] (the footprint swept along the commanded path,
//!   turning in place included, from the chair's measured [`Motion`] and with the dense points it
//!   no longer sees remembered: the control agent's policy) and [`Manual`] (pass-through).
//! - [`EchoMemory`]: the sonars' near echoes kept in the odometry frame where their cones agree,
//!   so the guard still sees a jamb that has fallen into the gap between two cones.
//! - [`tactical`]: basic actions (follow line, spin, turn to angle, go to XY, follow left/right wall,
//!   wait, stop) and [`tactical::ActionSequence`], each next action starting when the current is done.
//! - [`basic`]: differential-drive kinematics with limits and a [`basic::Watchdog`] that stops the
//!   chair when commands stop arriving.
//! - [`driver`]: [`driver::SeeingDriver`], a seeded model of a person who sees the obstacles
//!   around the chair and steers along a circuit with a head cap or a joystick.
//!
//! Guarantees:
//! - With no obstacle inside the safety range the user's command comes out unchanged, bit for bit
//!   (the round trip through [`MotionIntent`] is exact); [`Intervention::changed`] is then false.
//! - [`PotentialField`], [`Vfh`] and [`ArcGuard`] never drive faster than the user asked, nor in
//!   the opposite direction; [`ThesisField`] may (the thesis's `F_t` can point backwards), within
//!   the joystick's full deflection.
//! - Nothing here reads a clock: time is an explicit `u64` ns input, so runs are reproducible.
//! - Bad configuration or sensor input (NaN, negative ranges, wrong array sizes) is a
//!   [`ControlError`], never a panic.
#![warn(missing_docs)]

pub mod basic;
mod command;
mod dock;
pub mod driver;
mod echoes;
mod error;
mod guard;
mod joystick;
mod manual;
mod motion;
mod potential;
mod recovery;
pub mod tactical;
mod vfh;

pub use command::{MotionIntent, VelocityCommand};
pub use echoes::{EchoMemory, EchoMemoryParams};
pub use error::ControlError;
pub use guard::{ArcGuard, ArcGuardParams};
pub use joystick::{FieldCentre, JoystickMapping, ThesisField, ThesisFieldParams};
pub use manual::Manual;
pub use motion::{Motion, WheelMotion};
pub use potential::{PotentialField, PotentialFieldParams, Repulsion};
pub use vfh::{Vfh, VfhParams};

use nalgebra::{Isometry2, Point2};

/// Where a range sensor sits on the chair: `t_chair_sensor` maps sensor coordinates (x along the
/// acoustic or optical axis) into the chair frame (x forward, y left, origin at the centre of the
/// wheel axle, which is the centre of rotation).
pub type SensorMount = Isometry2<f64>;

/// What a shared controller sees in one control period.
#[derive(Debug, Clone, Copy)]
pub struct SharedInput<'a> {
    /// The user's command (joystick or head cap).
    pub user: VelocityCommand,
    /// Measured linear speed of the chair, m/s (the thesis's `Sp`; its sign is ignored).
    pub speed_mps: f64,
    /// Sonar ranges, m, one per mount given at construction; `None` = no echo.
    pub sonar_m: &'a [Option<f64>],
    /// Obstacle points from any dense sensor (laser scanner), in the chair frame, m.
    pub points_chair: &'a [Point2<f64>],
    /// The chair's measured motion, when its encoders are read ([`WheelMotion`]); the arc guard
    /// then predicts from the speed the chair has and remembers dense points it no longer sees.
    /// The thesis's field and VFH+ ignore it.
    pub motion: Option<Motion>,
}

/// How much a shared controller changed the user's command in one period.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Intervention {
    /// Corrected minus user linear speed, m/s.
    pub delta_linear_mps: f64,
    /// Corrected minus user angular speed, rad/s.
    pub delta_angular_radps: f64,
    /// Readings that took part (inside the safety range, or blocking histogram sectors).
    pub active_readings: usize,
}

impl Intervention {
    /// Difference between a corrected and a user command.
    pub fn between(
        user: VelocityCommand,
        corrected: VelocityCommand,
        active_readings: usize,
    ) -> Self {
        Intervention {
            delta_linear_mps: corrected.linear_mps - user.linear_mps,
            delta_angular_radps: corrected.angular_radps - user.angular_radps,
            active_readings,
        }
    }

    /// True when the command that reaches the wheels differs from the user's.
    pub fn changed(&self) -> bool {
        self.delta_linear_mps != 0.0 || self.delta_angular_radps != 0.0
    }

    /// One number for "how much": the largest wheel-speed change it causes on a chair with this
    /// track width, m/s (linear and angular changes in the same unit).
    pub fn wheel_change_mps(&self, track_width_m: f64) -> f64 {
        let turn = self.delta_angular_radps * track_width_m / 2.0;
        (self.delta_linear_mps - turn)
            .abs()
            .max((self.delta_linear_mps + turn).abs())
    }
}

/// The corrected command and how much it differs from the user's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SharedOutput {
    /// What goes to the basic control layer.
    pub command: VelocityCommand,
    /// What changed.
    pub intervention: Intervention,
}

/// A shared-control policy: takes the user's command and the sensors, returns what to drive.
///
/// Implementations may keep state between periods (VFH+ hysteresis); call `step` once per period.
pub trait SharedController {
    /// One control period.
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError>;
}
