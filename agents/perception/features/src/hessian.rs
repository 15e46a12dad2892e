//! The box-filter scale space (thesis 2.8.4, Bay et al.): for each octave and level a map of
//! `det(H_approx) = Dxx Dyy - (0.9 Dxy)^2` sampled every `2^octave` px, plus the Laplacian sign.
//! LN-SURF divides the determinant by the variance of the working image under the filter
//! (thesis Algorithm 1, lines 11-14).
//!
//! Filter size of octave `o`, level `l` (both from 0): `3 (2^(o+1) (l+1) + 1)`, i.e. 9, 15, 21, 27
//! then 15, 27, 39, 51 then 27, 51, 75, 99 (thesis eq. 2.65).

use rayon::prelude::*;

use crate::integral::FIXED;
use crate::simd;
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
    /// Zeroes the samples outside the valid window (the window itself is overwritten by `fill`
    /// or `subsample`), instead of clearing the whole map every frame.
    fn clear_outside_window(&mut self) {
        let cols = self.cols;
        let valid = self.first_col <= self.last_col && self.first_row <= self.last_row;
        for (r, (responses, laplacian)) in self
            .responses
            .chunks_mut(cols.max(1))
            .zip(self.laplacian_positive.chunks_mut(cols.max(1)))
            .enumerate()
        {
            if valid && (self.first_row..=self.last_row).contains(&r) {
                responses[..self.first_col].fill(0.0);
                responses[self.last_col + 1..].fill(0.0);
                laplacian[..self.first_col].fill(false);
                laplacian[self.last_col + 1..].fill(false);
            } else {
                responses.fill(0.0);
                laplacian.fill(false);
            }
        }
    }

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
    pub(crate) fn compute(
        &mut self,
        working: &IntegralImage,
        normalise: Option<&IntegralImage>,
        config: &DetectorConfig,
    ) {
        self.compute_with(working, normalise, config, simd::has_avx2(), true);
    }

    /// [`compute`](Self::compute) with the AVX2 row loop and the reuse of finer layers chosen by
    /// the caller (tests check that every choice gives the same maps).
    fn compute_with(
        &mut self,
        working: &IntegralImage,
        normalise: Option<&IntegralImage>,
        config: &DetectorConfig,
        avx2: bool,
        reuse: bool,
    ) {
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
            layer.last_col = if w > 2 * half {
                (w - 1 - half) / step
            } else {
                0
            };
            layer.last_row = if h > 2 * half {
                (h - 1 - half) / step
            } else {
                0
            };
            if w <= 2 * half || h <= 2 * half {
                layer.first_col = 1;
                layer.last_col = 0;
            }
            layer.responses.resize(layer.cols * layer.rows, 0.0);
            layer
                .laplacian_positive
                .resize(layer.cols * layer.rows, false);
            layer.clear_outside_window();
        }
        let min_variance = config.ln_min_variance;
        let levels = config.levels;
        self.layers
            .par_iter_mut()
            .enumerate()
            .filter(|(i, _)| !reuse || source_of(i / levels, i % levels, levels).is_none())
            .for_each(|(_, layer)| fill(layer, working, normalise, min_variance, avx2));
        for i in (0..count).filter(|_| reuse) {
            if let Some(source) = source_of(i / levels, i % levels, levels) {
                let (fine, coarse) = self.layers.split_at_mut(i);
                subsample(&mut coarse[0], &fine[source]);
            }
        }
    }
}

impl ScaleSpace {
    /// The image's contrast scale: the `quantile` of the positive responses of the finest
    /// tested layer (octave 0, level 1) over its valid window, every second sample. A change of
    /// contrast `c` (a haze, a weaker light the LSAC division leaves partly in) scales every
    /// response by `c^2`, and this figure with it, so a threshold relative to it keeps the same
    /// keypoints. 0 when the layer has no positive response.
    pub(crate) fn contrast(&self, quantile: f32) -> f32 {
        let Some(layer) = self.layers.get(1) else {
            return 0.0;
        };
        if layer.first_col > layer.last_col || layer.first_row > layer.last_row {
            return 0.0;
        }
        let mut positive: Vec<f32> = (layer.first_row..=layer.last_row)
            .step_by(2)
            .flat_map(|r| {
                layer.responses[r * layer.cols + layer.first_col..=r * layer.cols + layer.last_col]
                    .iter()
                    .step_by(2)
                    .copied()
            })
            .filter(|&v| v > 0.0)
            .collect();
        if positive.is_empty() {
            return 0.0;
        }
        let at = ((positive.len() - 1) as f32 * quantile.clamp(0.0, 1.0)).round() as usize;
        *positive.select_nth_unstable_by(at, f32::total_cmp).1
    }
}

