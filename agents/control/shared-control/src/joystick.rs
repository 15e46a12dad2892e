//! The thesis's potential field read as a joystick filter (section 3.6 with section 3.4's "the
//! collision avoidance algorithm alters the joystick signal"): the `shared` paradigm.
//!
//! - `F_a` is the user's 2-D input vector (joystick deflection or head tilt, each axis in
//!   [-1, 1]): x forward, y to the left (thesis 3.6: "directly proportional to the current user
//!   input").
//! - Each sonar echo `D_i` places `O_i` on the acoustic axis; it pushes along `O_i -> C` with
//!   `|F_i| = alpha exp(-beta D_i + omega Sp) |F_a|` (equations 3.1-3.2), C at the centre of the
//!   footprint rectangle ("Robot Center Point", figure 3.7).
//! - `F_t = F_a + sum F_i` (3.3-3.4) is then a joystick vector again, and [`JoystickMapping`] turns
//!   it into `(v, omega)` the way the joystick maps its own input: forward component to linear
//!   speed (negative = reverse, allowed), lateral component to turn rate.
//!
//! What the text leaves open, and what we assume (the sensitivity sweep of the experiment varies
//! each; see `docs/results/shared-control.md`):
//! - units of `D` and `Sp`: centimetres and m/s ([`ThesisFieldParams::distance_unit_m`],
//!   [`ThesisFieldParams::speed_unit_mps`]); with the thesis's constants the repulsion equals the
//!   user's pull at 25 cm at 0.5 m/s and 79 cm at 1.5 m/s, inside the 27-80 cm perimeter of
//!   section 3.4; D in metres would repel from every wall of a room, Sp in cm/s would saturate;
//! - the activation range ("repulsive forces start acting just when a safety range is reached";
//!   figure 3.8 is not in the text we have): a reading acts when its force is at least
//!   `epsilon |F_a|` (5 %), that distance bounded to 27-80 cm (the perimeter of section 3.4);
//! - the mapping: linear to the forward axis, turn rate to the lateral axis, each clamped to full
//!   deflection; the maxima are [`JoystickMapping`]'s (assumed, the text gives no speeds);
//! - `Sp` is the measured linear speed's magnitude;
//! - nothing caps `F_t`: it may reverse the chair and exceed the user's deflection, up to the
//!   joystick's full deflection ([`ThesisFieldParams::allow_reverse`],
//!   [`ThesisFieldParams::cap_at_user`] switch these off for the sweep).

use nalgebra::{Point2, Vector2};

use crate::error::check_positive;
use crate::potential::field_repulsion;
use crate::{
    ControlError, Intervention, PotentialFieldParams, SensorMount, SharedController, SharedInput,
    SharedOutput, VelocityCommand,
};

/// How a 2-D input vector (x forward, y left, each in [-1, 1]) becomes a velocity command, as a
/// proportional powered-wheelchair joystick does: `v = x v_max` (reverse at its own maximum),
/// `omega = y omega_max`. Invertible inside the limits.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JoystickMapping {
    /// Linear speed at full forward deflection, m/s (0.8).
    pub max_forward_mps: f64,
    /// Linear speed at full backward deflection, m/s (0.4: chairs reverse slower).
    pub max_reverse_mps: f64,
    /// Turn rate at full lateral deflection, rad/s (1.0).
    pub max_angular_radps: f64,
}

impl Default for JoystickMapping {
    fn default() -> Self {
        JoystickMapping {
            max_forward_mps: 0.8,
            max_reverse_mps: 0.4,
            max_angular_radps: 1.0,
        }
    }
}

impl JoystickMapping {
    /// Checks the maxima are positive and finite.
    pub fn validate(&self) -> Result<(), ControlError> {
        check_positive("max_forward_mps", self.max_forward_mps)?;
        check_positive("max_reverse_mps", self.max_reverse_mps)?;
        check_positive("max_angular_radps", self.max_angular_radps)?;
        Ok(())
    }

    /// The command for input vector `input` (each axis clamped to full deflection).
    pub fn to_command(&self, input: Vector2<f64>) -> VelocityCommand {
        let x = input.x.clamp(-1.0, 1.0);
        let y = input.y.clamp(-1.0, 1.0);
        let linear = if x >= 0.0 {
            x * self.max_forward_mps
        } else {
            x * self.max_reverse_mps
        };
        VelocityCommand::new(linear, y * self.max_angular_radps)
    }

    /// The input vector that gives `command` (the inverse of [`JoystickMapping::to_command`]).
    pub fn to_input(&self, command: VelocityCommand) -> Vector2<f64> {
        let x = if command.linear_mps >= 0.0 {
            command.linear_mps / self.max_forward_mps
        } else {
            command.linear_mps / self.max_reverse_mps
        };
        Vector2::new(x, command.angular_radps / self.max_angular_radps)
    }
}

