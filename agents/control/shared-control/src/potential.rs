//! Equations 3.1-3.4 of thesis 3.6 with an arc-chord mapping of our own (the `shared-chord`
//! variant; the thesis's reading as a joystick filter is [`crate::ThesisField`]).
//!
//! Each sonar echo `D_i` places an obstacle `O_i` on the sensor's acoustic axis; it pushes the chair
//! along `O_i -> C` (C here = centre of the drive axle, equation 3.1) with
//! `|F_i| = alpha exp(-beta D_i + omega Sp) |F_a|` (3.2). The repulsions add up to `F_r` (3.3) and
//! `F_t = F_a + F_r` (3.4). Our invention, not the thesis's: `F_a` is the chord of the arc the
//! command drives in `lookahead_s` (length |v|), and `F_t` goes back to a command by the inverse,
//! its direction clamped to +-90 degrees, never reversing, never faster than the user.
//!
//! Units (an assumption; the text does not give them): `D` in **centimetres**, `Sp` in **m/s**.
//! With alpha 0.51, beta 0.271, omega 14.8 the repulsion equals the user's pull at
//! `D = (omega Sp + ln alpha) / beta`: 25 cm at 0.5 m/s, 52 cm at 1.0 m/s, 79 cm at 1.5 m/s, inside
//! the 27-80 cm sensing perimeter of section 3.4 over a powered chair's speed range; `D` in
//! metres would make the force vanish nowhere inside a room, `Sp` in cm/s would saturate it.
//!
//! Safety range (an assumption; figure 3.8 is not in the text): a reading acts only when `D` is within
//! `d_safe(Sp) = clamp((omega Sp - ln(epsilon / alpha)) / beta, 27 cm, 80 cm)`, the distance where the
//! repulsion falls to `epsilon |F_a|` (default 5 %), bounded by the perimeter the sonars cover. Beyond
//! it the user's command passes through untouched.

use nalgebra::{Point2, Vector2};

use crate::error::{check_positive, check_range};
use crate::{
    ControlError, Intervention, MotionIntent, SensorMount, SharedController, SharedInput,
    SharedOutput,
};

/// Constants of equation 3.2 and the safety range; defaults are the thesis's.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PotentialFieldParams {
    /// alpha, dimensionless (0.51).
    pub alpha: f64,
    /// beta, per centimetre of obstacle distance (0.271).
    pub beta_per_cm: f64,
    /// omega, per m/s of chair speed (14.8).
    pub omega_s_per_m: f64,
    /// Relative force below which a reading is outside the safety range (0.05).
    pub epsilon: f64,
    /// Inner bound of the safety range, m (0.27, the perimeter of section 3.4).
    pub min_safety_range_m: f64,
    /// Outer bound of the safety range, m (0.80, the perimeter of section 3.4).
    pub max_safety_range_m: f64,
    /// Horizon over which a command is turned into a direction of travel, s (1.0).
    pub lookahead_s: f64,
}

impl Default for PotentialFieldParams {
    fn default() -> Self {
        PotentialFieldParams {
            alpha: 0.51,
            beta_per_cm: 0.271,
            omega_s_per_m: 14.8,
            epsilon: 0.05,
            min_safety_range_m: 0.27,
            max_safety_range_m: 0.80,
            lookahead_s: 1.0,
        }
    }
}

impl PotentialFieldParams {
    /// Checks every constant is usable.
    pub fn validate(&self) -> Result<(), ControlError> {
        check_positive("alpha", self.alpha)?;
        check_positive("beta_per_cm", self.beta_per_cm)?;
        check_positive("omega_s_per_m", self.omega_s_per_m)?;
        check_positive("epsilon", self.epsilon)?;
        check_positive("min_safety_range_m", self.min_safety_range_m)?;
        check_positive("max_safety_range_m", self.max_safety_range_m)?;
        check_positive("lookahead_s", self.lookahead_s)?;
        if self.min_safety_range_m > self.max_safety_range_m {
            return Err(ControlError::BadParameter {
                name: "min_safety_range_m",
                value: self.min_safety_range_m,
                why: "must not exceed max_safety_range_m",
            });
        }
        Ok(())
    }

    /// `|F_i| / |F_a|` for an echo at `distance_m` while moving at `speed_mps` (equation 3.2).
    pub fn force_ratio(&self, distance_m: f64, speed_mps: f64) -> f64 {
        let distance_cm = distance_m * 100.0;
        self.alpha * (-self.beta_per_cm * distance_cm + self.omega_s_per_m * speed_mps.abs()).exp()
    }

    /// The safety range at `speed_mps`, m: readings beyond it are ignored.
    pub fn safety_range_m(&self, speed_mps: f64) -> f64 {
        let cm = (self.omega_s_per_m * speed_mps.abs() - (self.epsilon / self.alpha).ln())
            / self.beta_per_cm;
        (cm / 100.0).clamp(self.min_safety_range_m, self.max_safety_range_m)
    }
}

