//! Fusion of wheel and visual odometry in an extended Kalman filter with stochastic cloning
//! (Roumeliotis and Burdick 2002).
//!
//! Both sensors measure *relative* motion. The state holds two planar poses: the pose at the last
//! visual-odometry frame (the clone) and the current one. Wheel steps move the current pose and
//! grow its covariance; a visual-odometry motion measures the clone-to-current displacement, which
//! correlates both; then the clone is replaced by the current pose. Feeding a drifting visual pose
//! as an absolute measurement would count the same information twice; this does not.

use nalgebra::{Isometry3, Matrix3, Matrix3x2, Matrix3x6, SMatrix, SVector, Vector3};

use crate::wheel::{AccelerationSlip, OdometryStep, Pose2, WheelRates, wrap_angle};

/// The planar motion of a robot base between two camera poses: the camera's motion expressed in
/// the base frame (`t_base_camera` is the camera mount; base z points up), reduced to x, y, yaw.
pub fn planar_motion(
    t_base_camera: &Isometry3<f64>,
    t_previous_current_camera: &Isometry3<f64>,
) -> Pose2 {
    let t_base_motion = t_base_camera * t_previous_current_camera * t_base_camera.inverse();
    let (_, _, yaw) = t_base_motion.rotation.euler_angles();
    Pose2::new(
        t_base_motion.translation.vector.x,
        t_base_motion.translation.vector.y,
        yaw,
    )
}

/// The systematic part of wheel odometry's error, carried in the filter's state: a distance
/// scale error (tyres compress, wheels slip more than they grip back) and a heading drift per
/// metre (the two wheels' radii differ). Random motion noise alone grows the covariance with the
/// square root of the distance while a bias grows the error with the distance itself, so a
/// filter without these states is overconfident as soon as it dead-reckons for a while. Both are
/// estimated while absolute updates (scans, landmarks) or visual odometry observe the motion,
/// and held, with their remaining uncertainty, while they do not.
///
/// Measured travel is corrected as `trans' = trans (1 + scale) + heading track² turn / 4` and
/// each half turn as `rot' = rot (1 + scale) + heading trans / 2`: the radius difference that
/// turns the chair by `heading` per metre on a straight (`heading track` between the wheels'
/// scales) moves it by `heading track² / 4` per radian when it turns on the spot.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WheelBias {
    /// Prior standard deviation of the distance scale error (a fraction, zero mean).
    pub scale_sigma: f64,
    /// Prior standard deviation of the heading drift, rad per metre driven.
    pub heading_sigma_rad_per_m: f64,
    /// How fast the scale error may wander: standard deviation added per square root of a metre
    /// driven.
    pub scale_walk: f64,
    /// How fast the heading drift may wander, rad/m per square root of a metre driven.
    pub heading_walk_rad_per_m: f64,
    /// Distance between the wheels' contact points, m: how a radius difference moves the chair
    /// when it turns on the spot.
    pub track_m: f64,
}

impl WheelBias {
    /// No bias states: the plain odometry motion model.
    pub const NONE: WheelBias = WheelBias {
        scale_sigma: 0.0,
        heading_sigma_rad_per_m: 0.0,
        scale_walk: 0.0,
        heading_walk_rad_per_m: 0.0,
        track_m: 0.0,
    };

    /// A powered wheelchair's pneumatic tyres: each wheel's effective radius a few percent under
    /// the nominal one, and up to a few percent apart (0.5-3 % per wheel in the simulator,
    /// plus about 1 % slip): 3 % of scale and 0.03 rad/m of heading drift (1.7 degrees a metre;
    /// a 1.7 % radius difference on a 0.56 m track) at one standard deviation, each wandering
    /// by 0.1 % (0.001 rad/m) per square root of a metre as slip varies with the floor and the
    /// acceleration.
    pub const WHEELCHAIR: WheelBias = WheelBias {
        scale_sigma: 0.03,
        heading_sigma_rad_per_m: 0.02,
        scale_walk: 0.0002,
        heading_walk_rad_per_m: 0.0002,
        track_m: iw_body::TRACK_M,
    };
}

