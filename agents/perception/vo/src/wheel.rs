//! Differential-drive dead reckoning from encoder ticks with the probabilistic odometry motion
//! model (Thrun, Burgard, Fox, "Probabilistic Robotics", 5.4; thesis 3.3.2): the pose estimate
//! carries a covariance that grows with the distance travelled and the angle turned.

use iw_body::{Odometry, WheelGeometry};
use nalgebra::{Isometry2, Matrix3, Vector2, Vector3};

/// A planar pose: position in metres and heading in radians (counter-clockwise from x).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Pose2 {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// Heading, rad, wrapped to (-pi, pi].
    pub theta: f64,
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

impl Pose2 {
    /// A pose.
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Pose2 {
            x,
            y,
            theta: wrap_angle(theta),
        }
    }

    /// `self ⊕ delta`: applies a motion expressed in this pose's own frame.
    pub fn compose(&self, delta: &Pose2) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2::new(
            self.x + c * delta.x - s * delta.y,
            self.y + s * delta.x + c * delta.y,
            self.theta + delta.theta,
        )
    }

    /// `self^-1 ⊕ other`: `other` seen from this pose's frame.
    pub fn between(&self, other: &Pose2) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        let (dx, dy) = (other.x - self.x, other.y - self.y);
        Pose2::new(c * dx + s * dy, -s * dx + c * dy, other.theta - self.theta)
    }

    /// `self^-1`: the motion that undoes this one (`self^-1 ⊕ self` is no motion).
    pub fn inverse(&self) -> Pose2 {
        self.between(&Pose2::default())
    }
}

/// Drive geometry and the motion model's noise parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DiffDriveParams {
    /// Drive wheel radius, m.
    pub wheel_radius_m: f64,
    /// Distance between the wheels' contact points, m.
    pub track_m: f64,
    /// Encoder ticks per wheel revolution.
    pub ticks_per_rev: f64,
    /// Motion model alphas (Thrun 5.4): rotation noise from rotation (rad^2/rad^2), from
    /// translation (rad^2/m^2), translation noise from translation (m^2/m^2), from rotation (m^2/rad^2).
    pub alpha: [f64; 4],
}

impl Default for DiffDriveParams {
    /// The chair's nominal drive geometry ([`WheelGeometry`]'s default), and noise of a few
    /// percent of the motion.
    fn default() -> Self {
        let geometry = WheelGeometry::default();
        DiffDriveParams {
            wheel_radius_m: geometry.wheel_radius_m,
            track_m: geometry.track_m,
            ticks_per_rev: geometry.ticks_per_rev,
            alpha: [0.01, 0.002, 0.01, 0.002],
        }
    }
}

impl DiffDriveParams {
    /// The drive geometry alone.
    pub fn geometry(&self) -> WheelGeometry {
        WheelGeometry {
            track_m: self.track_m,
            wheel_radius_m: self.wheel_radius_m,
            ticks_per_rev: self.ticks_per_rev,
        }
    }
}

/// Slip that follows the wheels' acceleration: a wheel that speeds up or slows down loses a
/// fraction of its travel proportional to its acceleration (the tyre's grip is used up by the
/// torque). Thrun's alphas scale with the step itself and cannot express it: a turn on the spot
/// and a straight drive at constant speed slip alike per metre, the moment the wheels change
/// speed does not. Each odometry step knows the wheels' speeds in this step and the last
/// ([`WheelRates`]), so their acceleration. The loss is one-sided (a wheel never gains travel by
/// accelerating), so it is taken off the step as a known loss ([`Self::corrected`]), and only
/// what is unsure of it is noise ([`Self::covariance`]); left as zero-mean noise it would be a
/// bias that accumulates over each speed change.
///
/// The speeds need each step's own duration. A world process steps when its timer fires, 40 or
/// 60 ms apart for a 50 ms period, and moves the chairs by the time that passed; taken as
/// [`Self::period_s`] each, those steps' travel alternated by a fifth, read as several m/s² of
/// acceleration back and forth (4 m/s² at 0.5 m/s if they strictly alternate), and the
/// one-sided loss of it shortened the drive: across processes a chair dead-reckoning at
/// 0.5 m/s fell 11 cm behind in 4.4 m (2.5 %) with a standard deviation of 1.3 cm, and the
/// laser's scans, back, were gated out until it was taken for lost.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AccelerationSlip {
    /// Fraction of a wheel's travel lost per m/s² of its acceleration.
    pub per_mps2: f64,
    /// Nominal time between odometry steps, s: how long a step given without its duration took.
    pub period_s: f64,
    /// Distance between the wheels' contact points, m: splits a step into each wheel's travel.
    pub track_m: f64,
}

