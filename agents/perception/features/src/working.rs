//! The working images: intensity for SURF and LN-SURF, the local space average colour image for
//! LSAC-SURF (thesis Algorithm 2), and the hard/soft classification near saturation.

use rayon::prelude::*;

use crate::image32::LUMA_WEIGHTS;
use crate::integral::FIXED;
use crate::simd;
use crate::{
    DetectorConfig, DetectorKind, FeatureClass, GrayImage32, IntegralImage, Keypoint, LsacSpace,
};

/// The three colour channels of an image as `f32` planes (8-bit units, not rounded).
#[derive(Debug, Default)]
pub(crate) struct Planes {
    channels: [GrayImage32; 3],
    /// Scratch of the separable passes.
    tmp: GrayImage32,
}

impl Planes {
    /// Width, px.
    pub(crate) fn width(&self) -> usize {
        self.channels[0].width()
    }

    /// Height, px.
    pub(crate) fn height(&self) -> usize {
        self.channels[0].height()
    }

    /// The channels of `image` in float, each de-quantised by `iterations` rounds of
    /// [`dequantise`] (0: the 8-bit values as they are).
    pub(crate) fn load(&mut self, image: &image::RgbImage, iterations: usize) {
        for (c, plane) in self.channels.iter_mut().enumerate() {
            plane.channel_into(image, c);
            dequantise(plane, &mut self.tmp, image, c, iterations);
        }
    }

    /// The loaded planes at twice their width and height (bilinear, pixel centres at
    /// `(X + 0.5) / 2 - 0.5` of the input), then blurred by a Gaussian of `sigma` doubled px (see
    /// [`DetectorConfig::upsample`], [`DetectorConfig::doubled_sigma`]: without the blur the
    /// finest filters respond to the interpolation's own pattern, which a sub-pixel shift of the
    /// scene changes). Kept in float: rounding back to 8 bits would add a quantisation noise of
    /// its own, largest relative to the signal where the light is dim.
    pub(crate) fn double(&mut self, sigma: f32) {
        let (w, h) = (self.width(), self.height());
        if w == 0 || h == 0 {
            return;
        }
        let kernel = gaussian_kernel(sigma);
        for plane in &mut self.channels {
            // Rows doubled horizontally into `tmp` (2w x h), then columns back into `plane`.
            self.tmp.resize(2 * w, h);
            let input = &*plane;
            self.tmp
                .as_mut_slice()
                .par_chunks_mut(2 * w)
                .enumerate()
                .for_each(|(y, out)| {
                    let row = row_of(input, y);
                    double_line(out, |x| row[x], w);
                });
            plane.resize(2 * w, 2 * h);
            let tmp = &self.tmp;
            plane
                .as_mut_slice()
                .par_chunks_mut(2 * w)
                .enumerate()
                .for_each(|(y, out)| {
                    let i = y / 2;
                    let other = if y % 2 == 0 {
                        i.saturating_sub(1)
                    } else {
                        (i + 1).min(h - 1)
                    };
                    let (a, b) = (row_of(tmp, i), row_of(tmp, other));
                    for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
                        *o = 0.75 * a + 0.25 * b;
                    }
                });
            blur(plane, &mut self.tmp, &kernel);
        }
    }

    /// Channel `c` (0 red, 1 green, 2 blue).
    fn channel(&self, c: usize) -> &GrayImage32 {
        &self.channels[c]
    }
}

/// Row `y` of `image`.
fn row_of(image: &GrayImage32, y: usize) -> &[f32] {
    let w = image.width();
    &image.as_slice()[y * w..(y + 1) * w]
}

/// One line of `n` samples (`at(i)`) doubled into `out` (2n): sample `2i` lies a quarter pixel
/// before input sample `i`, `2i + 1` a quarter after; the border repeats.
fn double_line(out: &mut [f32], at: impl Fn(usize) -> f32, n: usize) {
    for i in 0..n {
        let (here, before, after) = (at(i), at(i.saturating_sub(1)), at((i + 1).min(n - 1)));
        out[2 * i] = 0.75 * here + 0.25 * before;
        out[2 * i + 1] = 0.75 * here + 0.25 * after;
    }
}

/// De-quantisation, "projection onto the quantisation cell" (see
/// [`DetectorConfig::dequantise_iterations`]): `plane` holds channel `c` of `image`; each round
/// blurs it by the binomial `[1, 2, 1] / 4` both ways (border repeated) and clamps every sample
/// back into `[v - 0.5, v + 0.5]` around its 8-bit value `v`. The rounds tend to the smoothest
/// image the 8 bits allow: rounding plateaus become ramps, and no sample moves more than half a
/// grey level. `tmp` is scratch.
fn dequantise(
    plane: &mut GrayImage32,
    tmp: &mut GrayImage32,
    image: &image::RgbImage,
    c: usize,
    iterations: usize,
) {
    let (w, h) = (plane.width(), plane.height());
    if iterations == 0 || w == 0 || h == 0 {
        return;
    }
    let raw = image.as_raw();
    for _ in 0..iterations {
        blur(plane, tmp, &BINOMIAL);
        plane
            .as_mut_slice()
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, out)| {
                let observed = &raw[3 * y * w..3 * (y + 1) * w];
                for (o, v) in out.iter_mut().zip(observed.iter().skip(c).step_by(3)) {
                    let v = f32::from(*v);
                    *o = o.clamp(v - 0.5, v + 0.5);
                }
            });
    }
}

