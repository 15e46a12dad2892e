//! Rigid alignment of 3D point pairs: Umeyama's closed form and the thesis's RANSAC on 3-point
//! samples with a pairwise-distance pre-check (thesis 5.3).

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;

use crate::VoError;

/// The rigid transform `t_dst_src` minimising `sum |dst_i - t_dst_src * src_i|^2` (Umeyama 1991,
/// without scale). Needs three pairs that are not collinear.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// let t = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.0, 0.2, 0.1));
/// let src = [Point3::new(0.0, 0.0, 1.0), Point3::new(1.0, 0.0, 2.0), Point3::new(0.0, 1.0, 1.5)];
/// let dst: Vec<_> = src.iter().map(|p| t * p).collect();
/// let est = iw_vo::umeyama(&src, &dst).unwrap();
/// approx::assert_relative_eq!(est.to_homogeneous(), t.to_homogeneous(), epsilon = 1e-9);
/// ```
pub fn umeyama(src: &[Point3<f64>], dst: &[Point3<f64>]) -> Result<Isometry3<f64>, VoError> {
    let n = src.len().min(dst.len());
    if n < 3 {
        return Err(VoError::TooFewPoints {
            found: n,
            needed: 3,
        });
    }
    let inv_n = 1.0 / n as f64;
    let mean_src = src[..n]
        .iter()
        .fold(Vector3::zeros(), |acc, p| acc + p.coords)
        * inv_n;
    let mean_dst = dst[..n]
        .iter()
        .fold(Vector3::zeros(), |acc, p| acc + p.coords)
        * inv_n;
    let mut cov = Matrix3::zeros();
    for (s, d) in src[..n].iter().zip(&dst[..n]) {
        cov += (d.coords - mean_dst) * (s.coords - mean_src).transpose();
    }
    cov *= inv_n;
    let svd = cov.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(VoError::TooFewPoints {
            found: n,
            needed: 3,
        });
    };
    let mut sorted = svd.singular_values;
    sorted.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    // Collinear or coincident points leave the rotation about their line undetermined.
    if sorted[1] <= 1e-12 * sorted[0].max(1e-300) {
        return Err(VoError::TooFewPoints {
            found: 2,
            needed: 3,
        });
    }
    let mut s = Matrix3::identity();
    if (u.determinant() * v_t.determinant()) < 0.0 {
        s[(2, 2)] = -1.0;
    }
    let rotation = Rotation3::from_matrix_unchecked(u * s * v_t);
    let translation = mean_dst - rotation * mean_src;
    Ok(Isometry3::from_parts(
        Translation3::from(translation),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

/// RANSAC settings (thesis: 35 hypotheses, 4 cm inlier threshold).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RansacParams {
    /// Hypotheses that pass the pre-check and are scored (thesis eq. 2.52: 35 for p 0.99, w 0.5).
    pub iterations: usize,
    /// A pair is an inlier when `|dst - T src|` is below this, m (thesis: 4 cm, the depth noise
    /// at the sensor's range limit).
    pub inlier_threshold_m: f64,
    /// Samples whose pairwise distances differ by more than this between the frames are refused
    /// before fitting, m.
    pub distance_tolerance_m: f64,
    /// Samples with two points closer than this are refused as degenerate, m.
    pub min_sample_spread_m: f64,
    /// Re-select inliers with the refined transform and refit this many extra times (thesis: 0).
    pub refit_rounds: usize,
}

impl Default for RansacParams {
    fn default() -> Self {
        RansacParams {
            iterations: 35,
            inlier_threshold_m: 0.04,
            distance_tolerance_m: 0.04,
            min_sample_spread_m: 0.05,
            refit_rounds: 0,
        }
    }
}

/// A robust rigid fit: the transform and the indices of the pairs it explains.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidFit {
    /// Maps source points onto destination points.
    pub t_dst_src: Isometry3<f64>,
    /// Indices of inlier pairs, ascending.
    pub inliers: Vec<usize>,
}

fn inliers_of(
    t: &Isometry3<f64>,
    src: &[Point3<f64>],
    dst: &[Point3<f64>],
    threshold_m: f64,
) -> (Vec<usize>, f64) {
    let limit2 = threshold_m * threshold_m;
    let mut inliers = Vec::new();
    let mut cost = 0.0;
    for (i, (s, d)) in src.iter().zip(dst).enumerate() {
        let e2 = (d - t * s).norm_squared();
        if e2 < limit2 {
            inliers.push(i);
            cost += e2;
        } else {
            cost += limit2;
        }
    }
    (inliers, cost)
}