/// The noise of one visual-odometry motion between two frames, growing with the motion: a
/// frame-to-frame estimate errs by a part of the distance and of the turn it measures (depth
/// noise, the feature matches' spread), however often frames come. A fixed covariance per frame
/// says a chair that the camera follows at 20 frames/s knows its heading 20 times better than at
/// 1 frame/s over the same drive, which made the fused covariance far smaller than the error
/// whenever only the wheels and the camera measured the motion.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VisualNoise {
    /// Standard deviation of x and y for any motion, m.
    pub floor_m: f64,
    /// Standard deviation of the heading for any motion, rad.
    pub floor_rad: f64,
    /// Standard deviation of x and y per metre of the motion.
    pub per_metre: f64,
    /// Standard deviation of the heading per radian turned.
    pub rad_per_rad: f64,
    /// Standard deviation of the heading per metre driven, rad/m.
    pub rad_per_metre: f64,
}

impl VisualNoise {
    /// The covariance of `motion` (x, y, theta), m² and rad².
    pub fn covariance(&self, motion: &Pose2) -> Matrix3<f64> {
        let d = motion.x.hypot(motion.y);
        let xy = self.floor_m + self.per_metre * d;
        let theta = self.floor_rad + self.rad_per_rad * motion.theta.abs() + self.rad_per_metre * d;
        Matrix3::from_diagonal(&Vector3::new(xy * xy, xy * xy, theta * theta))
    }
}

/// Size of the state: clone pose, current pose, wheel scale error, heading drift, visual
/// odometry's scale error.
const N: usize = 9;
type StateMatrix = SMatrix<f64, N, N>;
/// Index of the scale error (the heading drift follows it).
const BIAS: usize = 6;
/// Index of visual odometry's scale error.
const VISUAL_SCALE: usize = 8;

/// EKF over (clone pose, current pose, [`WheelBias`] states).
#[derive(Debug, Clone)]
pub struct OdometryFusion {
    clone: Pose2,
    current: Pose2,
    /// Scale error and heading drift (rad/m).
    bias: [f64; 2],
    /// Visual odometry's scale error: it measures `1 + visual_scale` times the travel.
    visual_scale: f64,
    covariance: StateMatrix,
    alpha: [f64; 4],
    walk: [f64; 2],
    /// Track for the turn's translation from the heading drift (see [`WheelBias`]).
    bias_track_m: f64,
    /// Slip with the wheels' acceleration, if modelled, and the wheels' speeds in the last step.
    slip: Option<(AccelerationSlip, WheelRates)>,
}

fn to_vec(a: &Pose2, b: &Pose2, bias: &[f64; 2], visual_scale: f64) -> SVector<f64, N> {
    SVector::<f64, N>::from_column_slice(&[
        a.x,
        a.y,
        a.theta,
        b.x,
        b.y,
        b.theta,
        bias[0],
        bias[1],
        visual_scale,
    ])
}

impl OdometryFusion {
    /// Starts at `pose` with `covariance`; wheel steps use the motion model `alpha`, with no
    /// bias states ([`WheelBias::NONE`]; see [`Self::with_bias`]).
    pub fn new(pose: Pose2, covariance: Matrix3<f64>, alpha: [f64; 4]) -> Self {
        let mut p = StateMatrix::zeros();
        for (r, c) in [(0, 0), (0, 3), (3, 0), (3, 3)] {
            p.fixed_view_mut::<3, 3>(r, c).copy_from(&covariance);
        }
        OdometryFusion {
            clone: pose,
            current: pose,
            bias: [0.0; 2],
            visual_scale: 0.0,
            covariance: p,
            alpha,
            walk: [0.0; 2],
            bias_track_m: 0.0,
            slip: None,
        }
    }

    /// Takes the slip that follows the wheels' acceleration off each wheel step and adds what is
    /// unsure of it to the motion model's noise (see [`AccelerationSlip`]); the first step after
    /// this counts as starting from rest.
    pub fn with_acceleration_slip(mut self, slip: AccelerationSlip) -> Self {
        self.slip = Some((slip, WheelRates::default()));
        self
    }

    /// Estimates the wheels' systematic error as `bias` describes (zero mean, its standard
    /// deviations as the prior), replacing any estimate so far.
    pub fn with_bias(mut self, bias: WheelBias) -> Self {
        self.bias = [0.0; 2];
        self.covariance.fixed_view_mut::<2, N>(BIAS, 0).fill(0.0);
        self.covariance.fixed_view_mut::<N, 2>(0, BIAS).fill(0.0);
        self.covariance[(BIAS, BIAS)] = bias.scale_sigma.powi(2);
        self.covariance[(BIAS + 1, BIAS + 1)] = bias.heading_sigma_rad_per_m.powi(2);
        self.walk = [bias.scale_walk, bias.heading_walk_rad_per_m];
        self.bias_track_m = bias.track_m;
        self
    }