/// The thesis's potential-field shared controller over a ring of sonars.
#[derive(Debug, Clone)]
pub struct PotentialField {
    params: PotentialFieldParams,
    mounts: Vec<SensorMount>,
}

/// The resultant repulsion of one period and how many readings produced it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Repulsion {
    /// `F_r` in the chair frame, same unit as `F_a` (m/s).
    pub force_chair: Vector2<f64>,
    /// Echoes inside the safety range.
    pub active_readings: usize,
}

impl PotentialField {
    /// A controller for sonars at `mounts` (`t_chair_sonar`, x along the acoustic axis).
    pub fn new(
        params: PotentialFieldParams,
        mounts: Vec<SensorMount>,
    ) -> Result<Self, ControlError> {
        params.validate()?;
        Ok(PotentialField { params, mounts })
    }

    /// The constants in use.
    pub fn params(&self) -> &PotentialFieldParams {
        &self.params
    }

    /// Equations 3.1-3.3: the summed repulsion for an attractive force of magnitude `fa`.
    pub fn repulsion(
        &self,
        sonar_m: &[Option<f64>],
        speed_mps: f64,
        fa: f64,
    ) -> Result<Repulsion, ControlError> {
        field_repulsion(
            &self.mounts,
            sonar_m,
            Point2::origin(),
            speed_mps,
            |speed| self.params.safety_range_m(speed),
            |d, speed| self.params.force_ratio(d, speed) * fa,
        )
    }
}

/// [`sum_repulsion`] at the measured speed `speed_mps` (its sign ignored): `safety_m(speed)` is the
/// activation range, `magnitude(D, speed)` the force of one echo.
pub(crate) fn field_repulsion(
    mounts: &[SensorMount],
    sonar_m: &[Option<f64>],
    centre_chair: Point2<f64>,
    speed_mps: f64,
    safety_m: impl Fn(f64) -> f64,
    magnitude: impl Fn(f64, f64) -> f64,
) -> Result<Repulsion, ControlError> {
    let speed_mps = check_range("speed", 0, speed_mps.abs())?;
    sum_repulsion(mounts, sonar_m, centre_chair, safety_m(speed_mps), |d| {
        magnitude(d, speed_mps)
    })
}

/// Equations 3.1 and 3.3: each echo within `safety_m` on its sonar's axis pushes along
/// `O_i -> centre_chair` with magnitude `magnitude(D_i)`; the pushes add up.
pub(crate) fn sum_repulsion(
    mounts: &[SensorMount],
    sonar_m: &[Option<f64>],
    centre_chair: Point2<f64>,
    safety_m: f64,
    magnitude: impl Fn(f64) -> f64,
) -> Result<Repulsion, ControlError> {
    if sonar_m.len() != mounts.len() {
        return Err(ControlError::SonarCount {
            expected: mounts.len(),
            got: sonar_m.len(),
        });
    }
    let mut force_chair = Vector2::zeros();
    let mut active_readings = 0;
    for (index, (mount, reading)) in mounts.iter().zip(sonar_m).enumerate() {
        let Some(distance_m) = *reading else { continue };
        let distance_m = check_range("sonar", index, distance_m)?;
        if distance_m > safety_m {
            continue;
        }
        let o_chair = mount * Point2::new(distance_m, 0.0);
        let Some(away) = (centre_chair - o_chair).try_normalize(1e-9) else {
            continue;
        };
        force_chair += away * magnitude(distance_m);
        active_readings += 1;
    }
    Ok(Repulsion {
        force_chair,
        active_readings,
    })
}

