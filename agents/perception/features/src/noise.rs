//! The noise model of LSAC-SURF-NT: how strong a response the camera's own noise gives at each
//! keypoint, estimated from the image itself.
//!
//! Why: LSAC-SURF divides the image by its local average `a`, which makes the working image
//! invariant to the light's gain but multiplies sensor noise by `255 / (2 a)`: in a dark region
//! noise becomes full-contrast texture and the box-filter Hessian finds blobs in it. A fixed
//! threshold cannot tell those from structure; a threshold that follows the local noise can.
//!
//! Model: the input's noise `sigma` (8-bit units) is signal-independent (read noise and
//! rounding: the regime where dim light is noisy), so in the working image it is
//! `sigma_w(a) = 255 sigma / (2 a)`, per region through the local average `a` at the keypoint.
//! In the per-channel space (the default) the working image is the luma of `I_k / (2 a_k)`, so
//! each channel's noise is estimated on its own and carried through its own average:
//! `sigma_w^2 = sum_k (w_k 255 sigma_k / (2 a_k))^2`. A gain on one channel (a change of
//! illuminant colour, LCC) scales `sigma_k` and `a_k` together and leaves the model as the
//! working image: unchanged; the luma's noise over the luma's average would not be.
//! For a filter of side `L` (lobe `l = L / 3`) white noise of variance `s^2` gives
//! `var(Dxx) = s^2 v(L)`, `v(L) = 6 l (2 l - 1) / L^4` (unit box weights 1, -2, 1 over
//! `(2 l - 1) x l` cells each, normalised by the area `L^2`), and the determinant of noise scales
//! as `s^2 v(L)`: that is the noise unit a keypoint's response is compared with.
//!
//! Estimate of `sigma`: Immerkaer's (1996) finest-scale operator, the 3x3 difference of two
//! Laplacians, which cancels any locally planar signal; per tile `sqrt(pi / 2) / 6` times the
//! mean absolute response, and over the image a low quantile of the tiles (texture only raises a
//! tile's figure; tiles with a saturated pixel are skipped: clipping hides noise). Never below
//! the 8-bit rounding noise `1 / sqrt(12)`. Assumption (the thesis is silent): noise is white;
//! demosaicing and JPEG correlate it, which the factor absorbs.

use crate::image32::{GrayImage32, LUMA_WEIGHTS};
use crate::{DetectorConfig, Keypoint, LsacSpace};

/// Rounding noise of an 8-bit image, 8-bit units: the least noise an 8-bit input can carry.
const ROUNDING_SIGMA: f32 = 0.288_675_13;
/// Quantile of the tiles' noise figures taken as the image's noise (texture only raises a tile).
const TILE_QUANTILE: f32 = 0.25;

/// Variance of a unit-noise `Dxx` box response at filter side `size` (see the module docs).
fn white_noise_variance(size: f32) -> f32 {
    let lobe = size / 3.0;
    6.0 * lobe * (2.0 * lobe - 1.0) / size.powi(4)
}

/// The noise model of one image.
pub(crate) struct NoiseFloor {
    /// Luma weight and noise (8-bit units) of each channel the working image divides by its own
    /// local average (the gray space: the gray image, weight 1, then two empty terms).
    terms: [(f32, f32); 3],
    factor: f32,
    base: f32,
    min_average: f32,
}

impl NoiseFloor {
    /// Estimates the noise of `image` for `config` (whose `noise_factor` is > 0); `plane` is
    /// scratch.
    pub(crate) fn measure(
        image: &image::RgbImage,
        plane: &mut GrayImage32,
        config: &DetectorConfig,
    ) -> Self {
        let tile = config.noise_tile_px;
        let terms = if config.lsac_space == LsacSpace::PerChannel {
            std::array::from_fn(|c| {
                plane.channel_into(image, c);
                (LUMA_WEIGHTS[c], estimate_sigma(plane, tile))
            })
        } else {
            plane.luma_into(image);
            [(1.0, estimate_sigma(plane, tile)), (0.0, 0.0), (0.0, 0.0)]
        };
        NoiseFloor {
            terms,
            factor: config.noise_factor,
            base: config.threshold,
            min_average: config.lsac_min_average,
        }
    }

    /// The determinant that noise alone gives at the 9x9 filter where the local averages are
    /// `averages` (per channel, as `Scratch::local_averages_at` gives them): the noise unit of
    /// that region.
    pub(crate) fn unit(&self, averages: [f32; 3]) -> f32 {
        let variance: f32 = self
            .terms
            .iter()
            .zip(averages)
            .map(|(&(weight, sigma), average)| {
                (weight * 255.0 * sigma / (2.0 * average.max(self.min_average))).powi(2)
            })
            .sum();
        variance * white_noise_variance(9.0)
    }

    /// The response `kp` must exceed where the noise unit is `unit`: the base threshold or
    /// `noise_factor` noise units at its filter size, whichever is higher.
    pub(crate) fn threshold(&self, kp: &Keypoint, unit: f32) -> f32 {
        let at_size = white_noise_variance(kp.size.max(9.0)) / white_noise_variance(9.0);
        self.base.max(self.factor * unit * at_size)
    }
}