/// The de-quantisation's light blur, per axis.
const BINOMIAL: [f32; 3] = [0.25, 0.5, 0.25];

/// Normalised Gaussian taps `-r..=r`, `r = ceil(3 sigma)`.
fn gaussian_kernel(sigma: f32) -> Vec<f32> {
    let r = (3.0 * sigma).ceil() as i32;
    let taps: Vec<f32> = (-r..=r)
        .map(|i| (-0.5 * (i as f32 / sigma).powi(2)).exp())
        .collect();
    let total: f32 = taps.iter().sum();
    taps.into_iter().map(|t| t / total).collect()
}

/// Separable convolution of `image` with `kernel` in place (border repeated); `tmp` is scratch.
fn blur(image: &mut GrayImage32, tmp: &mut GrayImage32, kernel: &[f32]) {
    let (w, h) = (image.width(), image.height());
    if w == 0 || h == 0 {
        return;
    }
    let r = kernel.len() / 2;
    tmp.resize(w, h);
    let src = &*image;
    tmp.as_mut_slice()
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, out)| {
            let row = row_of(src, y);
            for (x, o) in out.iter_mut().enumerate() {
                *o = kernel
                    .iter()
                    .enumerate()
                    .map(|(k, &t)| t * row[(x + k).saturating_sub(r).min(w - 1)])
                    .sum();
            }
        });
    let tmp = &*tmp;
    image
        .as_mut_slice()
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, out)| {
            out.fill(0.0);
            for (k, &t) in kernel.iter().enumerate() {
                let row = row_of(tmp, (y + k).saturating_sub(r).min(h - 1));
                for (o, &v) in out.iter_mut().zip(row) {
                    *o += t * v;
                }
            }
        });
}