/// The layer of an earlier octave this layer subsamples, if any: octave `o`, level `l` uses
/// the filter of octave `o - 1`, level `2 l + 1` at twice its step (Bay et al. reuse these).
fn source_of(octave: usize, level: usize, levels: usize) -> Option<usize> {
    (octave > 0 && 2 * level + 1 < levels).then(|| (octave - 1) * levels + 2 * level + 1)
}

/// Copies every second sample of `fine` (same filter, half the step) into `coarse`: the very
/// numbers a direct computation would give, since the filter sums are exact integers.
fn subsample(coarse: &mut Layer, fine: &Layer) {
    for r in coarse.first_row..=coarse.last_row.min(coarse.rows.saturating_sub(1)) {
        if coarse.first_col > coarse.last_col {
            break;
        }
        let (out, lap) = (
            &mut coarse.responses[r * coarse.cols..(r + 1) * coarse.cols],
            &mut coarse.laplacian_positive[r * coarse.cols..(r + 1) * coarse.cols],
        );
        let (src, src_lap) = (
            &fine.responses[2 * r * fine.cols..(2 * r + 1) * fine.cols],
            &fine.laplacian_positive[2 * r * fine.cols..(2 * r + 1) * fine.cols],
        );
        for c in coarse.first_col..=coarse.last_col {
            out[c] = src[2 * c];
            lap[c] = src_lap[2 * c];
        }
    }
}

/// One row of integral-table corners: `table[row * stride + x + dx]` for the centre columns `x`,
/// sliced to exactly the span the row's centres reach (so the loop needs no bounds checks).
#[derive(Clone, Copy)]
struct Corners<'a> {
    row: &'a [u32],
    base: usize,
}

impl<'a> Corners<'a> {
    /// Row `row` of the table, shifted by `dx` columns from the first centre, `span` entries.
    fn new(table: &'a [u32], stride: usize, row: usize, dx: isize, span: usize) -> Self {
        let base = (row * stride).wrapping_add_signed(dx);
        Corners {
            row: &table[base..base + span],
            base,
        }
    }
}

/// Box sum from its four corner rows/columns, wrapping (exact, see `integral`).
#[inline(always)]
fn box4(bottom_right: u32, top_right: u32, bottom_left: u32, top_left: u32) -> i32 {
    bottom_right
        .wrapping_sub(top_right)
        .wrapping_sub(bottom_left)
        .wrapping_add(top_left) as i32
}

fn fill(
    layer: &mut Layer,
    ii: &IntegralImage,
    normalise: Option<&IntegralImage>,
    min_variance: f32,
    avx2: bool,
) {
    if layer.first_col > layer.last_col || layer.first_row > layer.last_row {
        return;
    }
    match layer.step {
        1 => fill_rows::<1>(layer, ii, normalise, min_variance, avx2),
        2 => fill_rows::<2>(layer, ii, normalise, min_variance, avx2),
        4 => fill_rows::<4>(layer, ii, normalise, min_variance, avx2),
        8 => fill_rows::<8>(layer, ii, normalise, min_variance, avx2),
        16 => fill_rows::<16>(layer, ii, normalise, min_variance, avx2),
        _ => fill_rows::<32>(layer, ii, normalise, min_variance, avx2),
    }
}

