//! The working images: intensity for SURF and LN-SURF, the local space average colour image for
//! LSAC-SURF (thesis Algorithm 2), and the hard/soft classification near saturation.

use rayon::prelude::*;

use crate::image32::LUMA_WEIGHTS;
use crate::integral::FIXED;
use crate::simd;
use crate::{
    DetectorConfig, DetectorKind, FeatureClass, GrayImage32, IntegralImage, Keypoint, LsacSpace,
};

/// Gaussian blur of the doubled image, its px: SIFT's base scale (Lowe 2004, sigma 1.6). Without
/// it the finest filters respond to the interpolation's own pattern, which a sub-pixel shift of
/// the scene changes (measured: see `docs/results/repeatability.md`).
const DOUBLED_SIGMA: f32 = 1.6;

/// `image` at twice its width and height, bilinear with pixel centres at `(X + 0.5) / 2 - 0.5`
/// of the input, then blurred by [`DOUBLED_SIGMA`] (see [`DetectorConfig::upsample`]).
pub(crate) fn doubled(image: &image::RgbImage) -> image::RgbImage {
    let doubled = image::imageops::resize(
        image,
        image.width().saturating_mul(2),
        image.height().saturating_mul(2),
        image::imageops::FilterType::Triangle,
    );
    image::imageops::blur(&doubled, DOUBLED_SIGMA)
}

/// Buffers reused frame after frame.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    pub(crate) gray: GrayImage32,
    pub(crate) gray_integral: IntegralImage,
    channel_integrals: [IntegralImage; 3],
    lsac: GrayImage32,
    pub(crate) lsac_integral: IntegralImage,
}

impl Scratch {
    /// Fills the buffers `kind` needs from `image`.
    pub(crate) fn prepare(
        &mut self,
        kind: DetectorKind,
        image: &image::RgbImage,
        config: &DetectorConfig,
    ) {
        self.gray.luma_into(image);
        if !kind.is_lsac() {
            self.gray_integral
                .compute(&self.gray, kind == DetectorKind::LnSurf);
            return;
        }
        let (w, h) = (self.gray.width(), self.gray.height());
        self.lsac.resize(w, h);
        let radii = nested_radii(config.lsac_radius_px);
        let floor = config.lsac_min_average;
        match config.lsac_space {
            LsacSpace::Gray => {
                self.gray_integral.compute(&self.gray, false);
                let (gray, ii) = (&self.gray, &self.gray_integral);
                self.lsac
                    .as_mut_slice()
                    .par_chunks_mut(w)
                    .enumerate()
                    .for_each_init(
                        || vec![0.0; w],
                        |average, (y, row)| {
                            local_average_row(ii, y, &radii, average);
                            let intensity = &gray.as_slice()[y * w..(y + 1) * w];
                            for ((out, &i), &a) in row.iter_mut().zip(intensity).zip(average.iter())
                            {
                                *out = lsac_sample(i, a, floor);
                            }
                        },
                    );
            }
            LsacSpace::PerChannel => {
                self.channel_integrals
                    .par_iter_mut()
                    .enumerate()
                    .for_each(|(c, ii)| ii.compute_channel(image, c));
                let iis = &self.channel_integrals;
                let raw = image.as_raw();
                self.lsac
                    .as_mut_slice()
                    .par_chunks_mut(w)
                    .enumerate()
                    .for_each_init(
                        || vec![0.0; w],
                        |average, (y, row)| {
                            // Luma of the three ratios, summed channel by channel in luma_f32's order.
                            for (c, (ii, weight)) in iis.iter().zip(LUMA_WEIGHTS).enumerate() {
                                local_average_row(ii, y, &radii, average);
                                let pixels =
                                    raw[3 * y * w..3 * (y + 1) * w].iter().skip(c).step_by(3);
                                for ((out, &i), &a) in
                                    row.iter_mut().zip(pixels).zip(average.iter())
                                {
                                    let term = weight * lsac_sample(f32::from(i), a, floor);
                                    *out = if c == 0 { term } else { *out + term };
                                }
                            }
                        },
                    );
            }
        }
        self.lsac_integral.compute(&self.lsac, false);
    }

    /// The integral image the Hessian runs on for `kind`.
    pub(crate) fn working(&self, kind: DetectorKind) -> &IntegralImage {
        match kind {
            DetectorKind::LsacSurf | DetectorKind::LsacSurfNt => &self.lsac_integral,
            DetectorKind::Surf | DetectorKind::LnSurf => &self.gray_integral,
        }
    }
}

/// Radii of the three nested boxes whose mean approximates the Gaussian local average.
fn nested_radii(radius: usize) -> [usize; 3] {
    [(radius / 3).max(1), (2 * radius / 3).max(1), radius.max(1)]
}

/// Mean of three nested clipped box means centred on `(x, y)`: a centre-weighted kernel, the
/// box-filter approximation of the Gaussian local space average (thesis Algorithm 2, line 8).
fn local_average(ii: &IntegralImage, x: usize, y: usize, radii: &[usize; 3]) -> f32 {
    let (w, h) = (ii.width(), ii.height());
    let mut total = 0.0;
    for &r in radii {
        let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        total += ii.box_sum(x0, y0, x1, y1) / ((x1 - x0) * (y1 - y0)) as f32;
    }
    total / radii.len() as f32
}

