//! Basic control layer (thesis 3.3, figure 3.2): linear and angular speed to wheel speeds for a
//! differential-drive chair, with speed and acceleration limits, and a watchdog that stops the
//! chair when commands stop arriving.

use iw_body::WheelSpeeds;

use crate::error::check_positive;
use crate::{ControlError, VelocityCommand};

/// Geometry and limits of a differential-drive chair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DiffDrive {
    /// Distance between the two drive wheels, m.
    pub track_width_m: f64,
    /// Fastest a wheel may turn, m/s at the tyre.
    pub max_wheel_mps: f64,
    /// Fastest a wheel speed may change, m/s^2.
    pub max_wheel_accel_mps2: f64,
}

impl DiffDrive {
    /// Checks the geometry.
    pub fn new(
        track_width_m: f64,
        max_wheel_mps: f64,
        max_wheel_accel_mps2: f64,
    ) -> Result<Self, ControlError> {
        check_positive("track_width_m", track_width_m)?;
        check_positive("max_wheel_mps", max_wheel_mps)?;
        check_positive("max_wheel_accel_mps2", max_wheel_accel_mps2)?;
        Ok(DiffDrive {
            track_width_m,
            max_wheel_mps,
            max_wheel_accel_mps2,
        })
    }

    /// Wheel speeds for `command`; when a wheel would exceed `max_wheel_mps` both are scaled down
    /// together, so the chair keeps the commanded curvature and only goes slower.
    pub fn wheel_speeds(&self, command: VelocityCommand) -> Result<WheelSpeeds, ControlError> {
        let command = command.validate()?;
        let half_turn = command.angular_radps * self.track_width_m / 2.0;
        let (left, right) = (
            command.linear_mps - half_turn,
            command.linear_mps + half_turn,
        );
        let scale = (self.max_wheel_mps / left.abs().max(right.abs())).min(1.0);
        Ok(WheelSpeeds {
            left_mps: left * scale,
            right_mps: right * scale,
        })
    }

    /// The chair motion that wheel speeds produce (inverse kinematics).
    pub fn command(&self, wheels: WheelSpeeds) -> VelocityCommand {
        VelocityCommand {
            linear_mps: (wheels.left_mps + wheels.right_mps) / 2.0,
            angular_radps: (wheels.right_mps - wheels.left_mps) / self.track_width_m,
        }
    }

    /// Moves `from` towards `to` by at most `max_wheel_accel_mps2 * dt_s` per wheel.
    pub fn ramp(&self, from: WheelSpeeds, to: WheelSpeeds, dt_s: f64) -> WheelSpeeds {
        let step = self.max_wheel_accel_mps2 * dt_s.max(0.0);
        let toward = |a: f64, b: f64| a + (b - a).clamp(-step, step);
        WheelSpeeds {
            left_mps: toward(from.left_mps, to.left_mps),
            right_mps: toward(from.right_mps, to.right_mps),
        }
    }
}

/// Stops the chair when no command arrived for `timeout_ns` (a crashed agent, a lost link).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Watchdog {
    timeout_ns: u64,
    last_feed_ns: Option<u64>,
}

impl Watchdog {
    /// A watchdog that has not been fed yet (so it reports expired until the first command).
    pub fn new(timeout_ns: u64) -> Self {
        Watchdog {
            timeout_ns,
            last_feed_ns: None,
        }
    }

    /// A command arrived at `now_ns`.
    pub fn feed(&mut self, now_ns: u64) {
        self.last_feed_ns = Some(now_ns);
    }

    /// True when the last command is older than the timeout at `now_ns` (or none ever came).
    pub fn expired(&self, now_ns: u64) -> bool {
        self.last_feed_ns
            .is_none_or(|last| now_ns.saturating_sub(last) > self.timeout_ns)
    }
}

/// The basic control layer: latest command in, ramped wheel speeds out, zero after the watchdog
/// fires.
#[derive(Debug, Clone)]
pub struct BasicControl {
    drive: DiffDrive,
    watchdog: Watchdog,
    target: WheelSpeeds,
    output: WheelSpeeds,
    last_output_ns: Option<u64>,
}

impl BasicControl {
    /// A stopped chair with the given drive and watchdog timeout.
    pub fn new(drive: DiffDrive, timeout_ns: u64) -> Self {
        BasicControl {
            drive,
            watchdog: Watchdog::new(timeout_ns),
            target: WheelSpeeds::default(),
            output: WheelSpeeds::default(),
            last_output_ns: None,
        }
    }