/// Row-wise box-filter Hessian with the step a constant, so the step-1 loop (most of the work)
/// vectorises: every corner is a fixed column offset in one of ten table rows.
fn fill_rows<const STEP: usize>(
    layer: &mut Layer,
    ii: &IntegralImage,
    normalise: Option<&IntegralImage>,
    min_variance: f32,
    avx2: bool,
) {
    let stride = ii.stride();
    let table = ii.table();
    let size = layer.size as isize;
    let lobe = size / 3;
    let half = (size - 1) / 2;
    let lobe_half = (lobe - 1) / 2;
    let area = (size * size) as f32;
    let scale = 1.0 / (area * FIXED);
    let n = area as f64;
    let (first_col, last_col, first_row, last_row, cols) = (
        layer.first_col,
        layer.last_col,
        layer.first_row,
        layer.last_row,
        layer.cols,
    );
    let count = last_col - first_col + 1;
    layer
        .responses
        .par_chunks_mut(cols)
        .zip(layer.laplacian_positive.par_chunks_mut(cols))
        .enumerate()
        .filter(|(r, _)| (first_row..=last_row).contains(r))
        .for_each(|(r, (responses, laplacian))| {
            let y = (r * STEP) as isize;
            // Table row of image row `y + dy` as the bottom edge of a box ending there.
            let row = |dy: isize| (y + dy) as usize;
            let span = (count - 1) * STEP + 1;
            let at = |dy: isize, dx: isize| {
                Corners::new(
                    table,
                    stride,
                    row(dy),
                    dx + (first_col * STEP) as isize,
                    span,
                )
            };
            // Dxx: +1 over the full (2 lobe - 1) x size band, -3 over its centre lobe => 1, -2, 1.
            let (xt, xb) = (-(lobe - 1), lobe);
            let (xa_l, xa_r, xm_l, xm_r) = (
                at(xt, -half),
                at(xt, half + 1),
                at(xt, -lobe_half),
                at(xt, lobe_half + 1),
            );
            let (xb_l, xb_r, xn_l, xn_r) = (
                at(xb, -half),
                at(xb, half + 1),
                at(xb, -lobe_half),
                at(xb, lobe_half + 1),
            );
            // Dyy: the same turned by 90 degrees.
            let (yl, yr) = (-(lobe - 1), lobe);
            let (ya_l, ya_r, ym_l, ym_r) = (
                at(-half, yl),
                at(-half, yr),
                at(-lobe_half, yl),
                at(-lobe_half, yr),
            );
            let (yb_l, yb_r, yn_l, yn_r) = (
                at(half + 1, yl),
                at(half + 1, yr),
                at(lobe_half + 1, yl),
                at(lobe_half + 1, yr),
            );
            // Dxy: + top-left, + bottom-right, - top-right, - bottom-left lobes, one pixel off the axes.
            let corners = |dy: isize| [at(dy, -lobe), at(dy, 0), at(dy, 1), at(dy, lobe + 1)];
            let (t0, t1, t2, t3) = (corners(-lobe), corners(0), corners(1), corners(lobe + 1));
            let out = &mut responses[first_col..first_col + count];
            let lap = &mut laplacian[first_col..first_col + count];
            let filter = RowFilter {
                dxx: [xb_r, xa_r, xb_l, xa_l, xn_r, xm_r, xn_l, xm_l],
                dyy: [yb_r, ya_r, yb_l, ya_l, yn_r, ym_r, yn_l, ym_l],
                dxy: [t0, t1, t2, t3],
                scale,
            };
            filter.run::<STEP>(avx2, out, lap);
            if let Some(sq) = normalise {
                normalise_row::<STEP>(out, sq, at(-half, 0).base, size as usize, n, min_variance);
            }
        });
}

