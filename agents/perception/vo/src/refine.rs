//! Motion-only bundle adjustment: the camera pose that best explains where known 3D points are
//! seen (reprojection error, px) and how far they are (depth error), by robust Gauss-Newton.
//!
//! Points are fixed (they come from keyframes with known poses); only the 6-DoF pose moves, so each
//! iteration is one 6x6 solve. The depth term uses the Kinect noise model sigma_z = 1.425e-3 z^2 m
//! (Khoshelham and Elberink 2012) for both the keyframe's and the current frame's reading.

use nalgebra::{Isometry3, Matrix2x6, Matrix6, Point2, Point3, RowVector6, Vector3, Vector6};

/// One observation of a fixed world point by the camera being refined.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// The point in the world frame.
    pub p_world: Point3<f64>,
    /// Where the camera sees it: undistorted normalised image coordinates (x/z, y/z).
    pub normalised: Point2<f64>,
    /// The camera's own depth reading of it, m, when valid.
    pub depth_m: Option<f64>,
    /// Depth at which the point was measured in its keyframe, m (sets its depth uncertainty).
    pub source_depth_m: f64,
}

/// Settings of the refinement.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RefineParams {
    /// Gauss-Newton iterations per round (two rounds: all observations, then inliers only).
    pub iterations: usize,
    /// Focal length used to express reprojection errors in pixels, px.
    pub focal_px: f64,
    /// Standard deviation of a keypoint's position, px.
    pub sigma_px: f64,
    /// Huber threshold on the whitened residual (in standard deviations).
    pub huber: f64,
    /// Observations whose whitened squared residual exceeds this after round one are dropped
    /// (chi-square, 2 DoF, 99 %: 9.21).
    pub chi2_outlier: f64,
}

impl Default for RefineParams {
    fn default() -> Self {
        RefineParams {
            iterations: 6,
            focal_px: 517.0,
            sigma_px: 1.0,
            huber: 2.0,
            chi2_outlier: 9.21,
        }
    }
}

/// The refined pose and which observations it kept.
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    /// Maps world coordinates into the camera frame.
    pub t_camera_world: Isometry3<f64>,
    /// `inliers[i]`: observation `i` agrees with the refined pose.
    pub inliers: Vec<bool>,
    /// Number of inliers.
    pub inlier_count: usize,
}

fn sigma_depth_m(z: f64) -> f64 {
    1.425e-3 * z * z + 1e-3
}

fn skew_jacobian(p: &Vector3<f64>) -> nalgebra::Matrix3x6<f64> {
    // d(exp(delta) p)/d(delta) at delta = 0, delta = (translation, rotation): [I | -[p]x].
    nalgebra::Matrix3x6::new(
        1.0, 0.0, 0.0, 0.0, p.z, -p.y, //
        0.0, 1.0, 0.0, -p.z, 0.0, p.x, //
        0.0, 0.0, 1.0, p.y, -p.x, 0.0,
    )
}

fn huber_weight(whitened: f64, k: f64) -> f64 {
    if whitened <= k { 1.0 } else { k / whitened }
}

/// Whitened squared residuals (reprojection, depth) of one observation, `None` behind the camera.
fn residual(
    t: &Isometry3<f64>,
    o: &Observation,
    p: &RefineParams,
) -> Option<(nalgebra::Vector2<f64>, Option<f64>, Vector3<f64>)> {
    let pc = (t * o.p_world).coords;
    if pc.z < 0.05 {
        return None;
    }
    let proj = Point2::new(pc.x / pc.z, pc.y / pc.z);
    let r_uv = (proj - o.normalised) * (p.focal_px / p.sigma_px);
    let r_z = o.depth_m.map(|z| {
        (pc.z - z) / (sigma_depth_m(z).powi(2) + sigma_depth_m(o.source_depth_m).powi(2)).sqrt()
    });
    Some((r_uv, r_z, pc))
}

fn chi2(t: &Isometry3<f64>, o: &Observation, p: &RefineParams) -> f64 {
    match residual(t, o, p) {
        Some((r_uv, r_z, _)) => r_uv.norm_squared().max(r_z.map_or(0.0, |r| r * r)),
        None => f64::INFINITY,
    }
}

