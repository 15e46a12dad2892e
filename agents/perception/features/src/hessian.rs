//! The box-filter scale space (thesis 2.8.4, Bay et al.): for each octave and level a map of
//! `det(H_approx) = Dxx Dyy - (0.9 Dxy)^2` sampled every `2^octave` px, plus the Laplacian sign.
//! LN-SURF divides the determinant by the variance of the working image under the filter
//! (thesis Algorithm 1, lines 11-14).
//!
//! Filter size of octave `o`, level `l` (both from 0): `3 (2^(o+1) (l+1) + 1)`, i.e. 9, 15, 21, 27
//! then 15, 27, 39, 51 then 27, 51, 75, 99 (thesis eq. 2.65).

use rayon::prelude::*;

use crate::integral::FIXED;
use crate::{DetectorConfig, IntegralImage};

/// Relative weight of `Dxy` (Bay et al.): keeps the box determinant close to the Gaussian one.
const DXY_WEIGHT: f32 = 0.9;

/// One response map.
#[derive(Debug, Default)]
pub(crate) struct Layer {
    /// Octave, from 0.
    pub(crate) octave: usize,
    /// Filter side, px.
    pub(crate) size: usize,
    /// Sampling step, px.
    pub(crate) step: usize,
    /// Map columns and rows.
    pub(crate) cols: usize,
    pub(crate) rows: usize,
    /// First and last map column/row where the whole filter lies inside the image (inclusive);
    /// `first > last` when the filter is larger than the image.
    pub(crate) first_col: usize,
    pub(crate) last_col: usize,
    pub(crate) first_row: usize,
    pub(crate) last_row: usize,
    /// Responses, row-major; 0 outside the valid window.
    pub(crate) responses: Vec<f32>,
    /// Laplacian sign (Dxx + Dyy >= 0), row-major.
    pub(crate) laplacian_positive: Vec<bool>,
}

impl Layer {
    /// Response at map column `c`, row `r` (callers stay inside the map).
    pub(crate) fn at(&self, c: usize, r: usize) -> f32 {
        self.responses[r * self.cols + c]
    }
}

/// All layers, octave-major (`layers[o * levels + l]`).
#[derive(Debug, Default)]
pub(crate) struct ScaleSpace {
    pub(crate) layers: Vec<Layer>,
    pub(crate) levels: usize,
}

/// Filter side for octave `o` and level `l` (thesis eq. 2.65).
pub(crate) fn filter_size(octave: usize, level: usize) -> usize {
    3 * ((1 << (octave + 1)) * (level + 1) + 1)
}

impl ScaleSpace {
    /// Fills every layer from the working integral image; `normalise` (LN-SURF) must carry the
    /// integral of squares of the same image.
    pub(crate) fn compute(&mut self, working: &IntegralImage, normalise: Option<&IntegralImage>, config: &DetectorConfig) {
        let (w, h) = (working.width(), working.height());
        let count = config.octaves * config.levels;
        self.levels = config.levels;
        self.layers.resize_with(count, Layer::default);
        for (i, layer) in self.layers.iter_mut().enumerate() {
            let (octave, level) = (i / config.levels, i % config.levels);
            let size = filter_size(octave, level);
            let step = 1 << octave;
            let half = (size - 1) / 2;
            layer.octave = octave;
            layer.size = size;
            layer.step = step;
            layer.cols = w.div_ceil(step);
            layer.rows = h.div_ceil(step);
            layer.first_col = half.div_ceil(step);
            layer.first_row = half.div_ceil(step);
            // Last centre c with c * step + half <= dim - 1; none when the filter exceeds the image.
            layer.last_col = if w > 2 * half { (w - 1 - half) / step } else { 0 };
            layer.last_row = if h > 2 * half { (h - 1 - half) / step } else { 0 };
            if w <= 2 * half || h <= 2 * half {
                layer.first_col = 1;
                layer.last_col = 0;
            }
            layer.responses.clear();
            layer.responses.resize(layer.cols * layer.rows, 0.0);
            layer.laplacian_positive.clear();
            layer.laplacian_positive.resize(layer.cols * layer.rows, false);
        }
        let min_variance = config.ln_min_variance;
        self.layers.par_iter_mut().for_each(|layer| fill(layer, working, normalise, min_variance));
    }
}

/// Corner offsets of one box relative to the centre's index in the integral table.
#[derive(Debug, Clone, Copy)]
struct BoxCorners([isize; 4]);