/// The corners of one row of filter centres: Dxx and Dyy as (band, mid) box corners in
/// `box4` order, Dxy as four table rows of four columns each.
struct RowFilter<'a> {
    dxx: [Corners<'a>; 8],
    dyy: [Corners<'a>; 8],
    dxy: [[Corners<'a>; 4]; 4],
    /// `1 / (filter area x FIXED)`: responses in 8-bit units per unit area.
    scale: f32,
}

impl<'a> RowFilter<'a> {
    /// Fills `out` (determinants) and `lap` (Laplacian signs) for the row, with AVX2 when
    /// `avx2` says the CPU has it (same numbers: integer sums and the same float operations).
    fn run<const STEP: usize>(&self, avx2: bool, out: &mut [f32], lap: &mut [bool]) {
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: `avx2` is true only when `simd::has_avx2` found AVX2 on this CPU.
            return unsafe { self.run_avx2::<STEP>(out, lap) };
        }
        let _ = avx2;
        self.run_portable::<STEP>(out, lap);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2<const STEP: usize>(&self, out: &mut [f32], lap: &mut [bool]) {
        self.run_portable::<STEP>(out, lap);
    }

    #[inline(always)]
    fn run_portable<const STEP: usize>(&self, out: &mut [f32], lap: &mut [bool]) {
        let n = out.len().min(lap.len());
        // Every corner row cut to exactly the span the `n` centres reach: with the lengths known
        // the compiler drops the bounds checks and, for STEP 1, vectorises the loop.
        let span = n.saturating_sub(1) * STEP + 1;
        let cut = |c: &Corners<'a>| -> &'a [u32] { &c.row[..span] };
        let [xb_r, xa_r, xb_l, xa_l, xn_r, xm_r, xn_l, xm_l] = self.dxx.each_ref().map(cut);
        let [yb_r, ya_r, yb_l, ya_l, yn_r, ym_r, yn_l, ym_l] = self.dyy.each_ref().map(cut);
        let [t0, t1, t2, t3] = self.dxy.each_ref().map(|row| row.each_ref().map(cut));
        let scale = self.scale;
        let (out, lap) = (&mut out[..n], &mut lap[..n]);
        for i in 0..n {
            let x = i * STEP;
            let band = box4(xb_r[x], xa_r[x], xb_l[x], xa_l[x]);
            let mid = box4(xn_r[x], xm_r[x], xn_l[x], xm_l[x]);
            let dxx = band.wrapping_sub(mid.wrapping_mul(3)) as f32 * scale;
            let band = box4(yb_r[x], ya_r[x], yb_l[x], ya_l[x]);
            let mid = box4(yn_r[x], ym_r[x], yn_l[x], ym_l[x]);
            let dyy = band.wrapping_sub(mid.wrapping_mul(3)) as f32 * scale;
            let tl = box4(t1[1][x], t0[1][x], t1[0][x], t0[0][x]);
            let br = box4(t3[3][x], t2[3][x], t3[2][x], t2[2][x]);
            let tr = box4(t1[3][x], t0[3][x], t1[2][x], t0[2][x]);
            let bl = box4(t3[1][x], t2[1][x], t3[0][x], t2[0][x]);
            let dxy = tl.wrapping_add(br).wrapping_sub(tr).wrapping_sub(bl) as f32 * scale;
            out[i] = dxx * dyy - (DXY_WEIGHT * dxy) * (DXY_WEIGHT * dxy);
            lap[i] = dxx + dyy >= 0.0;
        }
    }
}

/// LN-SURF: divides one row of determinants by the variance of the working image under each
/// filter (`size` x `size` box whose top-left table corner for the first centre is `corner`).
fn normalise_row<const STEP: usize>(
    out: &mut [f32],
    sq: &IntegralImage,
    corner: usize,
    size: usize,
    n: f64,
    min_variance: f32,
) {
    let stride = sq.stride();
    let top_left = corner.wrapping_sub((size - 1) / 2);
    let (sums, squares) = (sq.table(), sq.squares_table());
    for (i, det) in out.iter_mut().enumerate() {
        let tl = top_left + i * STEP;
        let (tr, bl, br) = (tl + size, tl + size * stride, tl + size * stride + size);
        let fixed = box4(sums[br], sums[tr], sums[bl], sums[tl]);
        let mean = f64::from(fixed as f32 / FIXED) / n;
        let fixed_sq = squares[br]
            .wrapping_sub(squares[tr])
            .wrapping_sub(squares[bl])
            .wrapping_add(squares[tl]);
        let mean_sq = fixed_sq as f64 / f64::from(FIXED * FIXED) / n;
        let variance = ((mean_sq - mean * mean) as f32).max(min_variance);
        *det /= variance;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_sizes_follow_the_thesis() {
        let sizes: Vec<Vec<usize>> = (0..3)
            .map(|o| (0..4).map(|l| filter_size(o, l)).collect())
            .collect();
        assert_eq!(
            sizes,
            vec![
                vec![9, 15, 21, 27],
                vec![15, 27, 39, 51],
                vec![27, 51, 75, 99]
            ]
        );
    }

    /// A textured working image with odd dimensions (partial last map cells).
    fn textured(width: usize, height: usize) -> crate::GrayImage32 {
        let mut img = crate::GrayImage32::new(width, height);
        for (i, v) in img.as_mut_slice().iter_mut().enumerate() {
            let (x, y) = ((i % width) as f32, (i / width) as f32);
            *v = 128.0 + 90.0 * (x * 0.31).sin() * (y * 0.17).cos() + ((i * 7919) % 23) as f32;
        }
        img
    }

    #[test]
    fn vector_loop_and_layer_reuse_give_the_direct_maps() {
        let img = textured(203, 157);
        for ln in [false, true] {
            let ii = IntegralImage::from_image(&img, ln);
            let mut config = DetectorConfig::for_kind(crate::DetectorKind::Surf);
            config.levels = 5;
            let normalise = ln.then_some(&ii);
            let mut direct = ScaleSpace::default();
            direct.compute_with(&ii, normalise, &config, false, false);
            let mut fast = ScaleSpace::default();
            fast.compute_with(&ii, normalise, &config, simd::has_avx2(), true);
            for (i, (a, b)) in direct.layers.iter().zip(&fast.layers).enumerate() {
                let same = a
                    .responses
                    .iter()
                    .zip(&b.responses)
                    .all(|(x, y)| x.to_bits() == y.to_bits());
                assert!(
                    same && a.laplacian_positive == b.laplacian_positive,
                    "layer {i} (ln {ln}) differs"
                );
            }
            assert!(
                direct.layers[5].responses.iter().any(|&v| v != 0.0),
                "octave 1 has responses"
            );
        }
    }
}
