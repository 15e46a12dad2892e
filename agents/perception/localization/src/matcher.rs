//! Scan-to-map matching: Gauss-Newton on point-to-segment distances with a Cauchy kernel, so
//! that returns from chairs and people that are not on the map weigh little. The covariance is
//! derived, not tuned: the inverse of the weighted normal matrix at the points' own standard
//! deviations along the walls' normals (a beam's range noise reaches the normal by the cosine of
//! its incidence), over the points the converged pose puts on the map, scaled up when the
//! residuals spread wider than those deviations say; directions the scan cannot see (along a
//! blank corridor) get no information at all.

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
    /// Least cosine of a beam's incidence on the wall counted: a beam that grazes a wall is
    /// placed along the normal by its range noise times this at best. Below it the fit leans
    /// on grazing beams near corners and door edges, where the nearest segment is not the one
    /// hit, and single scans came out overconfident and slower to converge
    /// (docs/results/localization.md, the `derive` work).
    pub min_incidence_cos: f64,
    /// At the converged pose, a point farther from the map than this many of its standard
    /// deviations is taken for something not on the map (a person, a chair) and left out of a
    /// refit and of the covariance: the Cauchy kernel's pull falls only as one over the distance,
    /// so a mover's dozen points would pull every scan that sees it the same way. 0: no refit.
    pub outlier_sigmas: f64,
    /// A direction whose variance at the points' standard deviations would exceed this is not
    /// observed (m², with 1 rad = 1 m): a scan that places it no better than to 8 cm does so
    /// from a few points, at the kernel's edge.
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
            min_incidence_cos: 0.3,
            outlier_sigmas: 4.0,
            unobserved_var: 0.08f64.powi(2),
            min_points: 12,
        }
    }
}

impl MatcherConfig {
    /// Whether a direction with information `lambda` (1/m², with 1 rad = 1 m) is observed.
    fn observes(&self, lambda: f64) -> bool {
        lambda * self.unobserved_var > 1.0
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
    /// Information of the pose.
    h: Matrix3<f64>,
    /// Gradient.
    g: Vector3<f64>,
    /// Sum of the squared influences (robust weight times normalised residual), and of the
    /// robust weights: a point off the map (a person, a moved chair) pulls the match by its
    /// influence, which the kernel bounds, not by its residual.
    spread: (f64, f64),
    /// Points with a map normal.
    used: usize,
    /// Points within the inlier distance.
    inliers: usize,
}

/// Normal equations at `pose`, over the points within `gate` of their standard deviations of
/// the map (all with a map normal if `None`).
fn normal_equations(
    map: &LocalizationMap,
    points: &[ScanPoint],
    pose: &Pose2,
    config: &MatcherConfig,
    gate: Option<f64>,
) -> Normal {
    let mut n = Normal {
        h: Matrix3::zeros(),
        g: Vector3::zeros(),
        spread: (0.0, 0.0),
        used: 0,
        inliers: 0,
    };
    for p in points {
        let q = to_map(pose, &p.p_base);
        let Some(near) = map.nearest(&q) else {
            continue;
        };
        let e = near.distance_m;
        if e <= config.inlier_m {
            n.inliers += 1;
        }
        if near.normal == Vector2::zeros() || gate.is_some_and(|g| e > g * p.sigma_m) {
            continue;
        }
        let j = Vector3::new(
            near.normal.x,
            near.normal.y,
            near.normal.dot(&d_dtheta(pose.theta, &p.p_base)),
        );
        let robust = 1.0 / (1.0 + (e / config.kernel_m).powi(2));
        let sigma_m = p.sigma_m * incidence_cos(&near.normal, pose, &p.beam_base, config);
        let w = robust / (sigma_m * sigma_m);
        n.h += j * j.transpose() * w;
        n.g += j * (w * e);
        n.spread.0 += (robust * e / sigma_m).powi(2);
        n.spread.1 += robust;
        n.used += 1;
    }
    n
}

/// How much of a beam's range error reaches the wall's normal `normal` (map frame) for a base
/// at `pose`: the cosine of the incidence, at least [`MatcherConfig::min_incidence_cos`]; 1 for
/// a point with no beam direction.
fn incidence_cos(
    normal: &Vector2<f64>,
    pose: &Pose2,
    beam_base: &Vector2<f64>,
    config: &MatcherConfig,
) -> f64 {
    if *beam_base == Vector2::zeros() {
        return 1.0;
    }
    let beam_map = nalgebra::Rotation2::new(pose.theta) * beam_base;
    normal.dot(&beam_map).abs().max(config.min_incidence_cos)
}

/// Gauss-Newton from `guess`: the pose it converged to and the normal equations there. `None`
/// when fewer than [`MatcherConfig::min_points`] points lie near the map (or inside the gate).
fn solve(
    map: &LocalizationMap,
    points: &[ScanPoint],
    guess: &Pose2,
    config: &MatcherConfig,
    gate: Option<f64>,
) -> Option<(Pose2, Normal)> {
    let observed = |lambda: f64| config.observes(lambda);
    let mut pose = *guess;
    let mut last = None;
    for _ in 0..config.iterations.max(1) {
        let n = normal_equations(map, points, &pose, config, gate);
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
    let n = normal_equations(map, points, &pose, config, gate);
    let n = if n.used >= config.min_points {
        n
    } else {
        last?
    };
    Some((pose, n))
}

/// Matches `points` (base frame) against `map` from `guess`. `None` when fewer than
/// [`MatcherConfig::min_points`] points lie near the map.
pub fn match_scan(
    map: &LocalizationMap,
    points: &[ScanPoint],
    guess: &Pose2,
    config: &MatcherConfig,
) -> Option<ScanMatch> {
    let observed = |lambda: f64| config.observes(lambda);
    let (pose, n) = solve(map, points, guess, config, None)?;
    // Refit without the points the converged pose puts off the map.
    let (pose, n) = if config.outlier_sigmas > 0.0 {
        solve(map, points, &pose, config, Some(config.outlier_sigmas)).unwrap_or((pose, n))
    } else {
        (pose, n)
    };
    let eig = n.h.symmetric_eigen();
    let residual_scale = n.spread.0 / n.spread.1.max(f64::MIN_POSITIVE);
    // The information in the observed directions, inverted there.
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
        let inv = (v.transpose() * n.h * &v).try_inverse()?;
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
