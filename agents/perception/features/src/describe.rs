//! Orientation and the 64-element descriptor from Haar wavelet responses (thesis 2.8.4).
//!
//! Orientation: Haar responses of side `4s` sampled every `s` within radius `6s`, weighted by a
//! Gaussian of `2s`, summed over a sliding window of pi/3; the longest sum gives the angle.
//! Descriptor: a `20s` square aligned with that angle, 4x4 sub-regions of 5x5 samples, Haar side
//! `2s`, responses turned into the keypoint's frame, Gaussian `3.3s` weighting, per sub-region
//! `(sum dx, sum dy, sum |dx|, sum |dy|)`, then unit length (contrast invariance).

use std::f32::consts::{FRAC_PI_3, TAU};

use rayon::prelude::*;

use crate::{IntegralImage, Keypoint};

/// Haar wavelet responses `(dx, dy)` of side `side` (even, px) centred on pixel `(x, y)`.
fn haar(ii: &IntegralImage, x: isize, y: isize, side: isize) -> (f32, f32) {
    let h = side / 2;
    let dx = ii.box_sum_clipped(x, y - h, x + h, y + h) - ii.box_sum_clipped(x - h, y - h, x, y + h);
    let dy = ii.box_sum_clipped(x - h, y, x + h, y + h) - ii.box_sum_clipped(x - h, y - h, x + h, y);
    (dx, dy)
}

/// Nearest even integer >= 2 to `v`.
fn even_side(v: f32) -> isize {
    ((v / 2.0).round() as isize * 2).max(2)
}

/// Fills each keypoint's orientation (unless `upright`) and returns the descriptors.
pub(crate) fn describe(ii: &IntegralImage, keypoints: &mut [Keypoint], upright: bool) -> Vec<[f32; 64]> {
    keypoints
        .par_iter_mut()
        .map(|kp| {
            if !upright {
                kp.orientation = orientation(ii, kp);
            }
            descriptor(ii, kp)
        })
        .collect()
}

/// Dominant orientation, radians in `(-pi, pi]`, image axes (x right, y down).
pub(crate) fn orientation(ii: &IntegralImage, kp: &Keypoint) -> f32 {
    let s = kp.scale;
    let side = even_side(4.0 * s);
    let mut samples: Vec<(f32, f32, f32)> = Vec::with_capacity(113);
    for j in -6i32..=6 {
        for i in -6i32..=6 {
            let d2 = (i * i + j * j) as f32;
            if d2 >= 36.0 {
                continue;
            }
            let weight = (-d2 / (2.0 * 2.0 * 2.0)).exp();
            let px = (kp.x + i as f32 * s).round() as isize;
            let py = (kp.y + j as f32 * s).round() as isize;
            let (dx, dy) = haar(ii, px, py, side);
            let (dx, dy) = (dx * weight, dy * weight);
            if dx != 0.0 || dy != 0.0 {
                samples.push((dy.atan2(dx).rem_euclid(TAU), dx, dy));
            }
        }
    }
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
pub(crate) fn descriptor(ii: &IntegralImage, kp: &Keypoint) -> [f32; 64] {
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
                let px = (kp.x + (u * cos - v * sin) * s).round() as isize;
                let py = (kp.y + (u * sin + v * cos) * s).round() as isize;
                let weight = (-(u * u + v * v) / (2.0 * 3.3 * 3.3)).exp();
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