    /// Estimates visual odometry's scale error (zero mean, prior standard deviation `sigma`),
    /// replacing any estimate so far. Visual odometry's frame-to-frame errors are not all
    /// independent: on the simulator's rendered frames its travel on straight stretches is 2.2 %
    /// short of the truth (sample building, seeds 1 and 3). Taken as noise that averages out, that
    /// error calibrated the wheels' scale 2 % low with a confidence it does not have, and along a
    /// blank corridor, where nothing else measures the travel, the filter trusted a place on the
    /// axis that was about 2 standard deviations off. With this state, visual odometry
    /// measures the wheels' scale only as well as its own scale is known: from walls and
    /// landmarks, which see both.
    pub fn with_visual_scale(mut self, sigma: f64) -> Self {
        self.visual_scale = 0.0;
        self.covariance.row_mut(VISUAL_SCALE).fill(0.0);
        self.covariance.column_mut(VISUAL_SCALE).fill(0.0);
        self.covariance[(VISUAL_SCALE, VISUAL_SCALE)] = sigma * sigma;
        self
    }

    /// Visual odometry's estimated scale error and its standard deviation.
    pub fn visual_scale(&self) -> (f64, f64) {
        (
            self.visual_scale,
            self.covariance[(VISUAL_SCALE, VISUAL_SCALE)]
                .max(0.0)
                .sqrt(),
        )
    }

    /// The fused current pose.
    pub fn pose(&self) -> Pose2 {
        self.current
    }

    /// Covariance of the current pose (x, y, theta).
    pub fn covariance(&self) -> Matrix3<f64> {
        self.covariance.fixed_view::<3, 3>(3, 3).into_owned()
    }

    /// The estimated wheel bias: scale error and heading drift (rad/m), with their standard
    /// deviations.
    pub fn bias(&self) -> ([f64; 2], [f64; 2]) {
        (
            self.bias,
            [
                self.covariance[(BIAS, BIAS)].max(0.0).sqrt(),
                self.covariance[(BIAS + 1, BIAS + 1)].max(0.0).sqrt(),
            ],
        )
    }

    /// Prediction with one wheel odometry step of the slip model's nominal period (see
    /// [`Self::predict_over`]).
    pub fn predict(&mut self, step: &OdometryStep) {
        self.predict_timed(step, None);
    }

    /// Prediction with one wheel odometry step that took `duration_s`, corrected by the
    /// acceleration's slip (if modelled; the wheels' speeds are the step's travel over its
    /// duration) and the estimated bias.
    pub fn predict_over(&mut self, step: &OdometryStep, duration_s: f64) {
        self.predict_timed(step, Some(duration_s));
    }