    /// A new command from the tactical layer or a shared controller, received at `now_ns`.
    pub fn command(&mut self, command: VelocityCommand, now_ns: u64) -> Result<(), ControlError> {
        self.target = self.drive.wheel_speeds(command)?;
        self.watchdog.feed(now_ns);
        Ok(())
    }

    /// True when the watchdog has fired at `now_ns`.
    pub fn timed_out(&self, now_ns: u64) -> bool {
        self.watchdog.expired(now_ns)
    }

    /// The wheels were stopped outside this layer (a body fault, an emergency stop): forget the
    /// target and the ramp state, so the next output ramps up from rest instead of jumping back
    /// to the speed the chair had before.
    pub fn halt(&mut self, now_ns: u64) {
        self.target = WheelSpeeds::default();
        self.output = WheelSpeeds::default();
        self.last_output_ns = Some(now_ns);
    }

    /// The wheel speed references to send at `now_ns`: ramped towards the last command, or towards
    /// zero once the watchdog has fired.
    pub fn output(&mut self, now_ns: u64) -> WheelSpeeds {
        let goal = if self.watchdog.expired(now_ns) {
            WheelSpeeds::default()
        } else {
            self.target
        };
        let dt_s = self
            .last_output_ns
            .map_or(0.0, |last| now_ns.saturating_sub(last) as f64 * 1e-9);
        self.output = if self.last_output_ns.is_none() {
            goal
        } else {
            self.drive.ramp(self.output, goal, dt_s)
        };
        self.last_output_ns = Some(now_ns);
        self.output
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive() -> DiffDrive {
        DiffDrive::new(iw_body::TRACK_M, 1.2, 1.0).unwrap()
    }

    #[test]
    fn kinematics_round_trip_and_limits() {
        let d = drive();
        let cmd = VelocityCommand::new(0.5, 0.4);
        let w = d.wheel_speeds(cmd).unwrap();
        let back = d.command(w);
        assert!((back.linear_mps - 0.5).abs() < 1e-12 && (back.angular_radps - 0.4).abs() < 1e-12);
        let fast = d.wheel_speeds(VelocityCommand::new(2.0, 2.0)).unwrap();
        assert!(fast.left_mps.abs() <= 1.2 + 1e-12 && fast.right_mps.abs() <= 1.2 + 1e-12);
        // Curvature kept: w / v = 1 still.
        let c = d.command(fast);
        assert!((c.angular_radps / c.linear_mps - 1.0).abs() < 1e-9);
    }

    #[test]
    fn after_a_halt_the_output_ramps_up_from_rest() {
        let mut basic = BasicControl::new(drive(), 500_000_000);
        let mut now = 0;
        for _ in 0..30 {
            now += 100_000_000;
            basic.command(VelocityCommand::new(0.6, 0.0), now).unwrap();
            basic.output(now);
        }
        assert!((basic.output(now).left_mps - 0.6).abs() < 1e-12);
        basic.halt(now);
        now += 100_000_000;
        basic.command(VelocityCommand::new(0.6, 0.0), now).unwrap();
        // one 100 ms step at 1 m/s^2 from rest, not back to 0.6 m/s
        assert!(
            (basic.output(now).left_mps - 0.1).abs() < 1e-9,
            "{:?}",
            basic.output(now)
        );
    }

    #[test]
    fn watchdog_stops_after_timeout_in_simulated_time() {
        let mut basic = BasicControl::new(drive(), 500_000_000);
        basic.command(VelocityCommand::new(0.6, 0.0), 0).unwrap();
        let mut now = 0;
        // Commands keep coming every 100 ms: full speed after the ramp.
        for _ in 0..20 {
            now += 100_000_000;
            basic.command(VelocityCommand::new(0.6, 0.0), now).unwrap();
            basic.output(now);
        }
        assert!((basic.output(now).left_mps - 0.6).abs() < 1e-12);
        // Commands stop: still driving within the timeout, then ramping down to zero.
        let last = now;
        now += 400_000_000;
        assert!(!basic.timed_out(now));
        assert!(basic.output(now).left_mps > 0.0);
        now = last + 600_000_000;
        assert!(basic.timed_out(now));
        for _ in 0..10 {
            now += 100_000_000;
            basic.output(now);
        }
        assert_eq!(basic.output(now), WheelSpeeds::default());
    }

    #[test]
    fn unfed_watchdog_is_expired() {
        assert!(Watchdog::new(1).expired(0));
    }
}