/// [`local_average`] for every pixel of row `y`: where no box is clipped (the bulk of the
/// image) the same numbers from straight row slices of the table, a loop that vectorises.
fn local_average_row(ii: &IntegralImage, y: usize, radii: &[usize; 3], out: &mut [f32]) {
    let (w, h) = (ii.width(), ii.height());
    let outer = radii[2];
    let inner_cols = outer..w.saturating_sub(outer + 1).max(outer);
    if y < outer || y + outer + 1 > h || inner_cols.is_empty() {
        for (x, o) in out.iter_mut().enumerate() {
            *o = local_average(ii, x, y, radii);
        }
        return;
    }
    for x in (0..outer).chain(inner_cols.end..w) {
        out[x] = local_average(ii, x, y, radii);
    }
    let (s, t) = (ii.stride(), ii.table());
    let n = inner_cols.len();
    // Per radius: table rows y - r and y + r + 1 at columns x - r and x + r + 1.
    let corners = radii.map(|r| {
        let slice = |row: usize, col: usize| &t[row * s + col..row * s + col + n];
        let (top, bottom) = (y - r, y + r + 1);
        let (left, right) = (inner_cols.start - r, inner_cols.start + r + 1);
        (
            [
                slice(bottom, right),
                slice(top, right),
                slice(bottom, left),
                slice(top, left),
            ],
            ((2 * r + 1) * (2 * r + 1)) as f32,
        )
    });
    average_interior(simd::has_avx2(), &corners, &mut out[inner_cols]);
}

/// Table corners (bottom-right, top-right, bottom-left, top-left rows) and area of one box
/// radius, for a run of unclipped pixels.
type BoxRun<'a> = ([&'a [u32]; 4], f32);

/// The mean of the three box means for a run of unclipped pixels, with AVX2 when `avx2` says
/// the CPU has it (same float operations in the same order either way).
fn average_interior(avx2: bool, corners: &[BoxRun<'_>; 3], out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is true only when `simd::has_avx2` found AVX2 on this CPU.
        return unsafe { average_interior_avx2(corners, out) };
    }
    let _ = avx2;
    average_interior_portable(corners, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn average_interior_avx2(corners: &[BoxRun<'_>; 3], out: &mut [f32]) {
    average_interior_portable(corners, out);
}

#[inline(always)]
fn average_interior_portable<'a>(corners: &[BoxRun<'a>; 3], out: &mut [f32]) {
    let n = out.len();
    let cut = |(rows, area): &BoxRun<'a>| -> BoxRun<'a> { (rows.map(|r| &r[..n]), *area) };
    let [
        ([br0, tr0, bl0, tl0], area0),
        ([br1, tr1, bl1, tl1], area1),
        ([br2, tr2, bl2, tl2], area2),
    ] = corners.each_ref().map(cut);
    let mean = |br: u32, tr: u32, bl: u32, tl: u32, area: f32| {
        br.wrapping_sub(tr).wrapping_sub(bl).wrapping_add(tl) as i32 as f32 / FIXED / area
    };
    for i in 0..n {
        let mut total = 0.0;
        total += mean(br0[i], tr0[i], bl0[i], tl0[i], area0);
        total += mean(br1[i], tr1[i], bl1[i], tl1[i], area1);
        total += mean(br2[i], tr2[i], bl2[i], tl2[i], area2);
        out[i] = total / 3.0;
    }
}

/// Ebner's descriptor `I / (2 a)` (thesis eq. 4.17) scaled back to 8-bit units (x 255), so an
/// average-lit patch keeps about its intensity and one threshold serves SURF and LSAC-SURF.
fn lsac_sample(intensity: f32, average: f32, floor: f32) -> f32 {
    255.0 * intensity / (2.0 * average.max(floor))
}

/// Hard if the gray pixel under the keypoint lies strictly inside `band`, else soft.
pub(crate) fn classify(gray: &GrayImage32, kp: &Keypoint, band: Option<(u8, u8)>) -> FeatureClass {
    let Some((lower, upper)) = band else {
        return FeatureClass::Hard;
    };
    let (x, y) = (
        kp.x.round().max(0.0) as usize,
        kp.y.round().max(0.0) as usize,
    );
    match gray.get(x, y) {
        Some(v) if v > f32::from(lower) && v < f32::from(upper) => FeatureClass::Hard,
        _ => FeatureClass::Soft,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_averages_equal_the_per_pixel_average() {
        for (w, h, radius) in [(61, 47, 12), (20, 9, 12), (33, 40, 3), (5, 5, 1)] {
            let mut img = GrayImage32::new(w, h);
            for (i, v) in img.as_mut_slice().iter_mut().enumerate() {
                *v = ((i * 7919) % 256) as f32;
            }
            let ii = IntegralImage::from_image(&img, false);
            let radii = nested_radii(radius);
            let mut row = vec![0.0; w];
            for y in 0..h {
                local_average_row(&ii, y, &radii, &mut row);
                for (x, &a) in row.iter().enumerate() {
                    assert_eq!(
                        a.to_bits(),
                        local_average(&ii, x, y, &radii).to_bits(),
                        "{w}x{h} r {radius} at ({x}, {y})"
                    );
                }
            }
        }
    }
}