    fn predict_timed(&mut self, step: &OdometryStep, duration_s: Option<f64>) {
        // the slip with the wheels' acceleration taken off before the bias is applied
        let raw = *step;
        let timed = self
            .slip
            .map(|(slip, previous)| (slip, previous, duration_s.unwrap_or(slip.period_s)));
        let step = &match timed {
            Some((slip, previous, took_s)) => slip.corrected(&raw, took_s, previous),
            None => raw,
        };
        let [scale, heading] = self.bias;
        let half_drift = 0.5 * heading * step.trans;
        let turn_shift = 0.25 * self.bias_track_m.powi(2) * (step.rot1 + step.rot2);
        let corrected = OdometryStep {
            rot1: step.rot1 * (1.0 + scale) + half_drift,
            trans: step.trans * (1.0 + scale) + heading * turn_shift,
            rot2: step.rot2 * (1.0 + scale) + half_drift,
        };
        let next = self.current.compose(&corrected.as_delta());
        let (g, v) = corrected.jacobians(self.current.theta);
        // d(rot1, trans, rot2) / d(scale, heading)
        let d_step = Matrix3x2::new(
            step.rot1,
            0.5 * step.trans,
            step.trans,
            turn_shift,
            step.rot2,
            0.5 * step.trans,
        );
        let mut f = StateMatrix::identity();
        f.fixed_view_mut::<3, 3>(3, 3).copy_from(&g);
        f.fixed_view_mut::<3, 2>(3, BIAS).copy_from(&(v * d_step));
        let mut motion = step.covariance(&self.alpha);
        if let (Some((slip, previous, took_s)), Some((_, last))) = (timed, self.slip.as_mut()) {
            motion += slip.covariance(&raw, took_s, previous);
            *last = slip.rates(&raw, took_s);
        }
        let mut q = StateMatrix::zeros();
        q.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(v * motion * v.transpose()));
        let metres = step.trans.abs();
        q[(BIAS, BIAS)] = self.walk[0].powi(2) * metres;
        q[(BIAS + 1, BIAS + 1)] = self.walk[1].powi(2) * metres;
        self.covariance = f * self.covariance * f.transpose() + q;
        self.current = next;
    }

    /// Update with the visual odometry's motion since the previous visual update (`motion` in the
    /// clone's frame, `noise` its covariance); then clones the current pose for the next one.
    /// A motion whose innovation lies outside the 99.9 % chi-square gate (a tracking failure,
    /// such as a fast spin in front of a bare wall) is not fused; returns whether it was.
    pub fn update_visual(&mut self, motion: &Pose2, noise: &Matrix3<f64>) -> bool {
        let predicted = self.clone.between(&self.current);
        // visual odometry measures its scale times the translation
        let k = 1.0 + self.visual_scale;
        let (s, c) = self.clone.theta.sin_cos();
        let (dx, dy) = (self.current.x - self.clone.x, self.current.y - self.clone.y);
        let mut h = SMatrix::<f64, 3, N>::zeros();
        h.fixed_view_mut::<3, 6>(0, 0).copy_from(&Matrix3x6::new(
            -c,
            -s,
            -s * dx + c * dy,
            c,
            s,
            0.0, //
            s,
            -c,
            -c * dx - s * dy,
            -s,
            c,
            0.0, //
            0.0,
            0.0,
            -1.0,
            0.0,
            0.0,
            1.0,
        ));
        for r in 0..2 {
            for col in 0..6 {
                h[(r, col)] *= k;
            }
        }
        h[(0, VISUAL_SCALE)] = predicted.x;
        h[(1, VISUAL_SCALE)] = predicted.y;
        let innovation = Vector3::new(
            motion.x - k * predicted.x,
            motion.y - k * predicted.y,
            wrap_angle(motion.theta - predicted.theta),
        );
        let s_mat = h * self.covariance * h.transpose() + noise;
        let s_inv = s_mat
            .try_inverse()
            .filter(|s_inv| (innovation.transpose() * s_inv * innovation)[0] <= VISUAL_GATE_CHI2);
        let fused = s_inv.is_some();
        if let Some(s_inv) = s_inv {
            self.correct(&h, &innovation, &s_inv, noise);
        }
        // the clone becomes a copy of the current pose, correlated with everything as it is
        let mut t = StateMatrix::identity();
        t.fixed_view_mut::<3, 3>(0, 0).fill(0.0);
        t.fixed_view_mut::<3, 3>(0, 3).fill_with_identity();
        self.covariance = t * self.covariance * t.transpose();
        self.clone = self.current;
        fused
    }

    /// Applies a Kalman correction: `h` the measurement Jacobian, `s_inv` the innovation
    /// covariance's inverse. Joseph form keeps the covariance symmetric positive semi-definite.
    fn correct<const M: usize>(
        &mut self,
        h: &SMatrix<f64, M, N>,
        innovation: &SVector<f64, M>,
        s_inv: &SMatrix<f64, M, M>,
        noise: &SMatrix<f64, M, M>,
    ) {
        let k: SMatrix<f64, N, M> = self.covariance * h.transpose() * s_inv;
        let x = to_vec(&self.clone, &self.current, &self.bias, self.visual_scale) + k * innovation;
        self.clone = Pose2::new(x[0], x[1], x[2]);
        self.current = Pose2::new(x[3], x[4], x[5]);
        self.bias = [x[6], x[7]];
        self.visual_scale = x[VISUAL_SCALE];
        let i_kh = StateMatrix::identity() - k * h;
        self.covariance = i_kh * self.covariance * i_kh.transpose() + k * noise * k.transpose();
        self.covariance = (self.covariance + self.covariance.transpose()) * 0.5;
    }
}

