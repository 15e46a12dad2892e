//! Orientation and the 64-element descriptor from Haar wavelet responses (thesis 2.8.4).
//!
//! Orientation: Haar responses of side `4s` sampled every `s` within radius `6s`, weighted by a
//! Gaussian of `2s`, summed over a sliding window of pi/3; the longest sum gives the angle.
//! Descriptor: a `20s` square aligned with that angle, 4x4 sub-regions of 5x5 samples, Haar side
//! `2s`, responses turned into the keypoint's frame, Gaussian `3.3s` weighting, per sub-region
//! `(sum dx, sum dy, sum |dx|, sum |dy|)`, then unit length (contrast invariance).

use std::f32::consts::{FRAC_PI_3, TAU};

use rayon::prelude::*;

use crate::integral::FIXED;
use crate::{IntegralImage, Keypoint};

/// Haar wavelet responses `(dx, dy)` of side `side` (even, px) centred on pixel `(x, y)`.
#[inline(always)]
fn haar(ii: &IntegralImage, x: isize, y: isize, side: isize) -> (f32, f32) {
    let h = side / 2;
    if x < h || y < h || x + h > ii.width() as isize || y + h > ii.height() as isize {
        let dx =
            ii.box_sum_clipped(x, y - h, x + h, y + h) - ii.box_sum_clipped(x - h, y - h, x, y + h);
        let dy =
            ii.box_sum_clipped(x - h, y, x + h, y + h) - ii.box_sum_clipped(x - h, y - h, x + h, y);
        return (dx, dy);
    }
    // Inside the image: the four half boxes share a 3x3 grid of table corners.
    let (s, t) = (ii.stride(), ii.table());
    let (x, y, h) = (x as usize, y as usize, h as usize);
    let row = |r: usize| {
        let i = r * s + x - h;
        let corners = &t[i..=i + 2 * h];
        (corners[0], corners[h], corners[2 * h])
    };
    let ((a0, a1, a2), (b0, _, b2), (c0, c1, c2)) = (row(y - h), row(y), row(y + h));
    let sum = |br: u32, tr: u32, bl: u32, tl: u32| {
        br.wrapping_sub(tr).wrapping_sub(bl).wrapping_add(tl) as i32 as f32 / FIXED
    };
    let dx = sum(c2, a2, c1, a1) - sum(c1, a1, c0, a0);
    let dy = sum(c2, b2, c0, b0) - sum(b2, a2, b0, a0);
    (dx, dy)
}

/// Nearest even integer >= 2 to `v`.
fn even_side(v: f32) -> isize {
    ((v / 2.0).round() as isize * 2).max(2)
}

/// `v.round() as isize` (half away from zero) without the `roundf` call baseline x86-64 makes:
/// `|v| + 0.5` is exact in `f64`, and truncation is then the rounding.
#[inline]
fn round_px(v: f32) -> isize {
    let magnitude = (f64::from(v.abs()) + 0.5) as isize;
    if v < 0.0 { -magnitude } else { magnitude }
}

/// Gaussian weights, computed once per frame: orientation (sigma 2s on the 13x13 sample grid)
/// and descriptor (sigma 3.3s on the 20x20 grid).
struct Weights {
    orientation: [[f32; 13]; 13],
    descriptor: [[f32; 20]; 20],
}

impl Weights {
    fn new() -> Self {
        let mut w = Weights {
            orientation: [[0.0; 13]; 13],
            descriptor: [[0.0; 20]; 20],
        };
        for j in -6i32..=6 {
            for i in -6i32..=6 {
                let d2 = (i * i + j * j) as f32;
                w.orientation[(j + 6) as usize][(i + 6) as usize] = (-d2 / (2.0 * 2.0 * 2.0)).exp();
            }
        }
        for (row, weights) in w.descriptor.iter_mut().enumerate() {
            for (col, weight) in weights.iter_mut().enumerate() {
                let u = (col / 5) as f32 * 5.0 + (col % 5) as f32 - 9.5;
                let v = (row / 5) as f32 * 5.0 + (row % 5) as f32 - 9.5;
                *weight = (-(u * u + v * v) / (2.0 * 3.3 * 3.3)).exp();
            }
        }
        w
    }
}