impl SharedController for PotentialField {
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError> {
        let user = input.user.validate()?;
        let intent = MotionIntent::from_command(user, self.params.lookahead_s);
        let repulsion = self.repulsion(input.sonar_m, input.speed_mps, intent.speed_mps)?;
        if repulsion.active_readings == 0 || intent.sign == 0.0 {
            // Free space (or spinning in place, where F_a = 0): the user keeps full control.
            return Ok(SharedOutput {
                command: user,
                intervention: Intervention::default(),
            });
        }
        // Equation 3.4, then back to a command in the motion frame.
        let total = intent.to_motion_frame(intent.force_chair() + repulsion.force_chair);
        let raw_direction = total.y.atan2(total.x);
        let half_pi = std::f64::consts::FRAC_PI_2;
        // Never faster than the user, and slower as F_t turns away from the travel direction, down
        // to a stop when the obstacles push harder than the user pulls.
        let along = (raw_direction.cos().max(0.0) / intent.direction_rad.cos().max(1e-9)).min(1.0);
        let corrected = MotionIntent {
            sign: intent.sign,
            speed_mps: total.norm().min(intent.speed_mps) * along,
            direction_rad: raw_direction.clamp(-half_pi, half_pi),
        };
        let command = corrected.to_command(self.params.lookahead_s);
        Ok(SharedOutput {
            command,
            intervention: Intervention::between(user, command, repulsion.active_readings),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::VelocityCommand;
    use nalgebra::{Isometry2, Vector2 as V2};

    /// Four sonars at the corners of a 1 m x 0.6 m chair, looking front, left, right, back.
    fn ring() -> Vec<SensorMount> {
        vec![
            Isometry2::new(V2::new(0.5, 0.0), 0.0),
            Isometry2::new(V2::new(0.0, 0.3), std::f64::consts::FRAC_PI_2),
            Isometry2::new(V2::new(0.0, -0.3), -std::f64::consts::FRAC_PI_2),
            Isometry2::new(V2::new(-0.5, 0.0), std::f64::consts::PI),
        ]
    }

    fn field() -> PotentialField {
        PotentialField::new(PotentialFieldParams::default(), ring()).unwrap()
    }

    #[test]
    fn thesis_constants_span_the_perimeter() {
        let p = PotentialFieldParams::default();
        // Force equals the user's at 25 cm / 0.5 m/s, 79 cm / 1.5 m/s.
        assert!((p.force_ratio(0.248, 0.5) - 1.0).abs() < 0.05);
        assert!((p.force_ratio(0.794, 1.5) - 1.0).abs() < 0.05);
        assert_eq!(p.safety_range_m(0.0), 0.27);
        assert_eq!(p.safety_range_m(3.0), 0.80);
        assert!(p.safety_range_m(0.8) > p.safety_range_m(0.5));
    }

    #[test]
    fn forces_point_away_from_obstacles() {
        let f = field();
        let fa = 0.8;
        for (index, away) in [
            (0, V2::new(-1.0, 0.0)),
            (1, V2::new(0.0, -1.0)),
            (2, V2::new(0.0, 1.0)),
            (3, V2::new(1.0, 0.0)),
        ] {
            let mut sonar = [None; 4];
            sonar[index] = Some(0.2);
            let r = f.repulsion(&sonar, 0.8, fa).unwrap();
            assert_eq!(r.active_readings, 1);
            assert!(
                r.force_chair.dot(&away) > 0.99 * r.force_chair.norm(),
                "sonar {index}: {:?}",
                r.force_chair
            );
        }
    }

    #[test]
    fn forces_vanish_outside_the_safety_range() {
        let f = field();
        let speed = 0.5;
        let safety = f.params().safety_range_m(speed);
        let r = f
            .repulsion(
                &[Some(safety + 0.01), Some(2.0), None, Some(5.0)],
                speed,
                1.0,
            )
            .unwrap();
        assert_eq!(r.active_readings, 0);
        assert_eq!(r.force_chair, V2::zeros());
        let r = f
            .repulsion(&[Some(safety - 0.01), None, None, None], speed, 1.0)
            .unwrap();
        assert_eq!(r.active_readings, 1);
    }

    #[test]
    fn no_intervention_in_free_space() {
        let mut f = field();
        let user = VelocityCommand::new(0.9, 0.37);
        let out = f
            .step(&SharedInput {
                user,
                speed_mps: 0.9,
                sonar_m: &[Some(1.5), None, Some(0.9), Some(3.0)],
                points_chair: &[],
                motion: None,
            })
            .unwrap();
        assert_eq!(out.command, user);
        assert!(!out.intervention.changed());
    }

    #[test]
    fn obstacle_ahead_slows_and_obstacle_left_turns_right() {
        let mut f = field();
        let user = VelocityCommand::new(0.6, 0.0);
        let ahead = f
            .step(&SharedInput {
                user,
                speed_mps: 0.6,
                sonar_m: &[Some(0.2), None, None, None],
                points_chair: &[],
                motion: None,
            })
            .unwrap();
        assert!(ahead.command.linear_mps < 0.6 && ahead.command.linear_mps >= 0.0);
        assert!(ahead.intervention.changed());
        let left = f
            .step(&SharedInput {
                user,
                speed_mps: 0.6,
                sonar_m: &[None, Some(0.2), None, None],
                points_chair: &[],
                motion: None,
            })
            .unwrap();
        assert!(left.command.angular_radps < 0.0, "{left:?}");
        assert!(left.command.linear_mps <= 0.6);
    }

    #[test]
    fn bad_readings_are_errors() {
        let mut f = field();
        let user = VelocityCommand::new(0.5, 0.0);
        let bad = f.step(&SharedInput {
            user,
            speed_mps: 0.5,
            sonar_m: &[Some(f64::NAN), None, None, None],
            points_chair: &[],
            motion: None,
        });
        assert!(matches!(
            bad,
            Err(ControlError::BadReading { index: 0, .. })
        ));
        let short = f.step(&SharedInput {
            user,
            speed_mps: 0.5,
            sonar_m: &[None],
            points_chair: &[],
            motion: None,
        });
        assert!(matches!(
            short,
            Err(ControlError::SonarCount {
                expected: 4,
                got: 1
            })
        ));
    }
}
