//! Integral images (thesis 2.4, Viola and Jones): any box sum in four look-ups.
//!
//! Samples are stored as fixed-point integers (`FIXED` steps per 8-bit intensity unit) and
//! accumulated with wrapping arithmetic: the corner differences of a box are exact as long as
//! the true box sum fits the type, whatever the overflow of the running sums. So a box sum is
//! the same number wherever the box lies, with no float drift toward the bottom-right corner.

use crate::GrayImage32;

/// Fixed-point steps per 8-bit intensity unit.
pub(crate) const FIXED: f32 = 16.0;
/// Largest working sample (4x the 8-bit range) so that a 195x195 box sum fits an `i32`.
pub(crate) const MAX_SAMPLE: f32 = 1023.0;

/// Integral image `(width+1) x (height+1)` with a zero first row and column; optionally the
/// integral of squares too (LN-SURF's local variance).
#[derive(Debug, Clone, Default)]
pub struct IntegralImage {
    width: usize,
    height: usize,
    sum: Vec<u32>,
    squares: Vec<u64>,
}

impl IntegralImage {
    /// Builds the integral of `image` (samples clamped to `0..=1023`), with squares if asked.
    pub fn from_image(image: &GrayImage32, with_squares: bool) -> Self {
        let mut out = IntegralImage::default();
        out.compute(image, with_squares);
        out
    }

    /// Recomputes in place, reusing the allocations.
    pub fn compute(&mut self, image: &GrayImage32, with_squares: bool) {
        let (w, h) = (image.width(), image.height());
        self.width = w;
        self.height = h;
        let stride = w + 1;
        self.sum.clear();
        self.sum.resize(stride * (h + 1), 0);
        self.squares.clear();
        if with_squares {
            self.squares.resize(stride * (h + 1), 0);
        }
        if w == 0 {
            return;
        }
        for (y, row) in image.as_slice().chunks_exact(w).take(h).enumerate() {
            let (above, here) = self.sum.split_at_mut((y + 1) * stride);
            accumulate_row(
                &above[y * stride + 1..],
                &mut here[1..stride],
                row.iter().map(|&v| to_fixed(v)),
            );
        }
        if with_squares {
            for (y, row) in image.as_slice().chunks_exact(w).take(h).enumerate() {
                let (above, here) = self.squares.split_at_mut((y + 1) * stride);
                let squares = row
                    .iter()
                    .map(|&v| u64::from(to_fixed(v)) * u64::from(to_fixed(v)));
                accumulate_row(&above[y * stride + 1..], &mut here[1..stride], squares);
            }
        }
    }

    /// Recomputes in place from channel `channel` (0 red, 1 green, 2 blue) of an RGB image: the
    /// same table as [`compute`](Self::compute) on that channel as `f32`, without the copy.
    pub fn compute_channel(&mut self, image: &image::RgbImage, channel: usize) {
        let (w, h) = (image.width() as usize, image.height() as usize);
        self.width = w;
        self.height = h;
        let stride = w + 1;
        self.sum.clear();
        self.sum.resize(stride * (h + 1), 0);
        self.squares.clear();
        if w == 0 {
            return;
        }
        for (y, row) in image.as_raw().chunks_exact(3 * w).take(h).enumerate() {
            let (above, here) = self.sum.split_at_mut((y + 1) * stride);
            let fixed = row
                .chunks_exact(3)
                .map(|px| u32::from(px[channel]) * FIXED as u32);
            accumulate_row(&above[y * stride + 1..], &mut here[1..stride], fixed);
        }
    }

    /// Width of the source image, px.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of the source image, px.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row stride of the table (`width + 1`).
    pub(crate) fn stride(&self) -> usize {
        self.width + 1
    }

    /// The raw table (fixed point, wrapping).
    pub(crate) fn table(&self) -> &[u32] {
        &self.sum
    }

    /// The raw table of squares (fixed point squared, wrapping; empty without squares).
    pub(crate) fn squares_table(&self) -> &[u64] {
        &self.squares
    }

    /// Whether the integral of squares was computed.
    pub fn has_squares(&self) -> bool {
        !self.squares.is_empty()
    }

