//! Repeatability on real image sequences with ground-truth homographies (`img1..imgN` and
//! `H1toKp`): the thesis's protocol (eq. 4.66: 2 px, size ratio 1.5, `R = C / m_i`) where the
//! geometry is not the identity.
//!
//! Per pair (reference image 1, image i):
//! - only keypoints inside both images count: a reference keypoint whose centre maps inside
//!   image i, a keypoint of image i whose centre maps back inside the reference;
//! - reference keypoints are mapped into image i, their size multiplied by the homography's local
//!   scale there ([`Homography::local_scale`]); correspondences are then counted exactly as in
//!   [`crate::experiment::correspondences`];
//! - `R = C / m_i` (the thesis's rate) and the symmetric `C / min(m_1, m_i)` (Mikolajczyk et al.),
//!   which does not reward a detector for losing keypoints nor punish it for finding more in the
//!   dark than it found in the reference;
//! - the matching score: descriptor matches (computed by the caller) whose ends correspond under
//!   the same criterion, over `min(m_1, m_i)` (Mikolajczyk and Schmid 2005).

use crate::experiment::{DIST_TOL_PX, SIZE_TOL, correspondences};
use crate::homography::Homography;
use crate::{Keypoint, Match};

/// The scores of one pair, in percent where a rate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PairScore {
    /// Keypoints of the reference image in the region both images see (`m_1`).
    pub reference_keypoints: usize,
    /// Keypoints of image i in that region (`m_i`).
    pub keypoints: usize,
    /// Keypoints of the whole reference image.
    pub reference_keypoints_total: usize,
    /// Keypoints of the whole image i.
    pub keypoints_total: usize,
    /// One-to-one correspondences `C`.
    pub correspondences: usize,
    /// `100 C / m_i` (thesis eq. 4.66).
    pub repeatability: f64,
    /// `100 C / min(m_1, m_i)`.
    pub repeatability_symmetric: f64,
    /// Descriptor matches with both ends in the common region.
    pub matches: usize,
    /// Those whose ends correspond (within 2 px and size ratio 1.5 after mapping).
    pub correct_matches: usize,
    /// `100 correct_matches / min(m_1, m_i)`.
    pub matching_score: f64,
}

/// `(width, height)` of an image, px.
pub type Size = (u32, u32);

fn inside((x, y): (f64, f64), (w, h): Size) -> bool {
    x >= 0.0 && y >= 0.0 && x <= f64::from(w) - 1.0 && y <= f64::from(h) - 1.0
}

/// The reference keypoint as seen in image i, if its centre lands inside image i.
fn mapped(kp: &Keypoint, h: &Homography, size: Size) -> Option<Keypoint> {
    let (x, y) = h.map(f64::from(kp.x), f64::from(kp.y))?;
    inside((x, y), size).then(|| Keypoint {
        x: x as f32,
        y: y as f32,
        size: kp.size * h.local_scale(f64::from(kp.x), f64::from(kp.y)) as f32,
        ..*kp
    })
}

fn seen_by_reference(kp: &Keypoint, h: &Homography, size: Size) -> bool {
    h.map_inverse(f64::from(kp.x), f64::from(kp.y))
        .is_some_and(|p| inside(p, size))
}

fn corresponds(a: &Keypoint, b: &Keypoint) -> bool {
    let d = (a.x - b.x).hypot(a.y - b.y);
    let ratio = a.size / b.size.max(1e-12);
    d <= DIST_TOL_PX && (1.0 / SIZE_TOL..=SIZE_TOL).contains(&ratio)
}

fn percent(n: usize, of: usize) -> f64 {
    if of == 0 {
        0.0
    } else {
        100.0 * n as f64 / of as f64
    }
}

/// Scores one pair: `reference` keypoints of image 1 (`reference_size`), `other` of image i
/// (`other_size`), `h` from image 1 to image i, `matches` with `query_index` into `reference`
/// and `train_index` into `other` (out-of-range indices are ignored).
pub fn score_pair(
    reference: &[Keypoint],
    reference_size: Size,
    other: &[Keypoint],
    other_size: Size,
    h: &Homography,
    matches: &[Match],
) -> PairScore {
    let mapped_reference: Vec<Option<Keypoint>> = reference
        .iter()
        .map(|kp| mapped(kp, h, other_size))
        .collect();
    let common_reference: Vec<Keypoint> = mapped_reference.iter().flatten().copied().collect();
    let in_common: Vec<bool> = other
        .iter()
        .map(|kp| seen_by_reference(kp, h, reference_size))
        .collect();
    let common_other: Vec<Keypoint> = other
        .iter()
        .zip(&in_common)
        .filter(|(_, c)| **c)
        .map(|(kp, _)| *kp)
        .collect();
    let (m1, mi) = (common_reference.len(), common_other.len());
    let c = correspondences(&common_other, &common_reference);
    let mut matched = 0;
    let mut correct = 0;
    for m in matches {
        let (Some(Some(a)), Some(b), Some(true)) = (
            mapped_reference.get(m.query_index),
            other.get(m.train_index),
            in_common.get(m.train_index),
        ) else {
            continue;
        };
        matched += 1;
        correct += usize::from(corresponds(b, a));
    }
    PairScore {
        reference_keypoints: m1,
        keypoints: mi,
        reference_keypoints_total: reference.len(),
        keypoints_total: other.len(),
        correspondences: c,
        repeatability: percent(c, mi),
        repeatability_symmetric: percent(c, m1.min(mi)),
        matches: matched,
        correct_matches: correct,
        matching_score: percent(correct, m1.min(mi)),
    }
}

