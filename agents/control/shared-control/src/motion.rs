//! The chair's own motion as its wheel encoders measure it: what lets a guard predict from the
//! speed the chair really has (the wheels ramp, they do not jump to a new command) and remember
//! obstacles its sensors no longer see (a door jamb beside the chair, behind a front laser).

use iw_body::{Odometry, WheelGeometry};
use nalgebra::Isometry2;

use crate::VelocityCommand;

/// One period's motion estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// Time of the encoder reading, ns.
    pub time_ns: u64,
    /// Dead-reckoned pose in the odometry frame; only its change over a few seconds is used, so
    /// drift does not matter beyond that.
    pub t_odom_chair: Isometry2<f64>,
    /// Measured linear and angular speed over the last period (signed).
    pub twist: VelocityCommand,
}

/// Turns cumulative encoder ticks into [`Motion`]: the same dead reckoning as the perception
/// agent's ([`Odometry`]), plus the speed over the last reading.
#[derive(Debug, Clone)]
pub struct WheelMotion {
    odometry: Odometry,
    last_ns: Option<u64>,
}

impl WheelMotion {
    /// Starts at the odometry frame's origin.
    pub fn new(geometry: WheelGeometry) -> Self {
        Self {
            odometry: Odometry::new(geometry, Isometry2::identity()),
            last_ns: None,
        }
    }

    /// Integrates one encoder reading; `None` on the first reading (no speed yet) and when the
    /// time did not advance.
    pub fn update(&mut self, time_ns: u64, left_ticks: i64, right_ticks: i64) -> Option<Motion> {
        let travel = self.odometry.advance(left_ticks, right_ticks);
        let last = self.last_ns.replace(time_ns);
        let (travel, last) = (travel?, last?);
        let dt = time_ns.checked_sub(last).filter(|&d| d > 0)? as f64 * 1e-9;
        let track = self.odometry.geometry().track_m;
        Some(Motion {
            time_ns,
            t_odom_chair: self.odometry.t_world_body(),
            twist: VelocityCommand::new(
                (travel.left_m + travel.right_m) / 2.0 / dt,
                (travel.right_m - travel.left_m) / track / dt,
            ),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_and_pose_from_ticks() {
        let g = WheelGeometry::default();
        let mut m = WheelMotion::new(g);
        assert!(m.update(0, 0, 0).is_none());
        // 0.5 m/s straight for 0.1 s
        let ticks = (0.05 / g.m_per_tick()).round() as i64;
        let out = m.update(100_000_000, ticks, ticks).unwrap();
        assert!((out.twist.linear_mps - 0.5).abs() < 1e-3, "{out:?}");
        assert!(out.twist.angular_radps.abs() < 1e-9);
        assert!((out.t_odom_chair.translation.x - 0.05).abs() < 1e-4);
        // a repeated timestamp gives no speed rather than a division by zero
        assert!(m.update(100_000_000, ticks, ticks).is_none());
    }
}