impl OdometryFusion {
    /// Update with a measurement of the *current* pose alone (a scan matched to the map, a
    /// landmark's range and bearing): `innovation` is measured minus predicted, `h` its Jacobian
    /// with respect to the current (x, y, theta), `noise` its covariance. The measurement is not
    /// fused when its normalised innovation squared exceeds `gate_chi2`; returns that value and
    /// whether it was fused (`None` when the innovation covariance is singular).
    pub fn update_current<const M: usize>(
        &mut self,
        innovation: &SVector<f64, M>,
        h: &SMatrix<f64, M, 3>,
        noise: &SMatrix<f64, M, M>,
        gate_chi2: f64,
    ) -> Option<(f64, bool)> {
        let mut h_full = SMatrix::<f64, M, N>::zeros();
        h_full.fixed_view_mut::<M, 3>(0, 3).copy_from(h);
        let s_inv = (h_full * self.covariance * h_full.transpose() + noise).try_inverse()?;
        let nis = (innovation.transpose() * s_inv * innovation)[0];
        if !(nis.is_finite() && nis <= gate_chi2) {
            return Some((nis, false));
        }
        self.correct(&h_full, innovation, &s_inv, noise);
        Some((nis, true))
    }

    /// Restarts the pose at `pose` with `covariance` (a relocalisation), keeping the motion
    /// model and what is known of the wheels' bias and of visual odometry's scale (properties of
    /// the sensors, not of the pose).
    pub fn reset(&mut self, pose: Pose2, covariance: Matrix3<f64>) {
        let bias_cov = self.covariance.fixed_view::<3, 3>(BIAS, BIAS).into_owned();
        let (bias, walk, visual_scale, slip) = (self.bias, self.walk, self.visual_scale, self.slip);
        let bias_track_m = self.bias_track_m;
        *self = OdometryFusion::new(pose, covariance, self.alpha);
        self.bias = bias;
        self.walk = walk;
        self.bias_track_m = bias_track_m;
        self.visual_scale = visual_scale;
        self.slip = slip;
        self.covariance
            .fixed_view_mut::<3, 3>(BIAS, BIAS)
            .copy_from(&bias_cov);
    }
}

