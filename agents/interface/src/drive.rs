//! Proportional driving (thesis 3.3.1): a joystick or gamepad stick, the arrow keys, or the head
//! cap used "as a proportional controller where the position of his head is translated into the
//! wheelchair linear and angular speed", mapped to the user's velocity command.
//!
//! Every device is first reduced to a normalised 2-D input vector ([`Axes`]: `x` right, `y`
//! forward, each in [-1, 1]), then a radial dead zone is cut out and the rest rescaled, and the
//! vector is scaled by the gains ([`DriveMapping::max_linear_mps`],
//! [`DriveMapping::max_angular_radps`]): `y` to linear speed, `x` to turn rate (right is
//! clockwise, negative).
//!
//! The thesis gives no dead zone, range or gain; the values of [`DriveMapping::default`] are
//! ours: a stick's 10 % dead zone as powered-chair joysticks use, a head cap that ignores tilts
//! under 5 degrees and saturates at 25 degrees (a comfortable head tilt), 0.6 m/s and 0.8 rad/s
//! at full deflection (indoor speeds, well inside the prototype's 1 m/s wheels), and the arrow
//! keys at half deflection.

use serde::{Deserialize, Serialize};

use crate::InterfaceError;
use crate::input::{Device, RawInput};

/// A normalised 2-D input: `x` right, `y` forward, each in [-1, 1].
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Axes {
    /// Right deflection.
    pub x: f64,
    /// Forward deflection.
    pub y: f64,
}

impl Axes {
    /// Centred.
    pub const ZERO: Axes = Axes { x: 0.0, y: 0.0 };

    /// The vector with a radial dead zone of radius `dead_zone` cut out and the rest rescaled
    /// to reach 1 at full deflection (the length is capped at 1).
    fn past_dead_zone(self, dead_zone: f64) -> Axes {
        let r = self.x.hypot(self.y);
        if r <= dead_zone || r == 0.0 {
            return Axes::ZERO;
        }
        let k = ((r.min(1.0) - dead_zone) / (1.0 - dead_zone)) / r;
        Axes {
            x: self.x * k,
            y: self.y * k,
        }
    }
}

/// The user's velocity command from one device: what the interface streams as `drive`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DriveCommand {
    /// The device it came from.
    pub device: Device,
    /// Linear speed, m/s.
    pub linear_mps: f64,
    /// Angular speed, rad/s (counter-clockwise positive).
    pub angular_radps: f64,
}

impl DriveCommand {
    /// Whether the command asks the chair to stand still.
    pub fn is_stop(&self) -> bool {
        self.linear_mps == 0.0 && self.angular_radps == 0.0
    }
}

/// Dead zones and gains from device readings to velocity commands.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DriveMapping {
    /// Stick deflection (radial, of 1) under which a joystick or gamepad stick is centred.
    pub stick_dead_zone: f64,
    /// Head tilt under which the head cap is centred, rad.
    pub head_dead_zone_rad: f64,
    /// Head tilt that counts as full deflection, rad.
    pub head_full_scale_rad: f64,
    /// Deflection an arrow key gives, of 1.
    pub arrow_deflection: f64,
    /// Linear speed at full forward deflection, m/s.
    pub max_linear_mps: f64,
    /// Turn rate at full sideways deflection, rad/s.
    pub max_angular_radps: f64,
}

impl Default for DriveMapping {
    fn default() -> Self {
        DriveMapping {
            stick_dead_zone: 0.1,
            head_dead_zone_rad: 5f64.to_radians(),
            head_full_scale_rad: 25f64.to_radians(),
            arrow_deflection: 0.5,
            max_linear_mps: 0.6,
            max_angular_radps: 0.8,
        }
    }
}

/// The numbers of a proportional [`RawInput`]: a stick's device and (x, y), the head cap's
/// (pitch, roll), the arrows (up, down, left, right).
#[derive(Debug, Clone, Copy)]
enum Proportional {
    Stick(Device, f64, f64),
    HeadCap(f64, f64),
    Arrows(bool, bool, bool, bool),
}

impl Proportional {
    fn of(reading: &RawInput) -> Option<Self> {
        Some(match *reading {
            RawInput::Joystick { x, y } => Proportional::Stick(Device::Joystick, x, y),
            RawInput::GamepadStick { x, y } => Proportional::Stick(Device::Gamepad, x, y),
            RawInput::HeadCap {
                pitch_rad,
                roll_rad,
            } => Proportional::HeadCap(pitch_rad, roll_rad),
            RawInput::Arrows {
                up,
                down,
                left,
                right,
            } => Proportional::Arrows(up, down, left, right),
            _ => return None,
        })
    }
}

/// Slack on the [-1, 1] stick range for rounding in a device driver or a browser.
const STICK_SLACK: f64 = 1e-6;

impl DriveMapping {
    /// The command a proportional `reading` (stick, head cap, arrow keys) stands for; `None`
    /// for a symbolic one. A non-finite axis, a stick beyond [-1, 1] or a head tilted past 90
    /// degrees is refused: the caller stops the chair.
    pub fn command(&self, reading: &RawInput) -> Option<Result<DriveCommand, InterfaceError>> {
        Some(self.proportional(Proportional::of(reading)?))
    }