/// What a detection runs on: the input's 8-bit pixels, or float planes (the doubled image).
#[derive(Clone, Copy)]
pub(crate) enum Source<'a> {
    /// The input image.
    Rgb(&'a image::RgbImage),
    /// Float channels.
    Planes(&'a Planes),
}

impl Source<'_> {
    fn size(self) -> (usize, usize) {
        match self {
            Source::Rgb(image) => (image.width() as usize, image.height() as usize),
            Source::Planes(planes) => (planes.width(), planes.height()),
        }
    }

    /// Channel `c` of row `y` into `out` (as many samples as the width).
    fn channel_row(self, c: usize, y: usize, out: &mut [f32]) {
        match self {
            Source::Rgb(image) => {
                let w = image.width() as usize;
                let raw = &image.as_raw()[3 * y * w..3 * (y + 1) * w];
                for (o, &v) in out.iter_mut().zip(raw.iter().skip(c).step_by(3)) {
                    *o = f32::from(v);
                }
            }
            Source::Planes(planes) => out.copy_from_slice(row_of(planes.channel(c), y)),
        }
    }
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
    /// Fills the buffers `kind` needs from `source`.
    pub(crate) fn prepare(
        &mut self,
        kind: DetectorKind,
        source: Source<'_>,
        config: &DetectorConfig,
    ) {
        match source {
            Source::Rgb(image) => self.gray.luma_into(image),
            Source::Planes(planes) => self.gray.luma_of(planes.channels.each_ref()),
        }
        if !kind.is_lsac() {
            self.gray_integral
                .compute(&self.gray, kind == DetectorKind::LnSurf);
            return;
        }
        let (w, h) = source.size();
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
                self.channel_integrals.par_iter_mut().enumerate().for_each(
                    |(c, ii)| match source {
                        Source::Rgb(image) => ii.compute_channel(image, c),
                        Source::Planes(planes) => ii.compute(planes.channel(c), false),
                    },
                );
                let iis = &self.channel_integrals;
                self.lsac
                    .as_mut_slice()
                    .par_chunks_mut(w)
                    .enumerate()
                    .for_each_init(
                        || (vec![0.0; w], vec![0.0; w]),
                        |(average, pixels), (y, row)| {
                            // Luma of the three ratios, summed channel by channel in luma_f32's order.
                            for (c, (ii, weight)) in iis.iter().zip(LUMA_WEIGHTS).enumerate() {
                                local_average_row(ii, y, &radii, average);
                                source.channel_row(c, y, pixels);
                                for ((out, &i), &a) in
                                    row.iter_mut().zip(pixels.iter()).zip(average.iter())
                                {
                                    let term = weight * lsac_sample(i, a, floor);
                                    *out = if c == 0 { term } else { *out + term };
                                }
                            }
                        },
                    );
            }
        }
        self.lsac_integral.compute(&self.lsac, false);
    }

    /// The local averages at working-image point `(x, y)` that the LSAC division used there:
    /// red, green and blue (per-channel space), or the gray one three times (gray space);
    /// needs `prepare` with an LSAC kind.
    pub(crate) fn local_averages_at(&self, x: f32, y: f32, config: &DetectorConfig) -> [f32; 3] {
        let (w, h) = (self.lsac.width(), self.lsac.height());
        let (x, y) = (
            (x.round().max(0.0) as usize).min(w.saturating_sub(1)),
            (y.round().max(0.0) as usize).min(h.saturating_sub(1)),
        );
        let radii = nested_radii(config.lsac_radius_px);
        match config.lsac_space {
            LsacSpace::Gray => [local_average(&self.gray_integral, x, y, &radii); 3],
            LsacSpace::PerChannel => self
                .channel_integrals
                .each_ref()
                .map(|ii| local_average(ii, x, y, &radii)),
        }
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
    fn doubling_commutes_with_a_gain_because_it_does_not_round() {
        // Even values halve exactly in 8 bits: the doubled planes of the dim image must be half
        // the bright image's. Rounding the doubled image back to 8 bits broke this (LIC, LCC).
        let (w, h) = (23, 17);
        let bright = image::RgbImage::from_fn(w, h, |x, y| {
            let v = |k: u32| (((x * 7 + y * 13 + k * 5) * 37) % 128 * 2) as u8;
            image::Rgb([v(0), v(1), v(2)])
        });
        let dim = image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb(bright.get_pixel(x, y).0.map(|v| v / 2))
        });
        let (mut a, mut b) = (Planes::default(), Planes::default());
        a.load(&bright, 0);
        a.double(1.6);
        b.load(&dim, 0);
        b.double(1.6);
        assert_eq!((a.width(), a.height()), (2 * w as usize, 2 * h as usize));
        for c in 0..3 {
            for (&p, &q) in a.channel(c).as_slice().iter().zip(b.channel(c).as_slice()) {
                assert!((p - 2.0 * q).abs() < 1e-3, "channel {c}: {p} vs 2 x {q}");
            }
        }
        // A flat image stays flat, borders included.
        let flat = image::RgbImage::from_pixel(5, 4, image::Rgb([9, 99, 199]));
        a.load(&flat, 0);
        a.double(1.6);
        for (c, v) in [9.0, 99.0, 199.0].into_iter().enumerate() {
            assert!(
                a.channel(c)
                    .as_slice()
                    .iter()
                    .all(|&p| (p - v).abs() < 1e-3)
            );
        }
    }

    #[test]
    fn dequantising_a_rounded_slope_recovers_it_inside_the_quantisation_cells() {
        // A dim, smooth light: a slope of 0.3 grey level per column and 0.2 per row, different
        // per channel, rounded to 8 bits: plateaus 3-5 px wide.
        let (w, h) = (64usize, 48usize);
        let truth = |x: usize, y: usize, c: usize| {
            20.0 + 0.3 * x as f32 + 0.2 * y as f32 + 7.0 * c as f32 + 0.1 * (x * c) as f32
        };
        let image = image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
            image::Rgb(std::array::from_fn(|c| {
                truth(x as usize, y as usize, c).round() as u8
            }))
        });
        let rms = |planes: &Planes, c: usize| {
            let mut sum = 0.0;
            let mut n = 0;
            for y in 8..h - 8 {
                for x in 8..w - 8 {
                    let p = planes.channel(c).get(x, y).unwrap();
                    sum += (p - truth(x, y, c)).powi(2);
                    n += 1;
                }
            }
            (sum / n as f32).sqrt()
        };
        let (mut rounded, mut smooth) = (Planes::default(), Planes::default());
        rounded.load(&image, 0);
        smooth.load(&image, 64);
        for c in 0..3 {
            // No sample leaves its cell.
            for (x, y) in (0..h).flat_map(|y| (0..w).map(move |x| (x, y))) {
                let v = f32::from(image.get_pixel(x as u32, y as u32).0[c]);
                assert_eq!(rounded.channel(c).get(x, y), Some(v));
                let p = smooth.channel(c).get(x, y).unwrap();
                assert!((p - v).abs() <= 0.5, "channel {c} ({x}, {y}): {p} from {v}");
            }
            // The rounding's error (about 1 / sqrt(12) = 0.29) mostly gone.
            let (before, after) = (rms(&rounded, c), rms(&smooth, c));
            assert!(before > 0.25, "channel {c}: rounding error {before}");
            assert!(
                after < 0.1,
                "channel {c}: rms error {after} (rounded {before})"
            );
        }
    }

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
