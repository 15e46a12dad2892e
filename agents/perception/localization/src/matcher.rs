//! Scan-to-map matching: Gauss-Newton on point-to-segment distances with a Cauchy kernel, so
//! that returns from chairs and people that are not on the map weigh little.
//!
//! The covariance is the Laplace approximation of the match's own cost, with nothing fixed
//! added: the inverse of the weighted normal matrix, scaled by the variance the residuals
//! actually show (a posteriori variance factor: a noisier scan, or a map that fits worse, gives
//! a larger covariance) and by how much neighbouring beams' residuals agree (their lag-one
//! correlation: beams on one misplaced wall, or on an object the map does not have, are not
//! independent evidence). Directions the scan cannot see (along a blank corridor) get no
//! information at all. When the scan was taken is not the matcher's business: the localizer
//! fuses each scan at the state of its own time.

use nalgebra::{Matrix3, Vector2, Vector3};

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
    /// The residuals' variance factor is never taken below this: a scan that happens to fit
    /// better than its points' standard deviations say does not make the match surer than
    /// they do.
    pub min_variance_factor: f64,
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
            min_variance_factor: 0.1,
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

/// The scan's cost around `pose`, linearised.
struct Normal {
    /// Normal matrix, Σ w jjᵀ (w: kernel weight over the point's variance).
    h: Matrix3<f64>,
    /// Gradient, Σ w j e.
    g: Vector3<f64>,
    /// Points near the map (with a residual direction).
    used: usize,
    /// Points within [`MatcherConfig::inlier_m`].
    inliers: usize,
    /// What the residuals say of the covariance: `H⁻¹` times this is the match's covariance.
    scale: f64,
}

/// Normal equations at `pose`, and the covariance scale of a match there: the variance factor
/// the residuals show (the median normalised squared residual over its value for a standard
/// normal, 0.455: points as noisy as their standard deviations say give 1; things that are not
/// on the map are outliers the median passes over), times (1 + r)/(1 − r), where r is the
/// lag-one correlation of consecutive inliers' residual vectors (independent points: 0; a run
/// of points all off the same way, as on a wall the map has a few centimetres off: near 1).
fn normal_equations(
    map: &LocalizationMap,
    points: &[ScanPoint],
    pose: &Pose2,
    config: &MatcherConfig,
) -> Normal {
    let (mut h, mut g) = (Matrix3::zeros(), Vector3::zeros());
    let mut inliers = 0;
    // each used point's residual vector over its standard deviation; `None` between points
    // that are not neighbours (a point off the map or without a direction in between)
    let mut residuals: Vec<Option<Vector2<f64>>> = Vec::with_capacity(points.len());
    for p in points {
        let q = to_map(pose, &p.p_base);
        let Some(near) = map.nearest(&q) else {
            residuals.push(None);
            continue;
        };
        let e = near.distance_m;
        if e <= config.inlier_m {
            inliers += 1;
        }
        if near.normal == Vector2::zeros() {
            residuals.push(Some(Vector2::zeros()));
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
        residuals.push(Some(near.normal * (e / p.sigma_m)));
    }
    let mut squares: Vec<f64> = residuals
        .iter()
        .flatten()
        .map(|u| u.norm_squared())
        .collect();
    let used = squares.len();
    let factor = if used == 0 {
        1.0
    } else {
        let mid = used / 2;
        *squares.select_nth_unstable_by(mid, f64::total_cmp).1 / CHI2_1_MEDIAN
    }
    .max(config.min_variance_factor);
    // correlation among inliers (within three of the factor's standard deviations)
    let inlier = |u: &Vector2<f64>| u.norm_squared() <= 9.0 * factor;
    let (mut power, mut lagged) = (0.0, 0.0);
    for (k, u) in residuals.iter().enumerate() {
        let Some(u) = u.filter(inlier) else { continue };
        power += u.norm_squared();
        if let Some(Some(v)) = k.checked_sub(1).map(|i| residuals[i].filter(inlier)) {
            lagged += u.dot(&v);
        }
    }
    let r = if power > 0.0 {
        (lagged / power).clamp(0.0, MAX_CORRELATION)
    } else {
        0.0
    };
    Normal {
        h,
        g,
        used,
        inliers,
        scale: factor * (1.0 + r) / (1.0 - r),
    }
}

/// The median of a chi-square variable with one degree of freedom.
const CHI2_1_MEDIAN: f64 = 0.4549;

/// Neighbouring residuals' correlation is taken at most this (the covariance then grows 19
/// times): past it the scan is one misfit, which the gate and the inlier test judge.
const MAX_CORRELATION: f64 = 0.9;

/// Covariance `scale · H⁻¹` over the observed directions, [`UNOBSERVED_VAR`] in the others;
/// also how many were observed.
fn covariance(
    eig: &nalgebra::SymmetricEigen<f64, nalgebra::U3>,
    scale: f64,
    config: &MatcherConfig,
) -> (Matrix3<f64>, usize) {
    let mut covariance = Matrix3::zeros();
    let mut observed = 0;
    for k in 0..3 {
        let lambda = eig.eigenvalues[k];
        let v = eig.eigenvectors.column(k);
        let var = if observable(lambda, scale, config) {
            observed += 1;
            scale / lambda
        } else {
            UNOBSERVED_VAR
        };
        covariance += v * v.transpose() * var;
    }
    (covariance, observed)
}

/// Whether a direction with normal-matrix eigenvalue `lambda` is observed by a scan whose
/// covariance scale is `scale`.
fn observable(lambda: f64, scale: f64, config: &MatcherConfig) -> bool {
    lambda * config.unobserved_var > scale
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
        let n = normal_equations(map, points, &pose, config);
        if n.used < config.min_points {
            return None;
        }
        let eig = n.h.symmetric_eigen();
        // Solve in the observed directions only: a blank corridor leaves its axis where the
        // guess put it.
        let mut step = Vector3::zeros();
        for k in 0..3 {
            let lambda = eig.eigenvalues[k];
            if observable(lambda, n.scale, config) {
                let v = eig.eigenvectors.column(k);
                step -= v * (v.dot(&n.g) / lambda);
            }
        }
        // Gauss-Newton on a piecewise distance field can overshoot: cap each step.
        let len = step.fixed_rows::<2>(0).norm();
        if len > 0.2 {
            step *= 0.2 / len;
        }
        step[2] = step[2].clamp(-0.1, 0.1);
        pose = Pose2::new(pose.x + step[0], pose.y + step[1], pose.theta + step[2]);
        last = Some((eig, n.scale));
        if step.fixed_rows::<2>(0).norm() < 1e-4 && step[2].abs() < 1e-4 {
            break;
        }
    }
    let n = normal_equations(map, points, &pose, config);
    let (eig, scale) = if n.used >= config.min_points {
        (n.h.symmetric_eigen(), n.scale)
    } else {
        last?
    };
    let (covariance, observed) = covariance(&eig, scale, config);
    Some(ScanMatch {
        pose,
        covariance,
        inlier_fraction: n.inliers as f64 / points.len().max(1) as f64,
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