    fn proportional(&self, reading: Proportional) -> Result<DriveCommand, InterfaceError> {
        let (device, axes) = match reading {
            Proportional::Stick(device, x, y) => {
                let axes = Axes { x, y };
                let ok = |a: f64| a.is_finite() && a.abs() <= 1.0 + STICK_SLACK;
                if !(ok(axes.x) && ok(axes.y)) {
                    return Err(InterfaceError::BadAxes {
                        device,
                        x: axes.x,
                        y: axes.y,
                        range: "each axis in [-1, 1]",
                    });
                }
                (device, axes.past_dead_zone(self.stick_dead_zone))
            }
            Proportional::HeadCap(pitch_rad, roll_rad) => {
                let ok = |a: f64| a.is_finite() && a.abs() <= std::f64::consts::FRAC_PI_2;
                if !(ok(pitch_rad) && ok(roll_rad)) {
                    return Err(InterfaceError::BadAxes {
                        device: Device::HeadGesture,
                        x: roll_rad,
                        y: pitch_rad,
                        range: "tilts within +-pi/2 rad",
                    });
                }
                let full = self.head_full_scale_rad;
                let axes = Axes {
                    x: (roll_rad / full).clamp(-1.0, 1.0),
                    y: (pitch_rad / full).clamp(-1.0, 1.0),
                };
                (
                    Device::HeadGesture,
                    axes.past_dead_zone(self.head_dead_zone_rad / full),
                )
            }
            Proportional::Arrows(up, down, left, right) => {
                let axis = |plus: bool, minus: bool| {
                    self.arrow_deflection * (f64::from(u8::from(plus)) - f64::from(u8::from(minus)))
                };
                (
                    Device::Keyboard,
                    Axes {
                        x: axis(right, left),
                        y: axis(up, down),
                    },
                )
            }
        };
        Ok(DriveCommand {
            device,
            linear_mps: axes.y * self.max_linear_mps,
            // `+ 0.0` turns -0.0 (stick centred, x = -0) into 0.0, so a stop compares equal.
            angular_radps: -axes.x * self.max_angular_radps + 0.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn stick(x: f64, y: f64) -> RawInput {
        RawInput::Joystick { x, y }
    }

    fn command(m: &DriveMapping, r: RawInput) -> Result<DriveCommand, InterfaceError> {
        m.command(&r).expect("a proportional reading")
    }

    #[test]
    fn deflection_maps_proportionally_past_the_dead_zone() {
        let m = DriveMapping::default();
        let full = command(&m, stick(0.0, 1.0)).unwrap();
        assert_eq!((full.linear_mps, full.angular_radps), (0.6, 0.0));
        assert!(command(&m, stick(0.05, -0.08)).unwrap().is_stop());
        let half = command(&m, stick(0.0, 0.55)).unwrap();
        assert!((half.linear_mps - 0.3).abs() < 1e-12, "{half:?}");
        let right = command(&m, stick(1.0, 0.0)).unwrap();
        assert!(
            (right.angular_radps + 0.8).abs() < 1e-12,
            "right turns clockwise"
        );
        let head = command(
            &m,
            RawInput::HeadCap {
                pitch_rad: 15f64.to_radians(),
                roll_rad: 3f64.to_radians(),
            },
        )
        .unwrap();
        assert_eq!(head.device, Device::HeadGesture);
        assert!(head.linear_mps > 0.25 && head.linear_mps < 0.35, "{head:?}");
        let still = command(
            &m,
            RawInput::HeadCap {
                pitch_rad: 0.05,
                roll_rad: -0.05,
            },
        )
        .unwrap();
        assert!(still.is_stop(), "a head within 5 degrees drives nothing");
        let keys = command(
            &m,
            RawInput::Arrows {
                up: true,
                down: false,
                left: true,
                right: false,
            },
        )
        .unwrap();
        assert_eq!((keys.linear_mps, keys.angular_radps), (0.3, 0.4));
    }

    #[test]
    fn broken_readings_are_refused() {
        let m = DriveMapping::default();
        for bad in [
            stick(f64::NAN, 0.0),
            stick(0.0, f64::INFINITY),
            stick(1.5, 0.0),
            RawInput::HeadCap {
                pitch_rad: 2.0,
                roll_rad: 0.0,
            },
        ] {
            assert!(
                matches!(
                    command(&m, bad.clone()),
                    Err(InterfaceError::BadAxes { .. })
                ),
                "{bad:?}"
            );
        }
    }

    proptest! {
        /// Any accepted reading gives a finite command within the gains.
        #[test]
        fn commands_stay_within_the_gains(x in -1.0..=1.0f64, y in -1.0..=1.0f64, p in -1.5..1.5f64, r in -1.5..1.5f64) {
            let m = DriveMapping::default();
            for reading in [stick(x, y), RawInput::HeadCap { pitch_rad: p, roll_rad: r }] {
                let c = command(&m, reading).unwrap();
                prop_assert!(c.linear_mps.abs() <= m.max_linear_mps + 1e-12);
                prop_assert!(c.angular_radps.abs() <= m.max_angular_radps + 1e-12);
            }
        }
    }
}
