//! The noise floor of LSAC-SURF-NT: how strong a response pure image noise gives, measured per
//! tile from the image itself.
//!
//! Why: LSAC-SURF divides the image by its local average, which makes the working image
//! invariant to the light's gain but multiplies sensor noise by `255 / (2 a)`: in a dark region
//! (small `a`) noise becomes full-contrast texture and the box-filter Hessian finds blobs in it.
//! A fixed threshold cannot tell those from structure; a threshold that scales with the local
//! noise can.
//!
//! Estimate: in each tile, the median absolute deviation (MAD) of the finest layer's response
//! (9x9 filters, every pixel). Most of a tile is not a keypoint, so the median ignores the
//! structure that keypoints sit on and follows the noise. For a larger filter of side `L` (lobe
//! `l = L / 3`) white noise of variance `s^2` gives `var(Dxx) = s^2 * 6 l (2 l - 1) / L^4`
//! (unit box weights 1, -2, 1 over `(2 l - 1) x l` cells each, normalised by the area `L^2`), and
//! the determinant scales with that variance: the floor at size `L` is the 9x9 floor times
//! `v(L) / v(9)`. Assumption (the thesis is silent): noise is white; correlated noise (demosaicing,
//! JPEG) makes the coarser floors optimistic, never stricter than the 9x9 one.

use crate::hessian::ScaleSpace;
use crate::{DetectorConfig, Keypoint};

/// Variance of a unit-noise `Dxx` box response at filter side `size` (see the module docs).
fn white_noise_variance(size: f32) -> f32 {
    let lobe = size / 3.0;
    6.0 * lobe * (2.0 * lobe - 1.0) / size.powi(4)
}

/// Per-tile noise thresholds, from the finest layer.
pub(crate) struct NoiseFloor {
    tile_px: usize,
    cols: usize,
    rows: usize,
    /// `noise_factor * MAD` of the 9x9 responses per tile, row-major; 0 for a tile with no valid
    /// response (the base threshold then decides alone).
    floors: Vec<f32>,
    base: f32,
}

impl NoiseFloor {
    /// Measures the floor on `space` (computed with `config`, whose `noise_factor` is > 0).
    pub(crate) fn measure(space: &ScaleSpace, config: &DetectorConfig) -> Self {
        let tile_px = config.noise_tile_px.max(1);
        let Some(layer) = space.layers.first() else {
            return NoiseFloor {
                tile_px,
                cols: 0,
                rows: 0,
                floors: Vec::new(),
                base: config.threshold,
            };
        };
        // The finest layer samples every pixel: its map is the image's size.
        let (cols, rows) = (layer.cols.div_ceil(tile_px), layer.rows.div_ceil(tile_px));
        let mut floors = vec![0.0; cols * rows];
        let valid = layer.first_col <= layer.last_col && layer.first_row <= layer.last_row;
        let mut values = Vec::with_capacity(tile_px * tile_px);
        for ty in 0..rows {
            for tx in 0..cols {
                values.clear();
                if valid {
                    let r0 = (ty * tile_px).max(layer.first_row);
                    let r1 = ((ty + 1) * tile_px).min(layer.last_row + 1);
                    let c0 = (tx * tile_px).max(layer.first_col);
                    let c1 = ((tx + 1) * tile_px).min(layer.last_col + 1);
                    for r in r0..r1 {
                        if c0 < c1 {
                            values.extend_from_slice(
                                &layer.responses[r * layer.cols + c0..r * layer.cols + c1],
                            );
                        }
                    }
                }
                floors[ty * cols + tx] = config.noise_factor * mad(&mut values);
            }
        }
        NoiseFloor {
            tile_px,
            cols,
            rows,
            floors,
            base: config.threshold,
        }
    }

    /// The response `kp` must exceed: the base threshold or its tile's noise floor at its size,
    /// whichever is higher.
    pub(crate) fn threshold(&self, kp: &Keypoint) -> f32 {
        if self.cols == 0 || self.rows == 0 {
            return self.base;
        }
        let tx = ((kp.x.max(0.0) as usize) / self.tile_px).min(self.cols - 1);
        let ty = ((kp.y.max(0.0) as usize) / self.tile_px).min(self.rows - 1);
        let at_size = white_noise_variance(kp.size.max(9.0)) / white_noise_variance(9.0);
        self.base.max(self.floors[ty * self.cols + tx] * at_size)
    }
}

/// Median absolute deviation from the median (0 for an empty sample); reorders `values`.
fn mad(values: &mut [f32]) -> f32 {
    let Some(median) = median_of(values) else {
        return 0.0;
    };
    for v in values.iter_mut() {
        *v = (*v - median).abs();
    }
    median_of(values).unwrap_or(0.0)
}

/// The upper median (no averaging: a robust statistic needs no interpolation).
fn median_of(values: &mut [f32]) -> Option<f32> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f32::total_cmp);
    Some(*m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mad_ignores_a_minority_of_outliers() {
        // Median 3, deviations 2, 1, 0, 1, 2 and two huge ones: MAD 2.
        let mut v = vec![1.0, 2.0, 3.0, 4.0, 5.0, 1000.0, -1000.0];
        assert_eq!(mad(&mut v), 2.0);
        assert_eq!(mad(&mut []), 0.0);
    }

    #[test]
    fn the_floor_falls_with_the_filter_size_as_white_noise() {
        assert!((white_noise_variance(9.0) - 90.0 / 6561.0).abs() < 1e-9);
        // 15x15: lobe 5, 6 * 5 * 9 / 15^4.
        assert!((white_noise_variance(15.0) - 270.0 / 50625.0).abs() < 1e-9);
        assert!(white_noise_variance(27.0) < white_noise_variance(15.0));
    }
}