/// RANSAC over 3-pair samples (thesis Algorithm 3 line 5) followed by Umeyama on all inliers
/// (line 6). The best hypothesis has the most inliers, ties broken by the truncated squared error.
pub fn ransac_rigid(
    src: &[Point3<f64>],
    dst: &[Point3<f64>],
    params: &RansacParams,
    rng: &mut impl Rng,
) -> Result<RigidFit, VoError> {
    let n = src.len().min(dst.len());
    if n < 3 {
        return Err(VoError::TooFewPoints {
            found: n,
            needed: 3,
        });
    }
    let (src, dst) = (&src[..n], &dst[..n]);
    let mut best: Option<(Vec<usize>, f64)> = None;
    let mut scored = 0;
    // Pre-check refusals do not count as hypotheses; bound the draws so pure noise terminates.
    for _ in 0..params.iterations.saturating_mul(20).max(100) {
        if scored >= params.iterations {
            break;
        }
        let a = rng.random_range(0..n);
        let b = rng.random_range(0..n);
        let c = rng.random_range(0..n);
        if a == b || b == c || a == c {
            continue;
        }
        let consistent = [(a, b), (b, c), (a, c)].iter().all(|&(i, j)| {
            let ds = (src[i] - src[j]).norm();
            let dd = (dst[i] - dst[j]).norm();
            ds > params.min_sample_spread_m && (ds - dd).abs() < params.distance_tolerance_m
        });
        if !consistent {
            continue;
        }
        let Ok(t) = umeyama(&[src[a], src[b], src[c]], &[dst[a], dst[b], dst[c]]) else {
            continue;
        };
        scored += 1;
        let (inliers, cost) = inliers_of(&t, src, dst, params.inlier_threshold_m);
        let better = match &best {
            None => true,
            Some((bi, bc)) => inliers.len() > bi.len() || (inliers.len() == bi.len() && cost < *bc),
        };
        if better {
            best = Some((inliers, cost));
        }
    }
    let Some((mut inliers, _)) = best else {
        return Err(VoError::TooFewPoints {
            found: 0,
            needed: 3,
        });
    };
    let pick = |idx: &[usize], pts: &[Point3<f64>]| idx.iter().map(|&i| pts[i]).collect::<Vec<_>>();
    let mut t = umeyama(&pick(&inliers, src), &pick(&inliers, dst))?;
    for _ in 0..params.refit_rounds {
        let (again, _) = inliers_of(&t, src, dst, params.inlier_threshold_m);
        if again.len() < 3 || again == inliers {
            break;
        }
        inliers = again;
        t = umeyama(&pick(&inliers, src), &pick(&inliers, dst))?;
    }
    Ok(RigidFit {
        t_dst_src: t,
        inliers,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn cloud(rng: &mut ChaCha8Rng, n: usize) -> Vec<Point3<f64>> {
        (0..n)
            .map(|_| {
                Point3::new(
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(0.8..4.0),
                )
            })
            .collect()
    }

    #[test]
    fn umeyama_recovers_transform_under_noise() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let t = Isometry3::new(
            Vector3::new(0.05, 0.02, -0.03),
            Vector3::new(0.02, -0.08, 0.01),
        );
        let src = cloud(&mut rng, 200);
        let dst: Vec<_> = src
            .iter()
            .map(|p| {
                t * p
                    + Vector3::new(
                        rng.random_range(-0.005..0.005),
                        rng.random_range(-0.005..0.005),
                        rng.random_range(-0.005..0.005),
                    )
            })
            .collect();
        let est = umeyama(&src, &dst).expect("fit");
        assert!((est.translation.vector - t.translation.vector).norm() < 0.003);
        assert!(est.rotation.angle_to(&t.rotation) < 0.002);
    }

    #[test]
    fn umeyama_rejects_degenerate_input() {
        let line = [
            Point3::new(0.0, 0.0, 1.0),
            Point3::new(0.0, 0.0, 2.0),
            Point3::new(0.0, 0.0, 3.0),
        ];
        assert!(umeyama(&line, &line).is_err());
        assert!(matches!(
            umeyama(&line[..2], &line[..2]),
            Err(VoError::TooFewPoints {
                found: 2,
                needed: 3
            })
        ));
    }

    #[test]
    fn ransac_finds_transform_and_inliers_among_outliers() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let t = Isometry3::new(
            Vector3::new(-0.04, 0.01, 0.06),
            Vector3::new(-0.05, 0.1, 0.03),
        );
        let src = cloud(&mut rng, 120);
        let mut dst: Vec<_> = src.iter().map(|p| t * p).collect();
        // 40 % gross outliers: wrong matches land anywhere.
        for d in dst.iter_mut().take(48) {
            *d = Point3::new(
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.0..1.0),
                rng.random_range(0.8..4.0),
            );
        }
        let fit = ransac_rigid(
            &src,
            &dst,
            &RansacParams::default(),
            &mut ChaCha8Rng::seed_from_u64(1),
        )
        .expect("fit");
        assert!((fit.t_dst_src.translation.vector - t.translation.vector).norm() < 1e-6);
        assert!(fit.t_dst_src.rotation.angle_to(&t.rotation) < 1e-6);
        assert_eq!(fit.inliers, (48..120).collect::<Vec<_>>());
        // Same seed, same answer.
        let again = ransac_rigid(
            &src,
            &dst,
            &RansacParams::default(),
            &mut ChaCha8Rng::seed_from_u64(1),
        )
        .expect("fit");
        assert_eq!(fit, again);
    }

    #[test]
    fn ransac_on_too_few_pairs_is_an_error() {
        let p = [Point3::origin(); 2];
        let err = ransac_rigid(
            &p,
            &p,
            &RansacParams::default(),
            &mut ChaCha8Rng::seed_from_u64(0),
        )
        .expect_err("two pairs");
        assert_eq!(err.to_string(), "too few point pairs: 2 (need at least 3)");
    }
}