/// Each wheel's mean speed over one odometry step and the step's duration: what the next
/// step's acceleration is measured against. The default is rest.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WheelRates {
    /// Left wheel, m/s.
    pub left_mps: f64,
    /// Right wheel, m/s.
    pub right_mps: f64,
    /// How long the step took, s (zero: none yet).
    pub duration_s: f64,
}

impl AccelerationSlip {
    /// Each wheel's travel (left, right) in `step`, m.
    pub fn wheels(&self, step: &OdometryStep) -> (f64, f64) {
        let half_turn_m = 0.5 * (step.rot1 + step.rot2) * self.track_m;
        (step.trans - half_turn_m, step.trans + half_turn_m)
    }

    /// Each wheel's mean speed over `step`, which took `duration_s`.
    pub fn rates(&self, step: &OdometryStep, duration_s: f64) -> WheelRates {
        let (left, right) = self.wheels(step);
        WheelRates {
            left_mps: left / duration_s,
            right_mps: right / duration_s,
            duration_s,
        }
    }

    /// Each wheel's travel lost to slip in `step`, which took `duration_s` after a step at
    /// `previous`: each wheel's acceleration is the change of its mean speed over the time
    /// between the two steps' middles.
    pub fn loss(&self, step: &OdometryStep, duration_s: f64, previous: WheelRates) -> (f64, f64) {
        let now = self.rates(step, duration_s);
        // from rest: as if the step before took as long
        let before_s = if previous.duration_s > 0.0 {
            previous.duration_s
        } else {
            duration_s
        };
        let between_s = 0.5 * (duration_s + before_s);
        let (left, right) = self.wheels(step);
        let lost = |travel: f64, speed: f64, before: f64| {
            self.per_mps2 * ((speed - before) / between_s).abs() * travel
        };
        (
            lost(left, now.left_mps, previous.left_mps),
            lost(right, now.right_mps, previous.right_mps),
        )
    }

    /// `step` with each wheel's expected loss taken off.
    pub fn corrected(
        &self,
        step: &OdometryStep,
        duration_s: f64,
        previous: WheelRates,
    ) -> OdometryStep {
        let (left, right) = self.wheels(step);
        let (loss_l, loss_r) = self.loss(step, duration_s, previous);
        OdometryStep::from_wheels(left - loss_l, right - loss_r, self.track_m)
    }

    /// Covariance of (rot1, trans, rot2) that the slip in `step` leaves once its expected loss
    /// is taken off ([`Self::corrected`]): half the loss, at one standard deviation. The
    /// acceleration is known as the change of speed from one step to the next, the mean of
    /// two steps' accelerations, so where a speed change starts or ends it is off by about
    /// half (a standard deviation of a full loss, tried on the experiment's tour, made the
    /// filter no more consistent: NEES pass rate 0.870 against 0.887 on seed 2).
    pub fn covariance(
        &self,
        step: &OdometryStep,
        duration_s: f64,
        previous: WheelRates,
    ) -> Matrix3<f64> {
        let (loss_l, loss_r) = self.loss(step, duration_s, previous);
        let (var_l, var_r) = ((0.5 * loss_l).powi(2), (0.5 * loss_r).powi(2));
        // trans = (l + r) / 2; rot1 = rot2 = (r - l) / (2 track): one turn split in two halves
        let (a, b) = (0.5, 0.5 / self.track_m);
        let var_trans = a * a * (var_l + var_r);
        let var_rot = b * b * (var_l + var_r);
        let cov_rot_trans = a * b * (var_r - var_l);
        Matrix3::new(
            var_rot,
            cov_rot_trans,
            var_rot,
            cov_rot_trans,
            var_trans,
            cov_rot_trans,
            var_rot,
            cov_rot_trans,
            var_rot,
        )
    }
}