/// Where the repulsions point (the thesis's "Robot Center Point" C).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FieldCentre {
    /// The centre of the footprint rectangle (our reading of figure 3.7).
    Footprint,
    /// The centre of the drive axle (the centre of rotation).
    Axle,
}

/// Constants and open assumptions of the joystick-filter field; defaults are the thesis's
/// constants with the assumptions in the module docs.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ThesisFieldParams {
    /// alpha, beta, omega, epsilon and the 27-80 cm bounds (beta is per `distance_unit_m`, omega
    /// per `speed_unit_mps`; the `lookahead_s` field is not used here).
    pub constants: PotentialFieldParams,
    /// The unit `D` is measured in, m (0.01: centimetres).
    pub distance_unit_m: f64,
    /// The unit `Sp` is measured in, m/s (1.0).
    pub speed_unit_mps: f64,
    /// Where C is.
    pub centre: FieldCentre,
    /// Input vector to command.
    pub mapping: JoystickMapping,
    /// Whether `F_t` may reverse the chair when the user drives forward (true: the thesis's
    /// equations leave nothing that stops it).
    pub allow_reverse: bool,
    /// Whether `|F_t|` is capped at `|F_a|` (false: the thesis caps nothing; the joystick's full
    /// deflection still does).
    pub cap_at_user: bool,
}

impl Default for ThesisFieldParams {
    fn default() -> Self {
        ThesisFieldParams {
            constants: PotentialFieldParams::default(),
            distance_unit_m: 0.01,
            speed_unit_mps: 1.0,
            centre: FieldCentre::Footprint,
            mapping: JoystickMapping::default(),
            allow_reverse: true,
            cap_at_user: false,
        }
    }
}

impl ThesisFieldParams {
    /// Checks every constant is usable.
    pub fn validate(&self) -> Result<(), ControlError> {
        self.constants.validate()?;
        check_positive("distance_unit_m", self.distance_unit_m)?;
        check_positive("speed_unit_mps", self.speed_unit_mps)?;
        self.mapping.validate()
    }

    /// `|F_i| / |F_a|` for an echo at `distance_m` while moving at `speed_mps` (equation 3.2).
    pub fn force_ratio(&self, distance_m: f64, speed_mps: f64) -> f64 {
        let c = &self.constants;
        c.alpha
            * (-c.beta_per_cm * distance_m / self.distance_unit_m
                + c.omega_s_per_m * speed_mps.abs() / self.speed_unit_mps)
                .exp()
    }

    /// Readings farther than this act not at all, m: where the force falls to `epsilon |F_a|`,
    /// bounded to the perimeter the sonars cover.
    pub fn safety_range_m(&self, speed_mps: f64) -> f64 {
        let c = &self.constants;
        let units = (c.omega_s_per_m * speed_mps.abs() / self.speed_unit_mps
            - (c.epsilon / c.alpha).ln())
            / c.beta_per_cm;
        (units * self.distance_unit_m).clamp(c.min_safety_range_m, c.max_safety_range_m)
    }
}

/// The thesis's shared control as a joystick filter on a ring of sonars.
#[derive(Debug, Clone)]
pub struct ThesisField {
    params: ThesisFieldParams,
    mounts: Vec<SensorMount>,
    centre_chair: Point2<f64>,
}

impl ThesisField {
    /// A controller for sonars at `mounts` on a chair whose footprint reaches `front_m` ahead of
    /// and `rear_m` behind the axle.
    pub fn new(
        params: ThesisFieldParams,
        mounts: Vec<SensorMount>,
        front_m: f64,
        rear_m: f64,
    ) -> Result<Self, ControlError> {
        params.validate()?;
        check_positive("front_m", front_m)?;
        check_positive("rear_m", rear_m)?;
        let centre_chair = match params.centre {
            FieldCentre::Footprint => Point2::new((front_m - rear_m) / 2.0, 0.0),
            FieldCentre::Axle => Point2::origin(),
        };
        Ok(ThesisField {
            params,
            mounts,
            centre_chair,
        })
    }

    /// The constants in use.
    pub fn params(&self) -> &ThesisFieldParams {
        &self.params
    }
}

