//! Scan-to-map matching: Gauss-Newton on point-to-segment distances with a Cauchy kernel, so
//! that returns from chairs and people that are not on the map weigh little. The covariance is
//! derived, not tuned: the inverse of the weighted normal matrix at the points' own standard
//! deviations, with neighbouring points along the scan counted as one where they lie closer
//! than the errors' correlation length, scaled up when the residuals spread wider than those
//! deviations say; directions the scan cannot see (along a blank corridor) get no information
//! at all.

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
    /// Points closer than this along the scan share their errors (the same stretch of wall,
    /// drawn a little off, seen by neighbouring beams), m: each point counts for its spacing
    /// over this length, at most one.
    pub correlation_m: f64,
    /// A direction whose variance at the points' standard deviations (every point counted)
    /// would exceed this is not observed (m², with 1 rad = 1 m): a scan that places it no
    /// better than to 8 cm does so from a few points, at the kernel's edge.
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
            correlation_m: 0.0,
            unobserved_var: 0.08f64.powi(2),
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
    /// The residuals' mean squared influence over the points' variances (1 if they spread as
    /// the points' standard deviations say); the covariance is scaled by it when above 1.
    pub residual_scale: f64,
}

/// Variance given to a direction the scan does not observe.
pub const UNOBSERVED_VAR: f64 = 1e4;

/// The normal equations at one pose.
struct Normal {
    /// Information of the pose, every point counted.
    h: Matrix3<f64>,
    /// Gradient.
    g: Vector3<f64>,
    /// Information of the pose, each point counted for its share of the correlation length.
    h_shared: Matrix3<f64>,
    /// Sum of the shared squared influences (robust weight times normalised residual), and of
    /// the shared robust weights: a point off the map (a person, a moved chair) pulls the match
    /// by its influence, which the kernel bounds, not by its residual.
    spread: (f64, f64),
    /// Points with a map normal.
    used: usize,
    /// Points within the inlier distance.
    inliers: usize,
}

/// Normal equations at `pose`; `share[i]` is point `i`'s share of the correlation length.
fn normal_equations(
    map: &LocalizationMap,
    points: &[ScanPoint],
    share: &[f64],
    pose: &Pose2,
    config: &MatcherConfig,
) -> Normal {
    let mut n = Normal {
        h: Matrix3::zeros(),
        g: Vector3::zeros(),
        h_shared: Matrix3::zeros(),
        spread: (0.0, 0.0),
        used: 0,
        inliers: 0,
    };
    for (p, share) in points.iter().zip(share) {
        let q = to_map(pose, &p.p_base);
        let Some(near) = map.nearest(&q) else {
            continue;
        };
        let e = near.distance_m;
        if e <= config.inlier_m {
            n.inliers += 1;
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
        let jjt = j * j.transpose();
        n.h += jjt * w;
        n.g += j * (w * e);
        n.h_shared += jjt * (w * share);
        n.spread.0 += share * (robust * e / p.sigma_m).powi(2);
        n.spread.1 += share * robust;
        n.used += 1;
    }
    n
}

/// Each point's share of the correlation length: its spacing to its neighbours along the scan
/// (half the gap to each, a gap of more than the length counted as the length) over the length.
fn shares(points: &[ScanPoint], correlation_m: f64) -> Vec<f64> {
    if correlation_m <= 0.0 {
        return vec![1.0; points.len()];
    }
    let gap = |a: usize, b: usize| {
        (points[a].p_base - points[b].p_base)
            .norm()
            .min(correlation_m)
    };
    (0..points.len())
        .map(|i| {
            let before = if i > 0 { gap(i - 1, i) } else { correlation_m };
            let after = if i + 1 < points.len() {
                gap(i, i + 1)
            } else {
                correlation_m
            };
            (0.5 * (before + after) / correlation_m).min(1.0)
        })
        .collect()
}

/// Matches `points` (base frame) against `map` from `guess`. `None` when fewer than
/// [`MatcherConfig::min_points`] points lie near the map.
pub fn match_scan(
    map: &LocalizationMap,
    points: &[ScanPoint],
    guess: &Pose2,
    config: &MatcherConfig,
) -> Option<ScanMatch> {
    let share = shares(points, config.correlation_m);
    let observed = |lambda: f64| lambda * config.unobserved_var > 1.0;
    let mut pose = *guess;
    let mut last = None;
    for _ in 0..config.iterations.max(1) {
        let n = normal_equations(map, points, &share, &pose, config);
        if n.used < config.min_points {
            return None;
        }
        let eig = n.h.symmetric_eigen();
        // Solve in the observed directions only: a blank corridor leaves its axis where the
        // guess put it.
        let mut step = Vector3::zeros();
        for k in 0..3 {
            let lambda = eig.eigenvalues[k];
            if observed(lambda) {
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
        last = Some(n);
        if step.fixed_rows::<2>(0).norm() < 1e-4 && step[2].abs() < 1e-4 {
            break;
        }
    }
    let n = normal_equations(map, points, &share, &pose, config);
    let n = if n.used >= config.min_points {
        n
    } else {
        last?
    };
    let eig = n.h.symmetric_eigen();
    let residual_scale = n.spread.0 / n.spread.1.max(f64::MIN_POSITIVE);
    // The shared information in the observed directions, inverted there.
    let basis: Vec<_> = (0..3)
        .filter(|&k| observed(eig.eigenvalues[k]))
        .map(|k| eig.eigenvectors.column(k).into_owned())
        .collect();
    let mut covariance = Matrix3::zeros();
    for k in (0..3).filter(|&k| !observed(eig.eigenvalues[k])) {
        let v = eig.eigenvectors.column(k);
        covariance += v * v.transpose() * UNOBSERVED_VAR;
    }
    if !basis.is_empty() {
        let v = nalgebra::Matrix3xX::from_columns(&basis);
        let inv = (v.transpose() * n.h_shared * &v).try_inverse()?;
        covariance += &v * inv * v.transpose() * residual_scale.max(1.0);
    }
    Some(ScanMatch {
        pose,
        covariance,
        inlier_fraction: n.inliers as f64 / points.len().max(1) as f64,
        observed: basis.len(),
        residual_scale,
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