/// Largest residual of a match used to check the pixel convention, px: wrong matches are
/// farther, while a convention error is at most about a pixel.
pub const CONVENTION_GATE_PX: f64 = 5.0;

/// Residuals (px) of the descriptor `matches` under the homography read with each pixel
/// `origins` (see [`Homography::with_pixel_origin`]): one vector per origin, over the same
/// matches, those within [`CONVENTION_GATE_PX`] under every origin.
pub fn origin_residuals(
    reference: &[Keypoint],
    other: &[Keypoint],
    h: &Homography,
    matches: &[Match],
    origins: &[f64],
) -> Vec<Vec<f64>> {
    let shifted: Vec<Homography> = origins.iter().map(|&o| h.with_pixel_origin(o)).collect();
    let mut out = vec![Vec::new(); origins.len()];
    for m in matches {
        let (Some(a), Some(b)) = (reference.get(m.query_index), other.get(m.train_index)) else {
            continue;
        };
        let residuals: Option<Vec<f64>> = shifted
            .iter()
            .map(|h| {
                let (x, y) = h.map(f64::from(a.x), f64::from(a.y))?;
                let r = (x - f64::from(b.x)).hypot(y - f64::from(b.y));
                (r <= CONVENTION_GATE_PX).then_some(r)
            })
            .collect();
        if let Some(residuals) = residuals {
            for (o, r) in out.iter_mut().zip(residuals) {
                o.push(r);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::tests::kp;

    #[test]
    fn counts_only_the_common_region_and_scales_sizes() {
        // Image 2 is image 1 shifted 50 px right and zoomed 2x: x' = 2 x + 50, y' = 2 y.
        let h = Homography::parse("2 0 50 0 2 0 0 0 1").unwrap();
        let size = (200, 200);
        let reference = [
            kp(10.0, 10.0, 10.0), // -> (70, 20), size 20: repeated
            kp(20.0, 30.0, 10.0), // -> (90, 60): nobody there
            kp(90.0, 10.0, 10.0), // -> (230, 20): outside image 2, not counted
            kp(40.0, 40.0, 10.0), // -> (130, 80), but image 2 finds it at size 10: ratio 2
        ];
        let other = [
            kp(71.0, 21.0, 22.0),
            kp(130.0, 80.0, 10.0),
            kp(10.0, 10.0, 10.0), // maps back to (-20, 5): outside the reference
            kp(150.0, 150.0, 10.0),
        ];
        let matches = [
            Match {
                query_index: 0,
                train_index: 0,
                distance: 0.1,
            },
            Match {
                query_index: 3,
                train_index: 1,
                distance: 0.1,
            },
            Match {
                query_index: 1,
                train_index: 3,
                distance: 0.1,
            },
            Match {
                query_index: 2,
                train_index: 3,
                distance: 0.1,
            },
            Match {
                query_index: 9,
                train_index: 0,
                distance: 0.1,
            },
        ];
        let s = score_pair(&reference, size, &other, size, &h, &matches);
        assert_eq!((s.reference_keypoints, s.keypoints), (3, 3));
        assert_eq!((s.reference_keypoints_total, s.keypoints_total), (4, 4));
        assert_eq!(s.correspondences, 1);
        assert!((s.repeatability - 100.0 / 3.0).abs() < 1e-9);
        assert!((s.repeatability_symmetric - 100.0 / 3.0).abs() < 1e-9);
        assert_eq!((s.matches, s.correct_matches), (3, 1));
        assert!((s.matching_score - 100.0 / 3.0).abs() < 1e-9);
    }

    #[test]
    fn symmetric_rate_divides_by_the_smaller_count() {
        let h = Homography::parse("1 0 0 0 1 0 0 0 1").unwrap();
        let reference = [kp(10.0, 10.0, 9.0)];
        let other = [kp(10.0, 10.0, 9.0), kp(50.0, 50.0, 9.0)];
        let s = score_pair(&reference, (100, 100), &other, (100, 100), &h, &[]);
        assert_eq!(s.repeatability, 50.0);
        assert_eq!(s.repeatability_symmetric, 100.0);
        assert_eq!(s.matching_score, 0.0);
        let empty = score_pair(&[], (100, 100), &[], (100, 100), &h, &[]);
        assert_eq!(
            (empty.repeatability, empty.repeatability_symmetric),
            (0.0, 0.0)
        );
    }

    #[test]
    fn the_right_origin_has_the_smallest_residuals() {
        // Ground truth written 1-based: a 1.5x zoom; the keypoints obey it in 0-based terms.
        let h = Homography::parse("1.5 0 0 0 1.5 0 0 0 1").unwrap();
        let truth = h.with_pixel_origin(1.0);
        let reference: Vec<Keypoint> = (0..20)
            .map(|i| kp(10.0 + 3.0 * i as f32, 20.0 + 2.0 * i as f32, 9.0))
            .collect();
        let other: Vec<Keypoint> = reference
            .iter()
            .map(|k| {
                let (x, y) = truth.map(f64::from(k.x), f64::from(k.y)).unwrap();
                kp(x as f32, y as f32, 13.5)
            })
            .collect();
        let matches: Vec<Match> = (0..20)
            .map(|i| Match {
                query_index: i,
                train_index: i,
                distance: 0.0,
            })
            .collect();
        let r = origin_residuals(&reference, &other, &h, &matches, &[0.0, 0.5, 1.0]);
        let mean = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
        assert_eq!(r[2].len(), 20);
        assert!(mean(&r[2]) < 1e-4, "1-based fits: {}", mean(&r[2]));
        assert!(mean(&r[0]) > 0.4 && mean(&r[1]) > 0.2);
    }
}
