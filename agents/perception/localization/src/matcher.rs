//! Scan-to-map matching: Gauss-Newton on point-to-segment distances with a Cauchy kernel, so
//! that returns from chairs and people that are not on the map weigh little. The covariance is
//! the inverse of the weighted normal matrix, inflated for beams whose errors are correlated;
//! directions the scan cannot see (along a blank corridor) get no information at all.

use nalgebra::{Matrix3, Vector3};

use crate::map::LocalizationMap;
use crate::scan::{ScanPoint, d_dtheta, to_map};
use iw_vo::Pose2;

/// How the matcher weighs and stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatcherConfig {
    /// Gauss-Newton iterations at most.
    pub iterations: usize,
    /// Cauchy kernel width, m: a point this far from the map weighs half.
    pub kernel_m: f64,
    /// A point within this distance of the map at the match counts as an inlier, m.
    pub inlier_m: f64,
    /// The covariance is the normal matrix's inverse times this (neighbouring beams share map
    /// and model errors, so they are not independent).
    pub inflation: f64,
    /// Smallest covariance of a matched pose: (m², rad²).
    pub floor: (f64, f64),
    /// A direction whose variance would exceed this is not observed (m², with 1 rad = 1 m).
    pub unobserved_var: f64,
    /// Fewer matched points than this give no match.
    pub min_points: usize,
}

impl Default for MatcherConfig {
    fn default() -> Self {
        MatcherConfig {
            iterations: 12,
            kernel_m: 0.05,
            inlier_m: 0.1,
            inflation: 10.0,
            floor: (0.01f64.powi(2), 0.3f64.to_radians().powi(2)),
            unobserved_var: 0.25,
            min_points: 12,
        }
    }
}

/// A matched scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanMatch {
    /// The base pose that best explains the scan.
    pub pose: Pose2,
    /// Its covariance (x, y, theta); unobserved directions carry [`UNOBSERVED_VAR`].
    pub covariance: Matrix3<f64>,
    /// Fraction of all points within [`MatcherConfig::inlier_m`] of the map at `pose`.
    pub inlier_fraction: f64,
    /// Number of directions (of 3) the scan observed.
    pub observed: usize,
}

/// Variance given to a direction the scan does not observe.
pub const UNOBSERVED_VAR: f64 = 1e4;

/// Normal equations at `pose`: (H, g, weighted points, inliers).
fn normal_equations(
    map: &LocalizationMap,
    points: &[ScanPoint],
    pose: &Pose2,
    config: &MatcherConfig,
) -> (Matrix3<f64>, Vector3<f64>, usize, usize) {
    let (mut h, mut g) = (Matrix3::zeros(), Vector3::zeros());
    let (mut used, mut inliers) = (0, 0);
    for p in points {
        let q = to_map(pose, &p.p_base);
        let Some(near) = map.nearest(&q) else {
            continue;
        };
        let e = near.distance_m;
        if e <= config.inlier_m {
            inliers += 1;
        }
        if near.normal == nalgebra::Vector2::zeros() {
            continue;
        }
        let j = Vector3::new(
            near.normal.x,
            near.normal.y,
            near.normal.dot(&d_dtheta(pose.theta, &p.p_base)),
        );
        let robust = 1.0 / (1.0 + (e / config.kernel_m).powi(2));
        let w = robust / (p.sigma_m * p.sigma_m);
        h += j * j.transpose() * w;
        g += j * (w * e);
        used += 1;
    }
    (h, g, used, inliers)
}

/// Matches `points` (base frame) against `map` from `guess`. `None` when fewer than
/// [`MatcherConfig::min_points`] points lie near the map.
pub fn match_scan(
    map: &LocalizationMap,
    points: &[ScanPoint],
    guess: &Pose2,
    config: &MatcherConfig,
) -> Option<ScanMatch> {
    let mut pose = *guess;
    let mut last = None;
    for _ in 0..config.iterations.max(1) {
        let (h, g, used, _) = normal_equations(map, points, &pose, config);
        if used < config.min_points {
            return None;
        }
        let eig = h.symmetric_eigen();
        // Solve in the observed directions only: a blank corridor leaves its axis where the
        // guess put it.
        let mut step = Vector3::zeros();
        for k in 0..3 {
            let lambda = eig.eigenvalues[k];
            if lambda * config.unobserved_var > config.inflation {
                let v = eig.eigenvectors.column(k);
                step -= v * (v.dot(&g) / lambda);
            }
        }
        // Gauss-Newton on a piecewise distance field can overshoot: cap each step.
        let len = step.fixed_rows::<2>(0).norm();
        if len > 0.2 {
            step *= 0.2 / len;
        }
        step[2] = step[2].clamp(-0.1, 0.1);
        pose = Pose2::new(pose.x + step[0], pose.y + step[1], pose.theta + step[2]);
        last = Some(eig);
        if step.fixed_rows::<2>(0).norm() < 1e-4 && step[2].abs() < 1e-4 {
            break;
        }
    }
    let (h, _, used, inliers) = normal_equations(map, points, &pose, config);
    let eig = if used >= config.min_points {
        h.symmetric_eigen()
    } else {
        last?
    };
    let mut covariance = Matrix3::zeros();
    let mut observed = 0;
    for k in 0..3 {
        let lambda = eig.eigenvalues[k];
        let v = eig.eigenvectors.column(k);
        let var = if lambda * config.unobserved_var > config.inflation {
            observed += 1;
            config.inflation / lambda
        } else {
            UNOBSERVED_VAR
        };
        covariance += v * v.transpose() * var;
    }
    covariance[(0, 0)] += config.floor.0;
    covariance[(1, 1)] += config.floor.0;
    covariance[(2, 2)] += config.floor.1;
    Some(ScanMatch {
        pose,
        covariance,
        inlier_fraction: inliers as f64 / points.len().max(1) as f64,
        observed,
    })
}

/// Fraction of `points` within [`MatcherConfig::inlier_m`] (or three of their standard
/// deviations, if more) of the map for a base at `pose`.
pub fn inlier_fraction(
    map: &LocalizationMap,
    points: &[ScanPoint],
    pose: &Pose2,
    config: &MatcherConfig,
) -> f64 {
    let inliers = points
        .iter()
        .filter(|p| {
            map.nearest(&to_map(pose, &p.p_base))
                .is_some_and(|n| n.distance_m <= config.inlier_m.max(3.0 * p.sigma_m))
        })
        .count();
    inliers as f64 / points.len().max(1) as f64
}
