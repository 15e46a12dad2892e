//! Brute-force descriptor matching: Lowe's ratio test, mutual nearest neighbours, opposite
//! Laplacian signs skipped (a bright blob never matches a dark one), and only hard query
//! features matched, against all train features (thesis 4.5).

use rayon::prelude::*;

use crate::{FeatureClass, Features, Match, MatchConfig};

fn distance_sq(a: &[f32; 64], b: &[f32; 64]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Nearest and second-nearest squared distances from `features[i]` to the candidates of `other`.
fn nearest_two(features: &Features, i: usize, other: &Features) -> Option<(usize, f32, f32)> {
    let (kp, desc) = (features.keypoints.get(i)?, features.descriptors.get(i)?);
    let mut best = (usize::MAX, f32::INFINITY, f32::INFINITY);
    for (j, (okp, odesc)) in other.keypoints.iter().zip(&other.descriptors).enumerate() {
        if okp.laplacian_sign != kp.laplacian_sign {
            continue;
        }
        let d = distance_sq(desc, odesc);
        if d < best.1 {
            best = (j, d, best.1);
        } else if d < best.2 {
            best.2 = d;
        }
    }
    (best.0 != usize::MAX).then_some(best)
}

/// Matches `query` against `train`. An invalid `config` (see [`MatchConfig::validate`]) gives no
/// matches rather than a panic. Output sorted by query index.
pub fn match_features(query: &Features, train: &Features, config: &MatchConfig) -> Vec<Match> {
    if config.validate().is_err() {
        return Vec::new();
    }
    let n = query.keypoints.len().min(query.descriptors.len());
    let ratio_sq = config.ratio * config.ratio;
    let max_sq = config.max_distance * config.max_distance;
    (0..n)
        .into_par_iter()
        .filter(|&i| !config.hard_queries_only || query.keypoints[i].class == FeatureClass::Hard)
        .filter_map(|i| {
            let (j, d1, d2) = nearest_two(query, i, train)?;
            if d1 > max_sq || (d2.is_finite() && d1 >= ratio_sq * d2) {
                return None;
            }
            if config.mutual {
                let (back, _, _) = nearest_two(train, j, query)?;
                if back != i {
                    return None;
                }
            }
            Some(Match {
                query_index: i,
                train_index: j,
                distance: d1.sqrt(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Keypoint;

    fn features(descs: &[[f32; 64]]) -> Features {
        let kp = Keypoint {
            x: 0.0,
            y: 0.0,
            scale: 1.2,
            size: 9.0,
            orientation: 0.0,
            response: 1.0,
            laplacian_sign: 1,
            class: FeatureClass::Hard,
        };
        Features {
            keypoints: vec![kp; descs.len()],
            descriptors: descs.to_vec(),
        }
    }

    fn unit(k: usize) -> [f32; 64] {
        let mut d = [0.0; 64];
        d[k] = 1.0;
        d
    }

    #[test]
    fn identity_matches_itself() {
        let f = features(&(0..10).map(unit).collect::<Vec<_>>());
        let m = match_features(&f, &f, &MatchConfig::default());
        assert_eq!(m.len(), 10);
        assert!(
            m.iter()
                .all(|m| m.query_index == m.train_index && m.distance == 0.0)
        );
    }

    #[test]
    fn opposite_laplacian_and_soft_queries_are_skipped() {
        let a = features(&[unit(0), unit(1)]);
        let mut b = a.clone();
        b.keypoints[0].laplacian_sign = -1;
        let mut q = a.clone();
        q.keypoints[1].class = FeatureClass::Soft;
        assert_eq!(match_features(&a, &b, &MatchConfig::default()).len(), 1);
        assert_eq!(match_features(&q, &a, &MatchConfig::default()).len(), 1);
    }

    #[test]
    fn ambiguous_matches_fail_the_ratio_test() {
        let q = features(&[unit(0)]);
        let (mut left, mut right) = (unit(0), unit(0));
        left[1] = 0.1;
        right[1] = -0.1;
        let t = features(&[left, right]);
        assert!(match_features(&q, &t, &MatchConfig::default()).is_empty());
    }
}