/// The chi-square value with 3 degrees of freedom that 99.9 % of consistent innovations stay
/// under.
const VISUAL_GATE_CHI2: f64 = 16.27;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn gaussian(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
        sigma * iw_stats::standard_normal(rng)
    }

    fn rmse(estimate: &[Pose2], truth: &[Pose2]) -> f64 {
        let sum: f64 = estimate
            .iter()
            .zip(truth)
            .map(|(e, t)| (e.x - t.x).powi(2) + (e.y - t.y).powi(2))
            .sum();
        (sum / truth.len() as f64).sqrt()
    }

    /// A wheelchair drives a figure of eight for 120 s at 10 Hz. Wheel travel has 1 mm of noise
    /// per wheel and step (slip: the heading random-walks), visual odometry at 3.3 Hz has 2 cm of
    /// translation noise and 0.3 deg of heading noise per frame; both are unbiased and the filter
    /// is told their noise levels.
    fn run(seed: u64) -> (f64, f64, f64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let track = iw_body::TRACK_M;
        let alpha = [0.01, 0.002, 0.0005, 0.0005];
        let vo_noise = Matrix3::from_diagonal(&Vector3::new(
            0.02f64.powi(2),
            0.02f64.powi(2),
            0.3f64.to_radians().powi(2),
        ));
        let (mut truth, mut wheel, mut vo) = (Pose2::default(), Pose2::default(), Pose2::default());
        let mut fusion = OdometryFusion::new(Pose2::default(), Matrix3::zeros(), alpha);
        let mut vo_clone_truth = truth;
        let (mut t_all, mut w_all, mut v_all, mut f_all) = (vec![], vec![], vec![], vec![]);
        for k in 0..1200 {
            let time = k as f64 * 0.1;
            let v = 0.5;
            let omega = 0.35 * (time * std::f64::consts::TAU / 40.0).sin();
            let (left, right) = (
                (v - 0.5 * omega * track) * 0.1,
                (v + 0.5 * omega * track) * 0.1,
            );
            let true_step = OdometryStep::from_wheels(left, right, track);
            truth = truth.compose(&true_step.as_delta());
            let measured = OdometryStep::from_wheels(
                left + gaussian(&mut rng, 0.001),
                right + gaussian(&mut rng, 0.001),
                track,
            );
            wheel = wheel.compose(&measured.as_delta());
            fusion.predict(&measured);
            if k % 3 == 2 {
                let true_motion = vo_clone_truth.between(&truth);
                let noisy = Pose2::new(
                    true_motion.x + gaussian(&mut rng, 0.02),
                    true_motion.y + gaussian(&mut rng, 0.02),
                    true_motion.theta + gaussian(&mut rng, 0.3f64.to_radians()),
                );
                vo = vo.compose(&noisy);
                fusion.update_visual(&noisy, &vo_noise);
                vo_clone_truth = truth;
            }
            t_all.push(truth);
            w_all.push(wheel);
            v_all.push(vo);
            f_all.push(fusion.pose());
        }
        (
            rmse(&w_all, &t_all),
            rmse(&v_all, &t_all),
            rmse(&f_all, &t_all),
        )
    }

    #[test]
    fn fused_pose_beats_wheel_and_visual_odometry_alone() {
        for seed in 0..4 {
            let (wheel, visual, fused) = run(seed);
            eprintln!(
                "seed {seed}: position RMSE fused {fused:.3} m, wheel {wheel:.3} m, visual {visual:.3} m"
            );
            assert!(
                fused < wheel && fused < visual,
                "seed {seed}: fused {fused:.3} m, wheel {wheel:.3} m, visual {visual:.3} m"
            );
        }
    }

    #[test]
    fn planar_motion_of_a_forward_camera() {
        // Camera looking along base x (camera z forward = base x, camera x right = base -y).
        let t_base_camera = Isometry3::from_parts(
            nalgebra::Translation3::new(0.2, 0.0, 1.0),
            nalgebra::UnitQuaternion::from_rotation_matrix(
                &nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
                    0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
                )),
            ),
        );
        // Base drives 1 m forward: the camera moves 1 m along its own z.
        let m = planar_motion(&t_base_camera, &Isometry3::translation(0.0, 0.0, 1.0));
        assert!(
            (m.x - 1.0).abs() < 1e-12 && m.y.abs() < 1e-12 && m.theta.abs() < 1e-12,
            "{m:?}"
        );
    }

    /// The step a chair whose wheels have a `scale` error and a `heading` drift (rad/m) really
    /// makes when its encoders measure `measured` (the filter's bias model, [`WheelBias`]).
    fn biased(measured: &OdometryStep, scale: f64, heading: f64) -> OdometryStep {
        let half_drift = 0.5 * heading * measured.trans;
        OdometryStep {
            rot1: measured.rot1 * (1.0 + scale) + half_drift,
            trans: measured.trans * (1.0 + scale),
            rot2: measured.rot2 * (1.0 + scale) + half_drift,
        }
    }

    /// The measured step `k` of a slow slalom: 5 cm a step, the heading swinging both ways.
    fn slalom(k: usize) -> OdometryStep {
        let omega = 0.3 * (k as f64 * 0.02).sin();
        OdometryStep::from_wheels(
            0.05 - 0.5 * omega * 0.05 * iw_body::TRACK_M,
            0.05 + 0.5 * omega * 0.05 * iw_body::TRACK_M,
            iw_body::TRACK_M,
        )
    }

    const ALPHA: [f64; 4] = [0.01, 0.002, 0.0005, 0.0005];
    /// The simulated chair's wheels: 3 % of scale, 0.015 rad of heading drift a metre.
    const SCALE: f64 = 0.03;
    const HEADING: f64 = 0.015;
    /// A scan match's noise: 1 cm and 0.2 degrees.
    fn scan_noise() -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 0.2f64.to_radians().powi(2)))
    }

    /// Drives `steps` slalom steps from `from` on the biased wheels, the filter fusing a scan
    /// match of the true pose every fourth step when `scans`; returns the true pose.
    fn drive(
        f: &mut OdometryFusion,
        from: Pose2,
        steps: std::ops::Range<usize>,
        scans: bool,
        rng: &mut ChaCha8Rng,
    ) -> Pose2 {
        let mut truth = from;
        for k in steps {
            let measured = slalom(k);
            truth = truth.compose(&biased(&measured, SCALE, HEADING).as_delta());
            f.predict(&measured);
            if scans && k % 4 == 3 {
                let p = f.pose();
                let innovation = Vector3::new(
                    truth.x + gaussian(rng, 0.01) - p.x,
                    truth.y + gaussian(rng, 0.01) - p.y,
                    wrap_angle(truth.theta + gaussian(rng, 0.2f64.to_radians()) - p.theta),
                );
                f.update_current(&innovation, &Matrix3::identity(), &scan_noise(), 16.27)
                    .expect("an innovation covariance that inverts");
            }
        }
        truth
    }

    fn position_error(f: &OdometryFusion, truth: &Pose2) -> (f64, f64) {
        let c = f.covariance();
        (
            (f.pose().x - truth.x).hypot(f.pose().y - truth.y),
            2.0 * (c[(0, 0)] + c[(1, 1)]).sqrt(),
        )
    }

    /// Wheels 1 % apart in radius turn a chair that drives straight (the heading drift), and move
    /// one that turns on the spot round a point off its axle's centre. Half a turn on the spot
    /// moves it 2.8 mm; on the random slip's alphas alone the model's 2 sd is 1.1 mm; with the
    /// heading drift's state carried into the turn's translation it covers the error.
    #[test]
    fn a_turn_on_the_spot_with_unequal_wheels_stays_inside_the_covariance() {
        let track = iw_body::TRACK_M;
        let random_slip = [3.63e-5, 1.16e-4, 1.82e-5, 2.85e-6];
        let start = Pose2::new(1.0, 2.0, 0.3);
        let mut f = OdometryFusion::new(start, Matrix3::zeros(), random_slip)
            .with_bias(WheelBias::WHEELCHAIR);
        let mut truth = start;
        // pi on the spot in 50 steps; the right wheel 1 % larger than the left
        let wheel_m = std::f64::consts::PI * track / 100.0;
        for _ in 0..50 {
            f.predict(&OdometryStep::from_wheels(-wheel_m, wheel_m, track));
            let real = OdometryStep::from_wheels(-wheel_m * 0.995, wheel_m * 1.005, track);
            truth = truth.compose(&real.as_delta());
        }
        let (error, two_sd) = position_error(&f, &truth);
        eprintln!("half a turn on the spot: {error} m off, 2 sd {two_sd} m");
        assert!(error > 0.0025, "the turn moved the chair only {error} m");
        assert!(error < two_sd, "{error} m off, 2 sd {two_sd} m");
    }

    #[test]
    fn without_bias_states_the_filter_is_the_plain_odometry_model() {
        let start = Pose2::new(1.0, 2.0, 0.3);
        let p0 = Matrix3::from_diagonal(&Vector3::new(1e-4, 2e-4, 3e-4));
        let mut f = OdometryFusion::new(start, p0, ALPHA).with_bias(WheelBias::NONE);
        let (mut pose, mut cov) = (start, p0);
        for k in 0..200 {
            let step = slalom(k);
            f.predict(&step);
            (pose, cov) = step.propagate(&pose, &cov, &ALPHA);
        }
        assert!((f.pose().x - pose.x).abs() < 1e-12 && (f.pose().y - pose.y).abs() < 1e-12);
        assert!((f.pose().theta - pose.theta).abs() < 1e-12);
        assert!(
            (f.covariance() - cov).abs().max() < 1e-15,
            "{cov} {}",
            f.covariance()
        );
        // a scan update is the plain three-state Kalman update, and leaves no bias behind
        let innovation = Vector3::new(0.02, -0.01, 0.005);
        f.update_current(
            &innovation,
            &Matrix3::identity(),
            &scan_noise(),
            f64::INFINITY,
        )
        .unwrap();
        let k = cov * (cov + scan_noise()).try_inverse().unwrap();
        let expected = pose.compose(&Pose2::default());
        let moved = k * innovation;
        assert!((f.pose().x - (expected.x + moved.x)).abs() < 1e-12);
        assert!((f.pose().y - (expected.y + moved.y)).abs() < 1e-12);
        let updated = (Matrix3::identity() - k) * cov;
        assert!((f.covariance() - updated).abs().max() < 1e-12);
        assert_eq!(f.bias(), ([0.0, 0.0], [0.0, 0.0]));
        // and `new` alone has no bias states either
        let mut plain = OdometryFusion::new(start, p0, ALPHA);
        plain.predict(&slalom(0));
        assert_eq!(plain.bias(), ([0.0, 0.0], [0.0, 0.0]));
    }

    #[test]
    fn the_bias_is_learned_while_scans_observe_the_motion() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let start = Pose2::default();
        let mut f =
            OdometryFusion::new(start, scan_noise(), ALPHA).with_bias(WheelBias::WHEELCHAIR);
        drive(&mut f, start, 0..600, true, &mut rng);
        let ([scale, heading], [scale_sd, heading_sd]) = f.bias();
        eprintln!(
            "after 30 m: scale {scale:.4} ± {scale_sd:.4}, heading {heading:.4} ± {heading_sd:.4} rad/m"
        );
        assert!((scale - SCALE).abs() < 0.005, "scale {scale}");
        assert!((heading - HEADING).abs() < 0.003, "heading {heading}");
        assert!(
            scale_sd < WheelBias::WHEELCHAIR.scale_sigma / 3.0,
            "{scale_sd}"
        );
        assert!(
            heading_sd < WheelBias::WHEELCHAIR.heading_sigma_rad_per_m / 3.0,
            "{heading_sd}"
        );
    }

    #[test]
    fn a_learned_bias_is_held_while_blind_and_the_covariance_covers_the_error() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let start = Pose2::default();
        let mut f =
            OdometryFusion::new(start, scan_noise(), ALPHA).with_bias(WheelBias::WHEELCHAIR);
        let seen = drive(&mut f, start, 0..600, true, &mut rng);
        let (bias, sd) = f.bias();
        // 10 m blind: predictions only
        let truth = drive(&mut f, seen, 600..800, false, &mut rng);
        let (bias_after, sd_after) = f.bias();
        assert_eq!(bias_after, bias, "nothing observes the bias while blind");
        let walk = WheelBias::WHEELCHAIR;
        for (before, after, per_root_m) in [
            (sd[0], sd_after[0], walk.scale_walk),
            (sd[1], sd_after[1], walk.heading_walk_rad_per_m),
        ] {
            let grown = (before.powi(2) + per_root_m.powi(2) * 10.0).sqrt();
            assert!(
                after >= before && after <= grown + 1e-9,
                "{before} -> {after}, the walk allows {grown}"
            );
        }
        let (error, two_sigma) = position_error(&f, &truth);
        eprintln!("10 m blind with the learned bias: {error:.3} m off, 2 sigma {two_sigma:.3} m");
        assert!(error < 0.1, "{error}");
        assert!(error <= two_sigma, "{error} > 2 sigma {two_sigma}");
    }

    #[test]
    fn an_unlearned_bias_still_covers_the_error_of_a_blind_start() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let start = Pose2::default();
        let mut f =
            OdometryFusion::new(start, scan_noise(), ALPHA).with_bias(WheelBias::WHEELCHAIR);
        let mut plain = OdometryFusion::new(start, scan_noise(), ALPHA);
        let truth = drive(&mut f, start, 0..200, false, &mut rng);
        drive(&mut plain, start, 0..200, false, &mut rng);
        let (error, two_sigma) = position_error(&f, &truth);
        let (plain_error, plain_two_sigma) = position_error(&plain, &truth);
        assert!(
            (error - plain_error).abs() < 1e-12,
            "the same estimate, not the same trust"
        );
        assert!(error <= two_sigma, "{error} > 2 sigma {two_sigma}");
        assert!(
            plain_error > plain_two_sigma,
            "{plain_error} <= {plain_two_sigma}"
        );
    }

    #[test]
    fn a_reset_moves_the_pose_and_keeps_the_bias() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let start = Pose2::default();
        let mut f =
            OdometryFusion::new(start, scan_noise(), ALPHA).with_bias(WheelBias::WHEELCHAIR);
        drive(&mut f, start, 0..600, true, &mut rng);
        let bias = f.bias();
        let there = Pose2::new(5.0, -3.0, 1.0);
        let cov = Matrix3::from_diagonal(&Vector3::new(0.04, 0.04, 0.01));
        f.reset(there, cov);
        assert_eq!(f.bias(), bias);
        assert_eq!(f.pose(), there);
        assert_eq!(f.covariance(), cov);
        // the new pose is not correlated with the bias learned before it
        assert_eq!(f.covariance.fixed_view::<6, 2>(0, BIAS).abs().max(), 0.0);
        // and the bias still corrects the wheels: 1 m measured straight ahead is 1 + scale
        f.predict(&OdometryStep::from_wheels(1.0, 1.0, iw_body::TRACK_M));
        let travelled = (f.pose().x - there.x).hypot(f.pose().y - there.y);
        assert!((travelled - (1.0 + bias.0[0])).abs() < 1e-12, "{travelled}");
    }

    #[test]
    fn covariance_shrinks_on_a_visual_update() {
        let mut f =
            OdometryFusion::new(Pose2::default(), Matrix3::zeros(), [0.01, 0.01, 0.01, 0.01]);
        for _ in 0..10 {
            f.predict(&OdometryStep::from_wheels(0.1, 0.12, iw_body::TRACK_M));
        }
        let before = f.covariance().trace();
        let motion = Pose2::default().between(&f.pose());
        f.update_visual(&motion, &(Matrix3::identity() * 1e-6));
        assert!(f.covariance().trace() < before);
    }
}