    /// Sum over columns `x0..x1`, rows `y0..y1` (half-open, must lie inside the image), in
    /// 8-bit intensity units.
    pub fn box_sum(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> f32 {
        self.box_sum_fixed(x0, y0, x1, y1) as f32 / FIXED
    }

    /// As [`box_sum`](Self::box_sum) but clipped to the image (an empty box sums to 0); the
    /// Haar wavelets of the descriptor may reach past the border.
    pub fn box_sum_clipped(&self, x0: isize, y0: isize, x1: isize, y1: isize) -> f32 {
        let clip_x = |v: isize| v.clamp(0, self.width as isize) as usize;
        let clip_y = |v: isize| v.clamp(0, self.height as isize) as usize;
        let (x0, x1, y0, y1) = (clip_x(x0), clip_x(x1), clip_y(y0), clip_y(y1));
        if x0 >= x1 || y0 >= y1 {
            return 0.0;
        }
        self.box_sum(x0, y0, x1, y1)
    }

    /// Box sum in fixed-point steps; exact while the true sum fits an `i32`.
    pub(crate) fn box_sum_fixed(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> i32 {
        let s = self.stride();
        let t = &self.sum;
        t[y1 * s + x1]
            .wrapping_sub(t[y0 * s + x1])
            .wrapping_sub(t[y1 * s + x0])
            .wrapping_add(t[y0 * s + x0]) as i32
    }

    /// Sum of squared samples over the half-open box, in 8-bit units squared (`None` without
    /// squares).
    pub fn box_sum_squares(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> Option<f64> {
        if self.squares.is_empty() {
            return None;
        }
        let s = self.stride();
        let t = &self.squares;
        let fixed = t[y1 * s + x1]
            .wrapping_sub(t[y0 * s + x1])
            .wrapping_sub(t[y1 * s + x0])
            .wrapping_add(t[y0 * s + x0]);
        Some(fixed as f64 / f64::from(FIXED * FIXED))
    }
}

/// `here[x] = above[x] + samples[0..=x]`, wrapping: one row of the running table.
fn accumulate_row<T: Copy + Default + WrappingAdd>(
    above: &[T],
    here: &mut [T],
    samples: impl Iterator<Item = T>,
) {
    let mut run = T::default();
    for ((out, &up), q) in here.iter_mut().zip(above).zip(samples) {
        run = run.wrapping_add(q);
        *out = up.wrapping_add(run);
    }
}

/// The wrapping addition of the table's integer types.
trait WrappingAdd {
    fn wrapping_add(self, other: Self) -> Self;
}

impl WrappingAdd for u32 {
    fn wrapping_add(self, other: Self) -> Self {
        u32::wrapping_add(self, other)
    }
}

impl WrappingAdd for u64 {
    fn wrapping_add(self, other: Self) -> Self {
        u64::wrapping_add(self, other)
    }
}

/// Fixed-point sample, rounded half away from zero (as `f32::round`): the sample is clamped to
/// `[0, 16368]`, so `t + 0.5` is exact in `f64` and truncation is the rounding, without the
/// `roundf` call baseline x86-64 would make.
fn to_fixed(v: f32) -> u32 {
    // NaN stays NaN through `clamp` and the saturating cast turns it into 0.
    let t = v.clamp(0.0, MAX_SAMPLE) * FIXED;
    (f64::from(t) + 0.5) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(img: &GrayImage32, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
        let mut s = 0.0;
        for y in y0..y1 {
            for x in x0..x1 {
                s += f64::from((img.get(x, y).unwrap() * FIXED).round() / FIXED);
            }
        }
        s
    }

    #[test]
    fn thesis_table_2_1() {
        let a = [
            57, 57, 66, 72, 76, 64, 65, 66, 70, 78, 65, 61, 64, 69, 69, 109, 76, 84, 109, 107, 115,
            69, 101, 132, 124,
        ];
        let mut img = GrayImage32::new(5, 5);
        for (o, v) in img.as_mut_slice().iter_mut().zip(a) {
            *o = v as f32;
        }
        let ii = IntegralImage::from_image(&img, true);
        assert_eq!(ii.box_sum(0, 0, 5, 5), a.iter().sum::<i32>() as f32);
        assert_eq!(ii.box_sum(0, 0, 2, 2), (57 + 57 + 64 + 65) as f32);
        assert_eq!(ii.box_sum(3, 3, 5, 5), (109 + 107 + 132 + 124) as f32);
        let sq: i32 = [109, 107, 132, 124].iter().map(|v| v * v).sum();
        assert_eq!(ii.box_sum_squares(3, 3, 5, 5), Some(f64::from(sq)));
    }

    #[test]
    fn fixed_point_rounding_matches_f32_round() {
        let mut v = -3.0f32;
        while v < 1030.0 {
            for x in [v, v.next_up(), v.next_down(), v + 1.0 / 32.0] {
                assert_eq!(
                    to_fixed(x),
                    (x.clamp(0.0, MAX_SAMPLE) * FIXED).round() as u32,
                    "{x}"
                );
            }
            v += 1.0 / 64.0;
        }
        assert_eq!(to_fixed(f32::NAN), 0);
    }

    #[test]
    fn channel_table_equals_the_table_of_the_channel_image() {
        let rgb = image::RgbImage::from_fn(37, 23, |x, y| {
            image::Rgb([(x * 7 + y) as u8, (x * y) as u8, 255 - x as u8])
        });
        for c in 0..3 {
            let mut plane = GrayImage32::new(37, 23);
            for (o, px) in plane.as_mut_slice().iter_mut().zip(rgb.pixels()) {
                *o = f32::from(px.0[c]);
            }
            let mut direct = IntegralImage::default();
            direct.compute_channel(&rgb, c);
            assert_eq!(
                direct.sum,
                IntegralImage::from_image(&plane, false).sum,
                "channel {c}"
            );
        }
    }

    #[test]
    fn every_box_is_exact_even_when_running_sums_wrap() {
        // 700 x 700 x 255 x 16 overflows u32: the corner differences must still be exact.
        let (w, h) = (700, 700);
        let mut img = GrayImage32::new(w, h);
        for (i, v) in img.as_mut_slice().iter_mut().enumerate() {
            *v = ((i * 7919) % 256) as f32 + 0.25;
        }
        let ii = IntegralImage::from_image(&img, false);
        for &(x0, y0, x1, y1) in &[
            (0, 0, 3, 3),
            (650, 640, 700, 700),
            (10, 690, 200, 700),
            (0, 0, 37, 700),
        ] {
            assert_eq!(
                f64::from(ii.box_sum(x0, y0, x1, y1)),
                brute(&img, x0, y0, x1, y1),
                "box {x0},{y0},{x1},{y1}"
            );
        }
        assert_eq!(ii.box_sum_clipped(-5, -5, 2, 1), ii.box_sum(0, 0, 2, 1));
        assert_eq!(ii.box_sum_clipped(690, 690, 710, 690), 0.0);
    }
}