/// Immerkaer's noise estimate of `gray` (see the module docs), tiles of `tile` px.
fn estimate_sigma(gray: &GrayImage32, tile: usize) -> f32 {
    let (w, h) = (gray.width(), gray.height());
    let tile = tile.max(4);
    let px = gray.as_slice();
    let mut figures = Vec::new();
    for ty in (1..h.saturating_sub(1)).step_by(tile) {
        for tx in (1..w.saturating_sub(1)).step_by(tile) {
            let (y1, x1) = ((ty + tile).min(h - 1), (tx + tile).min(w - 1));
            let mut sum = 0.0f64;
            let mut saturated = false;
            for y in ty..y1 {
                for x in tx..x1 {
                    let at = |dx: usize, dy: usize| px[(y + dy - 1) * w + x + dx - 1];
                    saturated |= at(1, 1) >= 254.5;
                    let v = 4.0 * at(1, 1) - 2.0 * (at(0, 1) + at(2, 1) + at(1, 0) + at(1, 2))
                        + (at(0, 0) + at(2, 0) + at(0, 2) + at(2, 2));
                    sum += f64::from(v.abs());
                }
            }
            let n = (y1 - ty) * (x1 - tx);
            if !saturated && n >= 16 {
                let mean = sum / n as f64;
                figures.push(((std::f64::consts::PI / 2.0).sqrt() / 6.0 * mean) as f32);
            }
        }
    }
    if figures.is_empty() {
        return ROUNDING_SIGMA;
    }
    let at = ((figures.len() - 1) as f32 * TILE_QUANTILE).round() as usize;
    let (_, q, _) = figures.select_nth_unstable_by(at, f32::total_cmp);
    q.max(ROUNDING_SIGMA)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth ramp with a deterministic pseudo-Gaussian noise of `sigma` (sum of 12 uniforms).
    fn noisy_ramp(w: usize, h: usize, sigma: f32) -> GrayImage32 {
        let mut img = GrayImage32::new(w, h);
        let mut state = 0x9e37_79b9_u32;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        for y in 0..h {
            for x in 0..w {
                let n: f32 = (0..12).map(|_| uniform()).sum::<f32>() - 6.0;
                img.as_mut_slice()[y * w + x] = 60.0 + 0.2 * x as f32 + 0.1 * y as f32 + sigma * n;
            }
        }
        img
    }

    #[test]
    fn the_estimate_recovers_the_noise_of_a_planar_image() {
        for sigma in [1.0, 3.0, 8.0] {
            let got = estimate_sigma(&noisy_ramp(256, 192, sigma), 32);
            assert!(
                (got - sigma).abs() < 0.15 * sigma,
                "added {sigma}, estimated {got}"
            );
        }
        // No noise at all: an 8-bit image still carries its rounding.
        assert_eq!(estimate_sigma(&noisy_ramp(64, 64, 0.0), 32), ROUNDING_SIGMA);
    }

    #[test]
    fn the_floor_rises_where_the_region_is_dark() {
        let config = DetectorConfig::for_kind(crate::DetectorKind::LsacSurfNt);
        let floor = NoiseFloor {
            terms: [(1.0, 2.0), (0.0, 0.0), (0.0, 0.0)],
            factor: 10.0,
            base: 0.0,
            min_average: 4.0,
        };
        // Half the light, four times the noise unit (the division by `a` doubles sigma_w).
        assert!((floor.unit([20.0; 3]) / floor.unit([40.0; 3]) - 4.0).abs() < 1e-4);
        // Below the LSAC divisor's floor the model stops growing, as the working image does.
        assert_eq!(
            floor.unit([1.0; 3]),
            floor.unit([config.lsac_min_average; 3])
        );
    }

    #[test]
    fn a_gain_on_one_channel_leaves_the_per_channel_unit_unchanged() {
        let floor = |sigmas: [f32; 3]| NoiseFloor {
            terms: std::array::from_fn(|c| (LUMA_WEIGHTS[c], sigmas[c])),
            factor: 10.0,
            base: 0.0,
            min_average: 4.0,
        };
        let (sigmas, averages) = ([1.5, 2.0, 0.8], [60.0, 90.0, 30.0]);
        // Red and green at 0.3 (LCC): their noise and their averages scale together.
        let gain = [0.3, 0.3, 1.0];
        let relit = floor(std::array::from_fn(|c| sigmas[c] * gain[c]));
        let before = floor(sigmas).unit(averages);
        let after = relit.unit(std::array::from_fn(|c| averages[c] * gain[c]));
        assert!((after / before - 1.0).abs() < 1e-5, "{before} -> {after}");
        // The luma model (one sigma over the luma average) is not invariant to it.
        let luma = |g: [f32; 3]| {
            let a: f32 = (0..3).map(|c| LUMA_WEIGHTS[c] * averages[c] * g[c]).sum();
            let s: f32 = (0..3)
                .map(|c| (LUMA_WEIGHTS[c] * sigmas[c] * g[c]).powi(2))
                .sum::<f32>()
                .sqrt();
            (s / a).powi(2)
        };
        assert!((luma(gain) / luma([1.0; 3]) - 1.0).abs() > 0.05);
    }

    #[test]
    fn the_floor_falls_with_the_filter_size_as_white_noise() {
        assert!((white_noise_variance(9.0) - 90.0 / 6561.0).abs() < 1e-9);
        // 15x15: lobe 5, 6 * 5 * 9 / 15^4.
        assert!((white_noise_variance(15.0) - 270.0 / 50625.0).abs() < 1e-9);
        assert!(white_noise_variance(27.0) < white_noise_variance(15.0));
    }
}