impl SharedController for ThesisField {
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError> {
        let user = input.user.validate()?;
        let fa_input = self.params.mapping.to_input(user);
        // Equations 3.1-3.3 about C, `|F_a|` in input units.
        let repulsion = field_repulsion(
            &self.mounts,
            input.sonar_m,
            self.centre_chair,
            input.speed_mps,
            |speed| self.params.safety_range_m(speed),
            |d, speed| self.params.force_ratio(d, speed) * fa_input.norm(),
        )?;
        if repulsion.active_readings == 0 || fa_input.norm() == 0.0 {
            // Outside the safety range (or no input, |F_a| = 0): the user's command, bit for bit.
            return Ok(SharedOutput {
                command: user,
                intervention: Intervention::default(),
            });
        }
        let mut total = fa_input + repulsion.force_chair;
        if !self.params.allow_reverse && fa_input.x >= 0.0 {
            total.x = total.x.max(0.0);
        }
        if self.params.cap_at_user && total.norm() > fa_input.norm() {
            total *= fa_input.norm() / total.norm();
        }
        let command = self.params.mapping.to_command(total);
        Ok(SharedOutput {
            command,
            intervention: Intervention::between(user, command, repulsion.active_readings),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iw_body::layout::Footprint;

    fn field() -> ThesisField {
        let fp = Footprint::PROTOTYPE;
        ThesisField::new(
            ThesisFieldParams::default(),
            fp.sonar_mounts().to_vec(),
            fp.front_m,
            fp.rear_m,
        )
        .unwrap()
    }

    fn step(f: &mut ThesisField, user: VelocityCommand, sonar: &[Option<f64>]) -> SharedOutput {
        f.step(&SharedInput {
            user,
            speed_mps: user.linear_mps.abs(),
            sonar_m: sonar,
            points_chair: &[],
            motion: None,
        })
        .unwrap()
    }

    #[test]
    fn mapping_round_trips_and_clamps() {
        let m = JoystickMapping::default();
        for c in [
            VelocityCommand::new(0.5, -0.3),
            VelocityCommand::new(-0.2, 0.9),
            VelocityCommand::STOP,
        ] {
            let back = m.to_command(m.to_input(c));
            assert!((back.linear_mps - c.linear_mps).abs() < 1e-12);
            assert!((back.angular_radps - c.angular_radps).abs() < 1e-12);
        }
        let full = m.to_command(Vector2::new(3.0, -3.0));
        assert_eq!(full, VelocityCommand::new(0.8, -1.0));
        assert_eq!(m.to_command(Vector2::new(-2.0, 0.0)).linear_mps, -0.4);
    }

    #[test]
    fn free_space_is_bit_for_bit() {
        let mut f = field();
        let user = VelocityCommand::new(0.6, 0.37);
        let out = step(&mut f, user, &[None; iw_body::SONAR_COUNT]);
        assert_eq!(out.command, user);
        assert!(!out.intervention.changed());
    }

    #[test]
    fn a_close_obstacle_ahead_reverses_and_one_on_the_left_turns_right() {
        let mut f = field();
        let user = VelocityCommand::new(0.4, 0.0);
        // Sonars 0 and 1 look ahead from the front corners (figure 3.4).
        let mut sonar = [None; iw_body::SONAR_COUNT];
        sonar[0] = Some(0.05);
        sonar[1] = Some(0.05);
        let out = step(&mut f, user, &sonar);
        assert!(out.command.linear_mps < 0.0, "{out:?}");
        // A lateral sonar on the left side (positive y mount) pushes to the right: turn right.
        let mounts = Footprint::PROTOTYPE.sonar_mounts();
        let left = mounts
            .iter()
            .position(|m| {
                m.translation.y > 0.0
                    && (m.rotation.angle() - std::f64::consts::FRAC_PI_2).abs() < 0.1
            })
            .unwrap();
        let mut sonar = [None; iw_body::SONAR_COUNT];
        sonar[left] = Some(0.1);
        let out = step(&mut f, user, &sonar);
        assert!(out.command.angular_radps < 0.0, "{out:?}");
    }

    #[test]
    fn the_caps_hold_when_switched_on() {
        let fp = Footprint::PROTOTYPE;
        let mut f = ThesisField::new(
            ThesisFieldParams {
                allow_reverse: false,
                cap_at_user: true,
                ..ThesisFieldParams::default()
            },
            fp.sonar_mounts().to_vec(),
            fp.front_m,
            fp.rear_m,
        )
        .unwrap();
        let user = VelocityCommand::new(0.4, 0.2);
        let out = step(&mut f, user, &[Some(0.05); iw_body::SONAR_COUNT]);
        let m = JoystickMapping::default();
        assert!(out.command.linear_mps >= 0.0, "{out:?}");
        assert!(m.to_input(out.command).norm() <= m.to_input(user).norm() + 1e-12);
    }

    #[test]
    fn no_input_no_force() {
        let mut f = field();
        let out = step(
            &mut f,
            VelocityCommand::STOP,
            &[Some(0.05); iw_body::SONAR_COUNT],
        );
        assert_eq!(out.command, VelocityCommand::STOP);
    }

    #[test]
    fn thesis_constants_in_centimetres() {
        let p = ThesisFieldParams::default();
        assert!((p.force_ratio(0.248, 0.5) - 1.0).abs() < 0.05);
        assert_eq!(p.safety_range_m(0.0), 0.27);
        assert_eq!(p.safety_range_m(3.0), 0.80);
        let metres = ThesisFieldParams {
            distance_unit_m: 1.0,
            ..p
        };
        // D in metres: a wall 0.8 m away pushes harder than the user pulls at walking speed.
        assert!(metres.force_ratio(0.8, 0.5) > 1.0);
    }
}
