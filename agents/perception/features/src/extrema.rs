//! Threshold, 3x3x3 non-maximum suppression and quadratic interpolation in space and scale
//! (Brown and Lowe; thesis eqs. 2.68-2.71).

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::hessian::{ScaleSpace, filter_size};
use crate::{DetectorConfig, FeatureClass, Keypoint};

/// Interpolation steps to a neighbouring sample before giving up on a candidate.
const MAX_MOVES: usize = 3;

/// Map cells of octave `o`, level `l` whose 26 neighbours all carry full filters: the valid
/// window of the next (largest) level shrunk by one cell.
fn interior(
    space: &ScaleSpace,
    octave: usize,
    level: usize,
) -> Option<(usize, usize, usize, usize)> {
    let top = &space.layers[octave * space.levels + level + 1];
    let (c0, c1, r0, r1) = (
        top.first_col + 1,
        top.last_col.checked_sub(1)?,
        top.first_row + 1,
        top.last_row.checked_sub(1)?,
    );
    (c0 <= c1 && r0 <= r1 && top.first_col <= top.last_col).then_some((c0, c1, r0, r1))
}

/// All interpolated maxima above `config.threshold`, in a deterministic order.
pub(crate) fn find(space: &ScaleSpace, config: &DetectorConfig) -> Vec<Keypoint> {
    let levels = space.levels;
    let mut tasks = Vec::new();
    for octave in 0..space.layers.len() / levels.max(1) {
        for level in 1..levels - 1 {
            if let Some((c0, c1, r0, r1)) = interior(space, octave, level) {
                tasks.extend((r0..=r1).map(|r| (octave, level, c0, c1, r)));
            }
        }
    }
    tasks
        .par_iter()
        .flat_map_iter(|&(octave, level, c0, c1, r)| {
            let m = &space.layers[octave * levels + level];
            // Most samples fail the threshold: scan the row first, test neighbours only then.
            let row = &m.responses[r * m.cols + c0..=r * m.cols + c1];
            row.iter()
                .enumerate()
                .filter(|&(_, &v)| v > config.threshold)
                .filter_map(move |(i, _)| {
                    let c = c0 + i;
                    is_maximum(space, octave, level, c, r, config.threshold)
                        .then(|| interpolate(space, octave, level, c, r, config.threshold))
                        .flatten()
                })
        })
        .collect()
}

fn is_maximum(
    space: &ScaleSpace,
    octave: usize,
    level: usize,
    c: usize,
    r: usize,
    threshold: f32,
) -> bool {
    let base = octave * space.levels;
    let v = space.layers[base + level].at(c, r);
    if v <= threshold {
        return false;
    }
    for l in level - 1..=level + 1 {
        let layer = &space.layers[base + l];
        for rr in r - 1..=r + 1 {
            let row = &layer.responses[rr * layer.cols + c - 1..=rr * layer.cols + c + 1];
            for (cc, &other) in (c - 1..=c + 1).zip(row) {
                if other >= v && (l, rr, cc) != (level, r, c) {
                    return false;
                }
            }
        }
    }
    true
}

/// Fits a 3-D quadratic to the 27 samples around `(c, r, level)` and returns the keypoint at its
/// maximum; moves to the neighbouring sample when the offset exceeds half a cell (thesis 2.8.4).
fn interpolate(
    space: &ScaleSpace,
    octave: usize,
    level: usize,
    c: usize,
    r: usize,
    threshold: f32,
) -> Option<Keypoint> {
    let base = octave * space.levels;
    let (mut level, mut c, mut r) = (level, c, r);
    for _ in 0..MAX_MOVES {
        let (b, m, t) = (
            &space.layers[base + level - 1],
            &space.layers[base + level],
            &space.layers[base + level + 1],
        );
        let v = m.at(c, r);
        let gradient = Vector3::new(
            (m.at(c + 1, r) - m.at(c - 1, r)) / 2.0,
            (m.at(c, r + 1) - m.at(c, r - 1)) / 2.0,
            (t.at(c, r) - b.at(c, r)) / 2.0,
        );
        let dxx = m.at(c + 1, r) + m.at(c - 1, r) - 2.0 * v;
        let dyy = m.at(c, r + 1) + m.at(c, r - 1) - 2.0 * v;
        let dss = t.at(c, r) + b.at(c, r) - 2.0 * v;
        let dxy = (m.at(c + 1, r + 1) - m.at(c - 1, r + 1) - m.at(c + 1, r - 1)
            + m.at(c - 1, r - 1))
            / 4.0;
        let dxs = (t.at(c + 1, r) - t.at(c - 1, r) - b.at(c + 1, r) + b.at(c - 1, r)) / 4.0;
        let dys = (t.at(c, r + 1) - t.at(c, r - 1) - b.at(c, r + 1) + b.at(c, r - 1)) / 4.0;
        let hessian = Matrix3::new(dxx, dxy, dxs, dxy, dyy, dys, dxs, dys, dss);
        let offset = -(hessian.lu().solve(&gradient)?);
        if !offset.iter().all(|o| o.is_finite()) {
            return None;
        }
        if offset.iter().all(|o| o.abs() < 0.5) {
            let response = v + 0.5 * gradient.dot(&offset);
            if response <= threshold {
                return None;
            }
            let step = m.step as f32;
            let size_step = (filter_size(octave, level + 1) - filter_size(octave, level)) as f32;
            let size = m.size as f32 + offset.z * size_step;
            return Some(Keypoint {
                x: (c as f32 + offset.x) * step,
                y: (r as f32 + offset.y) * step,
                scale: 1.2 * size / 9.0,
                size,
                orientation: 0.0,
                response,
                laplacian_sign: if m.laplacian_positive[r * m.cols + c] {
                    1
                } else {
                    -1
                },
                class: FeatureClass::Hard,
            });
        }
        // Move one sample toward the extremum and refit there, if that sample can be fitted.
        let shift = |v: usize, o: f32| {
            if o >= 0.5 {
                v + 1
            } else if o <= -0.5 {
                v.saturating_sub(1)
            } else {
                v
            }
        };
        let next_level = shift(level, offset.z);
        if next_level < 1 || next_level + 1 >= space.levels {
            return None;
        }
        let (c0, c1, r0, r1) = interior(space, octave, next_level)?;
        let (nc, nr) = (shift(c, offset.x), shift(r, offset.y));
        if !(c0..=c1).contains(&nc) || !(r0..=r1).contains(&nr) {
            return None;
        }
        (level, c, r) = (next_level, nc, nr);
    }
    None
}
