//! Which keypoints a count cap keeps ([`DetectorConfig::max_keypoints`]): the highest ranked,
//! optionally discounted by size and spaced apart (LSAC-SURF-NT).

use crate::{DetectorConfig, Keypoint};

/// The rank of `kp`: its response times `(9 / size)^exponent` (the response when 0).
fn rank(kp: &Keypoint, exponent: f32) -> f32 {
    if exponent == 0.0 {
        kp.response
    } else {
        kp.response * (9.0 / kp.size.max(1e-6)).powf(exponent)
    }
}

/// Keeps at most `max` keypoints, highest rank first, none within `separation` px of a keypoint
/// kept before it. A keypoint's rank is multiplied by its `weights` entry when given (the noise
/// model's 1 / noise unit: the rank becomes a signal-to-noise ratio). Deterministic: ties keep
/// the input order.
pub(crate) fn keep(
    mut keypoints: Vec<Keypoint>,
    weights: Option<&[f32]>,
    max: usize,
    exponent: f32,
    separation: f32,
) -> Vec<Keypoint> {
    let mut ranked: Vec<(f32, Keypoint)> = keypoints
        .drain(..)
        .enumerate()
        .map(|(i, kp)| {
            let weight = weights.and_then(|w| w.get(i)).copied().unwrap_or(1.0);
            (rank(&kp, exponent) * weight, kp)
        })
        .collect();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
    if separation <= 0.0 {
        return ranked.into_iter().take(max).map(|(_, kp)| kp).collect();
    }
    // Kept keypoints hashed by cells of side `separation`: a conflict lies in the 3x3 cells around.
    let cell = |v: f32| (v / separation).floor() as i64;
    let mut grid: std::collections::HashMap<(i64, i64), Vec<(f32, f32)>> =
        std::collections::HashMap::new();
    let mut kept = Vec::with_capacity(max.min(ranked.len()));
    for (_, kp) in ranked {
        if kept.len() == max {
            break;
        }
        let (cx, cy) = (cell(kp.x), cell(kp.y));
        let crowded = (cx - 1..=cx + 1).any(|gx| {
            (cy - 1..=cy + 1).any(|gy| {
                grid.get(&(gx, gy)).is_some_and(|points| {
                    points
                        .iter()
                        .any(|&(x, y)| (x - kp.x).hypot(y - kp.y) <= separation)
                })
            })
        });
        if !crowded {
            grid.entry((cx, cy)).or_default().push((kp.x, kp.y));
            kept.push(kp);
        }
    }
    kept
}

/// [`keep`] with `config`'s cap, rank and spacing; `pixel` is the size of an input pixel in the
/// keypoints' coordinates (2 on a doubled image).
pub(crate) fn apply(
    keypoints: Vec<Keypoint>,
    weights: Option<&[f32]>,
    config: &DetectorConfig,
    pixel: f32,
) -> Vec<Keypoint> {
    match config.max_keypoints {
        Some(max) => keep(
            keypoints,
            weights,
            max,
            config.rank_size_exponent,
            config.min_separation_px * pixel,
        ),
        None => keypoints,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FeatureClass;

    fn kp(x: f32, y: f32, size: f32, response: f32) -> Keypoint {
        Keypoint {
            x,
            y,
            scale: 1.2 * size / 9.0,
            size,
            orientation: 0.0,
            response,
            laplacian_sign: 1,
            class: FeatureClass::Hard,
        }
    }

    #[test]
    fn the_cap_keeps_the_strongest_when_not_discounted() {
        let kept = keep(
            vec![
                kp(0.0, 0.0, 9.0, 1.0),
                kp(10.0, 0.0, 30.0, 3.0),
                kp(20.0, 0.0, 9.0, 2.0),
            ],
            None,
            2,
            0.0,
            0.0,
        );
        assert_eq!(
            kept.iter().map(|k| k.response).collect::<Vec<_>>(),
            [3.0, 2.0]
        );
    }

    #[test]
    fn the_size_discount_prefers_a_fine_keypoint_of_similar_response() {
        // 3.0 at 27 px ranks 3 (9/27)^2 = 0.33, below 1.0 at 9 px.
        let kept = keep(
            vec![kp(10.0, 0.0, 27.0, 3.0), kp(0.0, 0.0, 9.0, 1.0)],
            None,
            1,
            2.0,
            0.0,
        );
        assert_eq!(kept[0].size, 9.0);
    }

    #[test]
    fn a_keypoint_near_a_stronger_kept_one_is_dropped_at_any_scale() {
        let kept = keep(
            vec![
                kp(5.0, 5.0, 15.0, 1.0),
                kp(6.5, 5.5, 40.0, 0.9),  // 1.6 px from the first: dropped
                kp(8.0, 5.0, 15.0, 0.8),  // 3 px: kept
                kp(-3.0, 5.0, 15.0, 0.7), // other side of a cell border, 8 px: kept
            ],
            None,
            10,
            0.0,
            2.0,
        );
        assert_eq!(
            kept.iter().map(|k| k.response).collect::<Vec<_>>(),
            [1.0, 0.8, 0.7]
        );
    }
}