impl BoxCorners {
    /// Box over columns `x + dx0 ..= x + dx1`, rows `y + dy0 ..= y + dy1`.
    fn new(stride: usize, dx0: isize, dy0: isize, dx1: isize, dy1: isize) -> Self {
        let s = stride as isize;
        let at = |dx: isize, dy: isize| dy * s + dx;
        BoxCorners([at(dx1 + 1, dy1 + 1), at(dx1 + 1, dy0), at(dx0, dy1 + 1), at(dx0, dy0)])
    }

    fn sum(&self, table: &[u32], centre: usize) -> i32 {
        let at = |o: isize| table[centre.wrapping_add_signed(o)];
        let [a, b, c, d] = self.0;
        at(a).wrapping_sub(at(b)).wrapping_sub(at(c)).wrapping_add(at(d)) as i32
    }
}

fn fill(layer: &mut Layer, ii: &IntegralImage, normalise: Option<&IntegralImage>, min_variance: f32) {
    if layer.first_col > layer.last_col || layer.first_row > layer.last_row {
        return;
    }
    let stride = ii.stride();
    let table = ii.table();
    let (size, step) = (layer.size as isize, layer.step);
    let lobe = size / 3;
    let half = (size - 1) / 2;
    let lobe_half = (lobe - 1) / 2;
    // Dxx: +1 over the full (2 lobe - 1) x size band, -3 over its centre lobe => 1, -2, 1.
    let dxx_band = BoxCorners::new(stride, -half, -(lobe - 1), half, lobe - 1);
    let dxx_mid = BoxCorners::new(stride, -lobe_half, -(lobe - 1), lobe_half, lobe - 1);
    let dyy_band = BoxCorners::new(stride, -(lobe - 1), -half, lobe - 1, half);
    let dyy_mid = BoxCorners::new(stride, -(lobe - 1), -lobe_half, lobe - 1, lobe_half);
    // Dxy: + top-left, + bottom-right, - top-right, - bottom-left lobes, one pixel off the axes.
    let tl = BoxCorners::new(stride, -lobe, -lobe, -1, -1);
    let br = BoxCorners::new(stride, 1, 1, lobe, lobe);
    let tr = BoxCorners::new(stride, 1, -lobe, lobe, -1);
    let bl = BoxCorners::new(stride, -lobe, 1, -1, lobe);
    let area = (size * size) as f32;
    let scale = 1.0 / (area * FIXED);
    let (first_col, last_col, first_row, last_row, cols) =
        (layer.first_col, layer.last_col, layer.first_row, layer.last_row, layer.cols);
    let n = area as f64;
    layer
        .responses
        .par_chunks_mut(cols)
        .zip(layer.laplacian_positive.par_chunks_mut(cols))
        .enumerate()
        .filter(|(r, _)| (first_row..=last_row).contains(r))
        .for_each(|(r, (responses, laplacian))| {
            let y = r * step;
            for c in first_col..=last_col {
                let x = c * step;
                // Corner offsets already account for the table's zero first row and column.
                let centre = y * stride + x;
                let dxx = (dxx_band.sum(table, centre) - 3 * dxx_mid.sum(table, centre)) as f32 * scale;
                let dyy = (dyy_band.sum(table, centre) - 3 * dyy_mid.sum(table, centre)) as f32 * scale;
                let dxy = (tl.sum(table, centre) + br.sum(table, centre) - tr.sum(table, centre) - bl.sum(table, centre))
                    as f32
                    * scale;
                let mut det = dxx * dyy - (DXY_WEIGHT * dxy) * (DXY_WEIGHT * dxy);
                if let Some(sq) = normalise {
                    let (x0, y0) = ((x as isize - half) as usize, (y as isize - half) as usize);
                    let (x1, y1) = (x0 + size as usize, y0 + size as usize);
                    let mean = f64::from(sq.box_sum(x0, y0, x1, y1)) / n;
                    let mean_sq = sq.box_sum_squares(x0, y0, x1, y1).unwrap_or(0.0) / n;
                    let variance = ((mean_sq - mean * mean) as f32).max(min_variance);
                    det /= variance;
                }
                responses[c] = det;
                laplacian[c] = dxx + dyy >= 0.0;
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_sizes_follow_the_thesis() {
        let sizes: Vec<Vec<usize>> = (0..3).map(|o| (0..4).map(|l| filter_size(o, l)).collect()).collect();
        assert_eq!(sizes, vec![vec![9, 15, 21, 27], vec![15, 27, 39, 51], vec![27, 51, 75, 99]]);
    }
}
