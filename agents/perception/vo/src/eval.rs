//! Trajectory accuracy as in the TUM benchmark (Sturm et al. 2012, thesis 5.4.2): the absolute
//! trajectory error (ATE) after a rigid alignment, and the relative pose error (RPE, drift).

use nalgebra::{Isometry3, Point3};

use crate::tum::{StampedPose, associate_times};
use crate::{VoError, umeyama};

/// Absolute trajectory error of an estimate against a reference.
#[derive(Debug, Clone, PartialEq)]
pub struct Ate {
    /// Root mean square of the position errors, m.
    pub rmse_m: f64,
    /// Mean position error, m.
    pub mean_m: f64,
    /// Median position error, m.
    pub median_m: f64,
    /// Largest position error, m.
    pub max_m: f64,
    /// The rigid alignment applied to the estimate (reference frame <- estimate frame).
    pub t_reference_estimate: Isometry3<f64>,
    /// Per associated pose: (estimate time s, position error m), in time order.
    pub errors: Vec<(f64, f64)>,
}

/// Relative pose error over a fixed frame step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rpe {
    /// RMS translational drift per step, m.
    pub trans_rmse_m: f64,
    /// RMS rotational drift per step, degrees.
    pub rot_rmse_deg: f64,
    /// Relative motions compared.
    pub pairs: usize,
}

/// Estimate/reference pose pairs associated by nearest timestamp (greedy, one to one).
pub fn associate_poses<'a>(
    estimate: &'a [StampedPose],
    reference: &'a [StampedPose],
    max_dt_s: f64,
) -> Result<Vec<(&'a StampedPose, &'a StampedPose)>, VoError> {
    let times = |poses: &[StampedPose]| poses.iter().map(|p| p.timestamp_s).collect::<Vec<_>>();
    let pairs: Vec<_> = associate_times(&times(estimate), &times(reference), max_dt_s)
        .into_iter()
        .map(|(i, j)| (&estimate[i], &reference[j]))
        .collect();
    if pairs.is_empty() {
        return Err(VoError::NoCommonTimestamps {
            estimate: estimate.len(),
            reference: reference.len(),
            max_dt_s,
        });
    }
    Ok(pairs)
}

