//! Velocity commands and the direction of travel they imply.

use nalgebra::Vector2;

use crate::ControlError;

/// Linear and angular speed of the chair, the interface between the user, the tactical layer, the
/// shared controllers and the basic control layer.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct VelocityCommand {
    /// Forward speed, m/s (negative = reverse).
    pub linear_mps: f64,
    /// Turn rate, rad/s (positive = counter-clockwise, to the left).
    pub angular_radps: f64,
}

impl VelocityCommand {
    /// Standing still.
    pub const STOP: VelocityCommand = VelocityCommand {
        linear_mps: 0.0,
        angular_radps: 0.0,
    };

    /// A command from its two speeds.
    pub fn new(linear_mps: f64, angular_radps: f64) -> Self {
        VelocityCommand {
            linear_mps,
            angular_radps,
        }
    }

    /// Rejects NaN or infinite speeds (a broken input device must not reach the wheels).
    pub fn validate(self) -> Result<Self, ControlError> {
        if self.linear_mps.is_finite() && self.angular_radps.is_finite() {
            Ok(self)
        } else {
            Err(ControlError::NonFiniteCommand {
                linear_mps: self.linear_mps,
                angular_radps: self.angular_radps,
            })
        }
    }
}

/// The direction a command is taking the chair, in the *motion frame*: the chair frame when driving
/// forward, the chair frame turned by 180 degrees when reversing, so the travel direction is always
/// near +x.
///
/// Over a lookahead `tau` a chair at `(v, w)` moves along an arc whose chord points at `w tau / 2`
/// from the heading; that chord (length `|v| tau`, scaled to `|v|`) is the thesis's attractive force
/// `F_a`, "directly proportional to the current user input".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionIntent {
    /// +1 forward, -1 reverse, 0 standing or spinning in place.
    pub sign: f64,
    /// |v|, m/s: the magnitude of `F_a`.
    pub speed_mps: f64,
    /// Chord direction in the motion frame, rad, within [-pi/2, pi/2].
    pub direction_rad: f64,
}

impl MotionIntent {
    /// The intent of `command` over `lookahead_s`.
    pub fn from_command(command: VelocityCommand, lookahead_s: f64) -> Self {
        let sign = if command.linear_mps > 0.0 {
            1.0
        } else if command.linear_mps < 0.0 {
            -1.0
        } else {
            0.0
        };
        let half_pi = std::f64::consts::FRAC_PI_2;
        MotionIntent {
            sign,
            speed_mps: command.linear_mps.abs(),
            direction_rad: (command.angular_radps * lookahead_s / 2.0).clamp(-half_pi, half_pi),
        }
    }

    /// The attractive force `F_a` in the chair frame (m/s).
    pub fn force_chair(&self) -> Vector2<f64> {
        self.sign
            * self.speed_mps
            * Vector2::new(self.direction_rad.cos(), self.direction_rad.sin())
    }

    /// Turns a vector in the chair frame into the motion frame of this intent.
    pub fn to_motion_frame(&self, v_chair: Vector2<f64>) -> Vector2<f64> {
        if self.sign < 0.0 { -v_chair } else { v_chair }
    }

    /// The command that travels at `speed_mps` along `direction_rad` (motion frame) over
    /// `lookahead_s`; the inverse of [`MotionIntent::from_command`].
    pub fn to_command(&self, lookahead_s: f64) -> VelocityCommand {
        VelocityCommand {
            linear_mps: self.sign * self.speed_mps,
            angular_radps: 2.0 * self.direction_rad / lookahead_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_forward_and_reverse() {
        for cmd in [
            VelocityCommand::new(0.7, 0.4),
            VelocityCommand::new(-0.3, -0.8),
            VelocityCommand::new(0.5, 0.0),
        ] {
            let intent = MotionIntent::from_command(cmd, 1.0);
            let back = intent.to_command(1.0);
            assert!((back.linear_mps - cmd.linear_mps).abs() < 1e-12);
            assert!((back.angular_radps - cmd.angular_radps).abs() < 1e-12);
        }
    }

    #[test]
    fn reverse_force_points_backwards() {
        let intent = MotionIntent::from_command(VelocityCommand::new(-0.5, 0.0), 1.0);
        assert!(intent.force_chair().x < 0.0);
        assert!(intent.to_motion_frame(intent.force_chair()).x > 0.0);
    }

    #[test]
    fn nan_rejected() {
        assert!(VelocityCommand::new(f64::NAN, 0.0).validate().is_err());
    }
}