fn gauss_newton(
    mut t: Isometry3<f64>,
    obs: &[Observation],
    active: &[bool],
    p: &RefineParams,
) -> Isometry3<f64> {
    for _ in 0..p.iterations {
        let mut h = Matrix6::<f64>::zeros();
        let mut g = Vector6::<f64>::zeros();
        for (o, _) in obs.iter().zip(active).filter(|(_, a)| **a) {
            let Some((r_uv, r_z, pc)) = residual(&t, o, p) else {
                continue;
            };
            let j_point = skew_jacobian(&pc);
            let inv_z = 1.0 / pc.z;
            let s = p.focal_px / p.sigma_px;
            let j_proj = nalgebra::Matrix2x3::new(
                inv_z,
                0.0,
                -pc.x * inv_z * inv_z,
                0.0,
                inv_z,
                -pc.y * inv_z * inv_z,
            ) * s;
            let j_uv: Matrix2x6<f64> = j_proj * j_point;
            let w = huber_weight(r_uv.norm(), p.huber);
            h += j_uv.transpose() * j_uv * w;
            g += j_uv.transpose() * r_uv * w;
            if let (Some(r), Some(z)) = (r_z, o.depth_m) {
                let scale = 1.0
                    / (sigma_depth_m(z).powi(2) + sigma_depth_m(o.source_depth_m).powi(2)).sqrt();
                let j_z: RowVector6<f64> = j_point.row(2) * scale;
                let w = huber_weight(r.abs(), p.huber);
                h += j_z.transpose() * j_z * w;
                g += j_z.transpose() * r * w;
            }
        }
        let Some(delta) = h.cholesky().map(|c| -c.solve(&g)) else {
            break;
        };
        let step = Isometry3::new(
            delta.fixed_rows::<3>(0).into_owned(),
            delta.fixed_rows::<3>(3).into_owned(),
        );
        t = step * t;
        if delta.norm() < 1e-9 {
            break;
        }
    }
    t
}

/// Refines `t_camera_world` from its initial guess: a Huber-weighted round on all observations,
/// then a round on the ones within `chi2_outlier`. Returns the guess unchanged when fewer than
/// six observations agree (the 6-DoF problem would be under-determined).
pub fn refine_pose(
    t_camera_world: Isometry3<f64>,
    observations: &[Observation],
    params: &RefineParams,
) -> Refined {
    let all = vec![true; observations.len()];
    let first = gauss_newton(t_camera_world, observations, &all, params);
    let inliers: Vec<bool> = observations
        .iter()
        .map(|o| chi2(&first, o, params) < params.chi2_outlier)
        .collect();
    let inlier_count = inliers.iter().filter(|i| **i).count();
    if inlier_count < 6 {
        let inliers: Vec<bool> = observations
            .iter()
            .map(|o| chi2(&t_camera_world, o, params) < params.chi2_outlier)
            .collect();
        let inlier_count = inliers.iter().filter(|i| **i).count();
        return Refined {
            t_camera_world,
            inliers,
            inlier_count,
        };
    }
    let refined = gauss_newton(first, observations, &inliers, params);
    Refined {
        t_camera_world: refined,
        inliers,
        inlier_count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn recovers_pose_from_noisy_observations_with_outliers() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let t_true = Isometry3::new(
            Vector3::new(0.03, -0.02, 0.05),
            Vector3::new(0.04, -0.03, 0.02),
        );
        let params = RefineParams::default();
        let obs: Vec<Observation> = (0..150)
            .map(|i| {
                let p_world = Point3::new(
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(1.0..3.5),
                );
                let pc = t_true * p_world;
                let noise_px =
                    Point2::new(rng.random_range(-0.7..0.7), rng.random_range(-0.7..0.7))
                        / params.focal_px;
                let mut normalised = Point2::new(pc.x / pc.z, pc.y / pc.z) + noise_px.coords;
                if i % 10 == 0 {
                    normalised.x += 0.1; // a wrong match, 50 px off
                }
                Observation {
                    p_world,
                    normalised,
                    depth_m: Some(pc.z + rng.random_range(-0.005..0.005)),
                    source_depth_m: p_world.z,
                }
            })
            .collect();
        let r = refine_pose(Isometry3::identity(), &obs, &params);
        assert!(
            (r.t_camera_world.translation.vector - t_true.translation.vector).norm() < 0.003,
            "{}",
            r.t_camera_world
        );
        assert!(r.t_camera_world.rotation.angle_to(&t_true.rotation) < 0.002);
        assert!(
            r.inliers.iter().step_by(10).all(|i| !i),
            "every wrong match is rejected"
        );
        assert!(r.inlier_count >= 130);
    }

    #[test]
    fn too_few_observations_keep_the_guess() {
        let guess = Isometry3::translation(0.1, 0.0, 0.0);
        let r = refine_pose(guess, &[], &RefineParams::default());
        assert_eq!(r.t_camera_world, guess);
        assert_eq!(r.inlier_count, 0);
    }
}
