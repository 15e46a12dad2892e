//! The thesis's illumination experiments (4.6): synthetic relighting collections, the
//! repeatability protocol (eq. 4.66, after Schmid et al.); the Wilcoxon signed-rank test is `iw_stats`.
//!
//! Protocol, identity geometry: a relit keypoint corresponds to an unused reference keypoint
//! within [`DIST_TOL_PX`] px and a size ratio within [`SIZE_TOL`], one-to-one, nearest pairs
//! first; `R = 100 * correspondences / keypoints in the relit image` (0 when it has none).

use image::RgbImage;

use crate::Keypoint;

/// Largest centre distance of a correspondence, px.
pub const DIST_TOL_PX: f32 = 2.0;
/// Largest size ratio of a correspondence (either way).
pub const SIZE_TOL: f32 = 1.5;

/// A synthetic illumination change (thesis 4.6.1), applied in float then clipped and rounded to
/// 8 bits as a camera would store it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Relight {
    /// LIC: all channels times `a`.
    Intensity(f32),
    /// LIS: all channels plus `b` (8-bit units).
    Shift(f32),
    /// LCC: red and green times `a`, blue unchanged.
    Colour(f32),
}

/// The three collections in the thesis's order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Collection {
    /// Light intensity change.
    Lic,
    /// Light intensity shift.
    Lis,
    /// Light colour change.
    Lcc,
}

impl Collection {
    /// All collections.
    pub const ALL: [Collection; 3] = [Collection::Lic, Collection::Lis, Collection::Lcc];

    /// Lower-case name used in file and JSON keys: `lic`, `lis`, `lcc`.
    pub fn name(self) -> &'static str {
        match self {
            Collection::Lic => "lic",
            Collection::Lis => "lis",
            Collection::Lcc => "lcc",
        }
    }

    /// The relit versions of the collection, the reference (a = 1, b = 0) excluded because it
    /// would score 100 % by construction.
    pub fn changes(self) -> Vec<Relight> {
        match self {
            Collection::Lic => [
                1.0 / 2.0,
                1.0 / 1.5,
                1.0 / 1.2,
                1.0 / 1.1,
                1.1,
                1.2,
                1.5,
                2.0,
            ]
            .map(Relight::Intensity)
            .to_vec(),
            Collection::Lis => [-20.0, -15.0, -10.0, -5.0, 5.0, 10.0, 15.0, 20.0]
                .map(Relight::Shift)
                .to_vec(),
            Collection::Lcc => [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
                .map(Relight::Colour)
                .to_vec(),
        }
    }
}

impl Relight {
    /// The parameter (`a` or `b`).
    pub fn parameter(self) -> f32 {
        match self {
            Relight::Intensity(v) | Relight::Shift(v) | Relight::Colour(v) => v,
        }
    }

    /// The relit image, 8-bit, clipped and rounded half up.
    pub fn apply(self, image: &RgbImage) -> RgbImage {
        let mut out = image.clone();
        for px in out.pixels_mut() {
            for (c, v) in px.0.iter_mut().enumerate() {
                let f = f32::from(*v);
                let g = match self {
                    Relight::Intensity(a) => f * a,
                    Relight::Shift(b) => f + b,
                    Relight::Colour(a) if c < 2 => f * a,
                    Relight::Colour(_) => f,
                };
                *v = (g.clamp(0.0, 255.0) + 0.5).floor() as u8;
            }
        }
        out
    }
}

/// Repeatability (percent) of `relit` keypoints against `reference` ones (thesis eq. 4.66).
pub fn repeatability(relit: &[Keypoint], reference: &[Keypoint]) -> f64 {
    if relit.is_empty() {
        return 0.0;
    }
    100.0 * correspondences(relit, reference) as f64 / relit.len() as f64
}