/// Fills each keypoint's orientation (unless `upright`) and returns the descriptors.
pub(crate) fn describe(
    ii: &IntegralImage,
    keypoints: &mut [Keypoint],
    upright: bool,
) -> Vec<[f32; 64]> {
    let weights = Weights::new();
    keypoints
        .par_iter_mut()
        .map(|kp| {
            if !upright {
                kp.orientation = orientation(ii, kp, &weights);
            }
            descriptor(ii, kp, &weights)
        })
        .collect()
}

/// Dominant orientation, radians in `(-pi, pi]`, image axes (x right, y down).
fn orientation(ii: &IntegralImage, kp: &Keypoint, weights: &Weights) -> f32 {
    let s = kp.scale;
    let side = even_side(4.0 * s);
    let mut samples = [(0.0f32, 0.0f32, 0.0f32); 113];
    let mut n = 0;
    for j in -6i32..=6 {
        for i in -6i32..=6 {
            if i * i + j * j >= 36 {
                continue;
            }
            let weight = weights.orientation[(j + 6) as usize][(i + 6) as usize];
            let px = round_px(kp.x + i as f32 * s);
            let py = round_px(kp.y + j as f32 * s);
            let (dx, dy) = haar(ii, px, py, side);
            let (dx, dy) = (dx * weight, dy * weight);
            if dx != 0.0 || dy != 0.0 {
                samples[n] = (dy.atan2(dx).rem_euclid(TAU), dx, dy);
                n += 1;
            }
        }
    }
    let samples = &mut samples[..n];
    if samples.is_empty() {
        return 0.0;
    }
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Every window [angle_k, angle_k + pi/3) over the circle: two pointers on the doubled list.
    let n = samples.len();
    let at = |k: usize| {
        let (a, dx, dy) = samples[k % n];
        (if k >= n { a + TAU } else { a }, dx, dy)
    };
    let (mut end, mut sx, mut sy) = (0usize, 0.0f32, 0.0f32);
    let (mut best, mut best_x, mut best_y) = (-1.0f32, 0.0, 0.0);
    for start in 0..n {
        let start_angle = at(start).0;
        while end < start + n && at(end).0 < start_angle + FRAC_PI_3 {
            let (_, dx, dy) = at(end);
            sx += dx;
            sy += dy;
            end += 1;
        }
        let norm = sx * sx + sy * sy;
        if norm > best {
            (best, best_x, best_y) = (norm, sx, sy);
        }
        let (_, dx, dy) = at(start);
        sx -= dx;
        sy -= dy;
    }
    best_y.atan2(best_x)
}

/// The 64-element descriptor in the keypoint's frame, unit length (all zero on a flat patch).
fn descriptor(ii: &IntegralImage, kp: &Keypoint, weights: &Weights) -> [f32; 64] {
    let s = kp.scale;
    let side = even_side(2.0 * s);
    let (sin, cos) = kp.orientation.sin_cos();
    let mut out = [0.0f32; 64];
    for (k, cell) in out.chunks_exact_mut(4).enumerate() {
        let (cell_row, cell_col) = ((k / 4) as f32, (k % 4) as f32);
        for a in 0..5 {
            for b in 0..5 {
                // Sample centre in keypoint units: u along the orientation, v across it.
                let u = cell_col * 5.0 + b as f32 - 9.5;
                let v = cell_row * 5.0 + a as f32 - 9.5;
                let px = round_px(kp.x + (u * cos - v * sin) * s);
                let py = round_px(kp.y + (u * sin + v * cos) * s);
                let weight = weights.descriptor[(k / 4) * 5 + a][(k % 4) * 5 + b];
                let (dx, dy) = haar(ii, px, py, side);
                let du = weight * (dx * cos + dy * sin);
                let dv = weight * (-dx * sin + dy * cos);
                cell[0] += du;
                cell[1] += dv;
                cell[2] += du.abs();
                cell[3] += dv.abs();
            }
        }
    }
    let norm = out.iter().map(|v| v * v).sum::<f32>().sqrt();
    if norm > 0.0 {
        out.iter_mut().for_each(|v| *v /= norm);
    }
    out
}