/// One motion step in the odometry model's terms: turn, drive straight, turn.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OdometryStep {
    /// First rotation, rad.
    pub rot1: f64,
    /// Straight-line distance, m (negative when reversing).
    pub trans: f64,
    /// Second rotation, rad.
    pub rot2: f64,
}

impl OdometryStep {
    /// The step from wheel travel: the mid-point arc approximation (half the turn before, half after).
    pub fn from_wheels(left_m: f64, right_m: f64, track_m: f64) -> Self {
        let dtheta = (right_m - left_m) / track_m;
        OdometryStep {
            rot1: 0.5 * dtheta,
            trans: 0.5 * (left_m + right_m),
            rot2: 0.5 * dtheta,
        }
    }

    /// The motion in the start pose's frame.
    pub fn as_delta(&self) -> Pose2 {
        let (s, c) = self.rot1.sin_cos();
        Pose2::new(self.trans * c, self.trans * s, self.rot1 + self.rot2)
    }

    /// Covariance of (rot1, trans, rot2) under the model's alphas (Thrun table 5.6).
    pub fn covariance(&self, alpha: &[f64; 4]) -> Matrix3<f64> {
        let (r1, t, r2) = (
            self.rot1 * self.rot1,
            self.trans * self.trans,
            self.rot2 * self.rot2,
        );
        Matrix3::from_diagonal(&Vector3::new(
            alpha[0] * r1 + alpha[1] * t,
            alpha[2] * t + alpha[3] * (r1 + r2),
            alpha[0] * r2 + alpha[1] * t,
        ))
    }

    /// Jacobians of the motion at heading `theta`: with respect to the pose (G) and to the step's
    /// (rot1, trans, rot2) (V).
    pub fn jacobians(&self, theta: f64) -> (Matrix3<f64>, Matrix3<f64>) {
        let (s, c) = (theta + self.rot1).sin_cos();
        let g = Matrix3::new(
            1.0,
            0.0,
            -self.trans * s,
            0.0,
            1.0,
            self.trans * c,
            0.0,
            0.0,
            1.0,
        );
        let v = Matrix3::new(
            -self.trans * s,
            c,
            0.0,
            self.trans * c,
            s,
            0.0,
            1.0,
            0.0,
            1.0,
        );
        (g, v)
    }

    /// Applies the step to `pose` and propagates `covariance`: `G P G^T + V M V^T`.
    pub fn propagate(
        &self,
        pose: &Pose2,
        covariance: &Matrix3<f64>,
        alpha: &[f64; 4],
    ) -> (Pose2, Matrix3<f64>) {
        let (g, v) = self.jacobians(pose.theta);
        let next = pose.compose(&self.as_delta());
        (
            next,
            g * covariance * g.transpose() + v * self.covariance(alpha) * v.transpose(),
        )
    }
}

/// Dead reckoning from cumulative encoder counts (`iw_body::Odometry`) with the covariance of the
/// probabilistic motion model.
#[derive(Debug, Clone)]
pub struct WheelOdometry {
    params: DiffDriveParams,
    dead_reckoning: Odometry,
    covariance: Matrix3<f64>,
}