/// ATE: associates poses within `max_dt_s`, aligns the estimate's positions to the reference's
/// with Umeyama (rigid, as `evo_ape -a`), and summarises the remaining position errors.
pub fn ate(
    estimate: &[StampedPose],
    reference: &[StampedPose],
    max_dt_s: f64,
) -> Result<Ate, VoError> {
    let pairs = associate_poses(estimate, reference, max_dt_s)?;
    let position = |p: &StampedPose| Point3::from(p.t_world_camera.translation.vector);
    let est: Vec<_> = pairs.iter().map(|(e, _)| position(e)).collect();
    let gt: Vec<_> = pairs.iter().map(|(_, r)| position(r)).collect();
    let t_reference_estimate = umeyama(&est, &gt)?;
    let errors: Vec<(f64, f64)> = pairs
        .iter()
        .zip(est.iter().zip(&gt))
        .map(|((e, _), (pe, pg))| (e.timestamp_s, (pg - t_reference_estimate * pe).norm()))
        .collect();
    let n = errors.len() as f64;
    let mut sorted: Vec<f64> = errors.iter().map(|e| e.1).collect();
    sorted.sort_by(f64::total_cmp);
    let mid = sorted.len() / 2;
    let median_m = if sorted.len().is_multiple_of(2) {
        0.5 * (sorted[mid - 1] + sorted[mid])
    } else {
        sorted[mid]
    };
    Ok(Ate {
        rmse_m: (sorted.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
        mean_m: sorted.iter().sum::<f64>() / n,
        median_m,
        max_m: sorted.last().copied().unwrap_or(0.0),
        t_reference_estimate,
        errors,
    })
}

/// RPE between associated poses `step` apart (TUM/evo definition, no alignment needed):
/// `E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`.
pub fn rpe(
    estimate: &[StampedPose],
    reference: &[StampedPose],
    max_dt_s: f64,
    step: usize,
) -> Result<Rpe, VoError> {
    let pairs = associate_poses(estimate, reference, max_dt_s)?;
    let step = step.max(1);
    let (mut sum_t, mut sum_r, mut count) = (0.0, 0.0, 0usize);
    for (a, b) in pairs.iter().zip(pairs.iter().skip(step)) {
        let est = a.0.t_world_camera.inverse() * b.0.t_world_camera;
        let gt = a.1.t_world_camera.inverse() * b.1.t_world_camera;
        let e = gt.inverse() * est;
        sum_t += e.translation.vector.norm_squared();
        sum_r += e.rotation.angle().powi(2);
        count += 1;
    }
    if count == 0 {
        return Err(VoError::TooFewPoints {
            found: pairs.len(),
            needed: step + 1,
        });
    }
    Ok(Rpe {
        trans_rmse_m: (sum_t / count as f64).sqrt(),
        rot_rmse_deg: (sum_r / count as f64).sqrt().to_degrees(),
        pairs: count,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn circle(offset: Isometry3<f64>, noise: impl Fn(usize) -> f64) -> Vec<StampedPose> {
        (0..100)
            .map(|i| {
                let a = i as f64 * 0.06;
                let pose = Isometry3::new(
                    Vector3::new(a.cos(), a.sin(), 0.1 * a + noise(i)),
                    Vector3::new(0.0, 0.0, a),
                );
                StampedPose {
                    timestamp_s: i as f64 * 0.1,
                    t_world_camera: offset * pose,
                }
            })
            .collect()
    }

    #[test]
    fn ate_is_zero_after_alignment_of_a_moved_copy() {
        let gt = circle(Isometry3::identity(), |_| 0.0);
        let moved = circle(
            Isometry3::new(Vector3::new(3.0, -1.0, 0.5), Vector3::new(0.3, 0.2, 1.0)),
            |_| 0.0,
        );
        let r = ate(&moved, &gt, 0.02).expect("aligned");
        assert!(r.rmse_m < 1e-9, "{}", r.rmse_m);
        assert_eq!(r.errors.len(), 100);
        let d = rpe(&moved, &gt, 0.02, 1).expect("rpe");
        assert!(d.trans_rmse_m < 1e-9 && d.rot_rmse_deg < 1e-6);
    }

    #[test]
    fn ate_measures_known_offsets() {
        // Alternating +-1 cm along z cannot be aligned away: RMSE is exactly 1 cm.
        let gt = circle(Isometry3::identity(), |_| 0.0);
        let est = circle(
            Isometry3::identity(),
            |i| if i % 2 == 0 { 0.01 } else { -0.01 },
        );
        let r = ate(&est, &gt, 0.02).expect("aligned");
        assert!((r.rmse_m - 0.01).abs() < 1e-4, "{}", r.rmse_m);
        assert!((r.max_m - 0.01).abs() < 1e-3 && (r.median_m - 0.01).abs() < 1e-3);
        let d = rpe(&est, &gt, 0.02, 1).expect("rpe");
        assert!((d.trans_rmse_m - 0.02).abs() < 1e-3, "{}", d.trans_rmse_m);
    }

    #[test]
    fn disjoint_times_are_an_error() {
        let gt = circle(Isometry3::identity(), |_| 0.0);
        let late: Vec<_> = gt
            .iter()
            .map(|p| StampedPose {
                timestamp_s: p.timestamp_s + 100.0,
                ..*p
            })
            .collect();
        let err = ate(&late, &gt, 0.02).expect_err("no overlap");
        assert!(matches!(
            err,
            VoError::NoCommonTimestamps {
                estimate: 100,
                reference: 100,
                ..
            }
        ));
    }
}