/// The number of one-to-one correspondences `C` between two keypoint sets in the same frame:
/// pairs within [`DIST_TOL_PX`] and a size ratio within [`SIZE_TOL`], nearest pairs first.
pub fn correspondences(relit: &[Keypoint], reference: &[Keypoint]) -> usize {
    if relit.is_empty() || reference.is_empty() {
        return 0;
    }
    // Candidate pairs within tolerance, via a grid of DIST_TOL_PX cells over the reference.
    let cell = DIST_TOL_PX;
    let key = |x: f32, y: f32| ((x / cell).floor() as i64, (y / cell).floor() as i64);
    let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> =
        std::collections::HashMap::new();
    for (j, kp) in reference.iter().enumerate() {
        grid.entry(key(kp.x, kp.y)).or_default().push(j);
    }
    let mut pairs: Vec<(f32, usize, usize)> = Vec::new();
    for (i, kp) in relit.iter().enumerate() {
        let (gx, gy) = key(kp.x, kp.y);
        for dy in -1..=1 {
            for dx in -1..=1 {
                for &j in grid
                    .get(&(gx + dx, gy + dy))
                    .map(Vec::as_slice)
                    .unwrap_or(&[])
                {
                    let r = &reference[j];
                    let d = ((kp.x - r.x).powi(2) + (kp.y - r.y).powi(2)).sqrt();
                    let ratio = kp.size / r.size.max(1e-12);
                    if d <= DIST_TOL_PX && (1.0 / SIZE_TOL..=SIZE_TOL).contains(&ratio) {
                        pairs.push((d, i, j));
                    }
                }
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let (mut used_relit, mut used_ref) = (vec![false; relit.len()], vec![false; reference.len()]);
    let mut n = 0usize;
    for (_, i, j) in pairs {
        if !used_relit[i] && !used_ref[j] {
            used_relit[i] = true;
            used_ref[j] = true;
            n += 1;
        }
    }
    n
}

/// Median, mean and interquartile range (linear interpolation between order statistics, as
/// numpy's default) of a sample.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Median.
    pub median: f64,
    /// Arithmetic mean.
    pub mean: f64,
    /// Third minus first quartile.
    pub iqr: f64,
    /// Sample size.
    pub n: usize,
}

/// Quantile `q` in `[0, 1]` of sorted data (numpy "linear"); `None` when empty.
pub fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    let last = sorted.len().checked_sub(1)?;
    let pos = q.clamp(0.0, 1.0) * last as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    Some(sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64))
}

impl Summary {
    /// Summary of `values` (NaNs sorted last; an empty sample gives zeros and `n = 0`).
    pub fn of(values: &[f64]) -> Summary {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let q = |p| quantile(&v, p).unwrap_or(0.0);
        let mean = if v.is_empty() {
            0.0
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        };
        Summary {
            median: q(0.5),
            mean,
            iqr: q(0.75) - q(0.25),
            n: v.len(),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::FeatureClass;

    /// A hard keypoint at `(x, y)` of diameter `size` px (shared with `sequence`'s tests).
    pub(crate) fn kp(x: f32, y: f32, size: f32) -> Keypoint {
        Keypoint {
            x,
            y,
            scale: size * 1.2 / 9.0,
            size,
            orientation: 0.0,
            response: 1.0,
            laplacian_sign: 1,
            class: FeatureClass::Hard,
        }
    }

    #[test]
    fn protocol_counts_one_to_one_within_tolerances() {
        let reference = [kp(10.0, 10.0, 9.0), kp(50.0, 50.0, 9.0)];
        // Two relit keypoints compete for the first reference one: only the nearer counts.
        let relit = [
            kp(10.5, 10.0, 9.0),
            kp(11.0, 10.0, 9.0),
            kp(50.0, 51.0, 20.0),
            kp(90.0, 90.0, 9.0),
        ];
        assert_eq!(repeatability(&relit, &reference), 25.0);
        assert_eq!(repeatability(&reference, &reference), 100.0);
        assert_eq!(repeatability(&[], &reference), 0.0);
    }

    #[test]
    fn relighting_clips_and_rounds() {
        let img = RgbImage::from_pixel(1, 1, image::Rgb([100, 200, 50]));
        assert_eq!(
            Relight::Intensity(1.5).apply(&img).get_pixel(0, 0).0,
            [150, 255, 75]
        );
        assert_eq!(
            Relight::Shift(-60.0).apply(&img).get_pixel(0, 0).0,
            [40, 140, 0]
        );
        assert_eq!(
            Relight::Colour(0.25).apply(&img).get_pixel(0, 0).0,
            [25, 50, 50]
        );
        assert_eq!(
            Relight::Intensity(0.5)
                .apply(&RgbImage::from_pixel(1, 1, image::Rgb([3, 3, 3])))
                .get_pixel(0, 0)
                .0,
            [2, 2, 2]
        );
    }

    #[test]
    fn summary_matches_numpy() {
        let s = Summary::of(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!((s.median, s.mean, s.iqr, s.n), (2.5, 2.5, 1.5, 4));
    }
}