impl WheelOdometry {
    /// Starts at `pose` with zero uncertainty.
    pub fn new(params: DiffDriveParams, pose: Pose2) -> Self {
        let start = Isometry2::new(Vector2::new(pose.x, pose.y), pose.theta);
        WheelOdometry {
            params,
            dead_reckoning: Odometry::new(params.geometry(), start),
            covariance: Matrix3::zeros(),
        }
    }

    /// Feeds the cumulative tick counts of both wheels; returns the step since the last call
    /// (`None` on the first call, which only latches the counters).
    pub fn update(&mut self, left_ticks: i64, right_ticks: i64) -> Option<OdometryStep> {
        let before = self.pose();
        let travel = self.dead_reckoning.advance(left_ticks, right_ticks)?;
        let step = OdometryStep::from_wheels(travel.left_m, travel.right_m, self.params.track_m);
        // The pose is the dead reckoning's; the model contributes the covariance.
        self.covariance = step
            .propagate(&before, &self.covariance, &self.params.alpha)
            .1;
        Some(step)
    }

    /// Dead-reckoned pose.
    pub fn pose(&self) -> Pose2 {
        let t = self.dead_reckoning.t_world_body();
        Pose2::new(t.translation.x, t.translation.y, t.rotation.angle())
    }

    /// Covariance of (x, y, theta).
    pub fn covariance(&self) -> Matrix3<f64> {
        self.covariance
    }

    /// Drive geometry and noise.
    pub fn params(&self) -> &DiffDriveParams {
        &self.params
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_and_turn_in_place() {
        let params = DiffDriveParams::default();
        let ticks_per_m = params.ticks_per_rev / (std::f64::consts::TAU * params.wheel_radius_m);
        let mut odo = WheelOdometry::new(params, Pose2::default());
        assert!(odo.update(0, 0).is_none());
        let one_m = (ticks_per_m).round() as i64;
        odo.update(one_m, one_m);
        assert!((odo.pose().x - 1.0).abs() < 1e-4 && odo.pose().y.abs() < 1e-9);
        // Turn in place by +90 deg: right wheel forward, left back, each a quarter of pi*track.
        let arc = (std::f64::consts::FRAC_PI_2 * 0.5 * params.track_m * ticks_per_m).round() as i64;
        odo.update(one_m - arc, one_m + arc);
        assert!((odo.pose().theta - std::f64::consts::FRAC_PI_2).abs() < 1e-3);
        assert!((odo.pose().x - 1.0).abs() < 1e-3);
    }

    #[test]
    fn covariance_grows_with_travel() {
        let params = DiffDriveParams::default();
        let mut odo = WheelOdometry::new(params, Pose2::default());
        odo.update(0, 0);
        let mut last_trace = 0.0;
        for i in 1..=20 {
            odo.update(i * 2000, i * 2100);
            let trace = odo.covariance().trace();
            assert!(trace > last_trace, "step {i}: {trace} <= {last_trace}");
            last_trace = trace;
        }
        let eig = odo.covariance().symmetric_eigenvalues();
        assert!(
            eig.iter().all(|e| *e >= -1e-12),
            "positive semi-definite: {eig}"
        );
    }

    #[test]
    fn acceleration_slip_follows_each_wheels_acceleration() {
        const P: f64 = 0.05;
        let slip = AccelerationSlip {
            per_mps2: 0.02,
            period_s: P,
            track_m: 0.56,
        };
        // cruising: no acceleration, no slip
        let cruise = OdometryStep::from_wheels(0.025, 0.025, slip.track_m);
        let cruising = slip.rates(&cruise, P);
        assert_eq!(slip.loss(&cruise, P, cruising), (0.0, 0.0));
        assert_eq!(slip.covariance(&cruise, P, cruising), Matrix3::zeros());
        assert_eq!(slip.corrected(&cruise, P, cruising), cruise);
        // both wheels speeding up at 1.2 m/s²: 2.4 % of the travel lost, the travel unsure by
        // half that, the heading not at all
        let faster = OdometryStep::from_wheels(0.028, 0.028, slip.track_m);
        let loss = 0.02 * 1.2 * 0.028;
        let (l, r) = slip.loss(&faster, P, cruising);
        assert!((l - loss).abs() < 1e-12 && (r - loss).abs() < 1e-12);
        assert!((slip.corrected(&faster, P, cruising).trans - (0.028 - loss)).abs() < 1e-12);
        let c = slip.covariance(&faster, P, cruising);
        assert!(
            (c[(1, 1)] - (0.5 * loss).powi(2) / 2.0).abs() < 1e-15,
            "{c}"
        );
        let heading = c[(0, 0)] + 2.0 * c[(0, 2)] + c[(2, 2)];
        assert!(c[(0, 1)].abs() < 1e-15 && heading > 0.0);
        // from a straight into a turn on the spot: the left wheel reverses, losing travel in
        // the other direction; the turn is unsure by the left wheel's half loss over the track
        let turn = OdometryStep::from_wheels(-0.01, 0.025, slip.track_m);
        let (l, r) = slip.wheels(&turn);
        assert!((l + 0.01).abs() < 1e-12 && (r - 0.025).abs() < 1e-12);
        let (l, r) = slip.loss(&turn, P, cruising);
        assert!((l + 0.02 * (0.035 / 0.0025) * 0.01).abs() < 1e-12 && r == 0.0);
        let corrected = slip.corrected(&turn, P, cruising);
        assert!(
            slip.wheels(&corrected).0 > -0.01,
            "the loss shortens the reversed travel"
        );
        let c = slip.covariance(&turn, P, cruising);
        let heading = c[(0, 0)] + 2.0 * c[(0, 2)] + c[(2, 2)];
        assert!(
            (heading - (0.5 * l / slip.track_m).powi(2)).abs() < 1e-15,
            "{c}"
        );
    }

    /// A world process's steps, 40 and 60 ms apart, at a constant 0.5 m/s: with each step's
    /// duration the wheels do not accelerate and lose nothing after the start; taken as the
    /// nominal 50 ms each, the alternating travel reads as 4 m/s² back and forth and the
    /// one-sided loss shortens the drive by several percent.
    #[test]
    fn uneven_steps_at_a_constant_speed_lose_nothing_with_their_durations() {
        let slip = AccelerationSlip {
            per_mps2: 0.02,
            period_s: 0.05,
            track_m: 0.56,
        };
        let (mut timed, mut nominal) = (WheelRates::default(), WheelRates::default());
        let (mut timed_m, mut nominal_m) = (0.0, 0.0);
        for k in 0..100 {
            let duration_s = if k % 2 == 0 { 0.04 } else { 0.06 };
            let step = OdometryStep::from_wheels(0.5 * duration_s, 0.5 * duration_s, slip.track_m);
            timed_m += slip.corrected(&step, duration_s, timed).trans;
            timed = slip.rates(&step, duration_s);
            nominal_m += slip.corrected(&step, slip.period_s, nominal).trans;
            nominal = slip.rates(&step, slip.period_s);
        }
        // 2.5 m driven; the start from rest at 12.5 m/s² loses 5 mm
        assert!((timed_m - (2.5 - 0.005)).abs() < 1e-9, "{timed_m} m");
        assert!(
            nominal_m < 2.4,
            "{nominal_m} m: the nominal period reads no loss"
        );
    }

    #[test]
    fn between_inverts_compose() {
        let a = Pose2::new(1.0, -2.0, 2.5);
        let d = Pose2::new(0.3, 0.1, 1.2);
        let b = a.compose(&d);
        let back = a.between(&b);
        assert!(
            (back.x - d.x).abs() < 1e-12
                && (back.y - d.y).abs() < 1e-12
                && (back.theta - d.theta).abs() < 1e-12
        );
        assert!(
            (wrap_angle(3.5 * std::f64::consts::PI) + 0.5 * std::f64::consts::PI).abs() < 1e-12
        );
    }
}
