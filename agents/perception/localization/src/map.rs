//! The map as the localizer sees it: solid segments (walls, furniture) in a bucket grid for
//! nearest-segment queries, landmarks with known poses, and a coarse distance grid for the
//! global search.

use nalgebra::{Point2, Vector2};

use crate::LocalizationError;
use iw_vo::Pose2;

/// A marker with a known pose (thesis 3.8): its id is what the detector decodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landmark {
    /// Identifier encoded on the marker.
    pub id: u32,
    /// Centre of the marker and the direction its face looks, map frame.
    pub pose: Pose2,
}

/// Nearest point of a segment to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Distance, m.
    pub distance_m: f64,
    /// Unit vector from the nearest point to the query point (the residual's direction).
    pub normal: Vector2<f64>,
}

/// Bucket size of the segment grid, m.
const BUCKET_M: f64 = 0.5;
/// Distance grid cell for the global search, m.
const FIELD_CELL_M: f64 = 0.1;

/// Solid segments and landmarks, indexed for the matcher and the global search.
#[derive(Debug, Clone)]
pub struct LocalizationMap {
    segments: Vec<(Point2<f64>, Point2<f64>)>,
    landmarks: Vec<Landmark>,
    min: Point2<f64>,
    cols: usize,
    rows: usize,
    /// Per bucket: segments within `reach_m` of it.
    buckets: Vec<Vec<u32>>,
    reach_m: f64,
    /// Distance to the nearest segment at each field cell centre, capped at `reach_m`.
    field: Vec<f32>,
    field_cols: usize,
    field_rows: usize,
}

fn nearest_on(a: &Point2<f64>, b: &Point2<f64>, p: &Point2<f64>) -> Point2<f64> {
    let e = b - a;
    let len2 = e.norm_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(&e) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + e * t
}

impl LocalizationMap {
    /// Indexes `segments` (solid map geometry; doors and anything that moves left out) and
    /// `landmarks`. Queries answer within `reach_m` of a segment. Errors on no segments, a
    /// non-finite coordinate or an area over 1 km².
    pub fn new(
        segments: Vec<(Point2<f64>, Point2<f64>)>,
        landmarks: Vec<Landmark>,
        reach_m: f64,
    ) -> Result<Self, LocalizationError> {
        if segments.is_empty() {
            return Err(LocalizationError::BadMap {
                reason: "no solid segments to match against".into(),
            });
        }
        if !(reach_m.is_finite() && reach_m > 0.0 && reach_m <= 10.0) {
            return Err(LocalizationError::BadMap {
                reason: format!("reach {reach_m} m must lie in (0, 10]"),
            });
        }
        let finite = |p: &Point2<f64>| p.x.is_finite() && p.y.is_finite();
        if let Some(bad) = segments.iter().find(|(a, b)| !finite(a) || !finite(b)) {
            return Err(LocalizationError::BadMap {
                reason: format!("segment {bad:?} has a non-finite coordinate"),
            });
        }
        let (mut lo, mut hi) = (segments[0].0, segments[0].0);
        for (a, b) in &segments {
            lo = lo.inf(a).inf(b);
            hi = hi.sup(a).sup(b);
        }
        let margin = Vector2::repeat(reach_m + BUCKET_M);
        let (min, max) = (lo - margin, hi + margin);
        let size = max - min;
        if size.x * size.y > 1e6 {
            return Err(LocalizationError::BadMap {
                reason: format!("map spans {:.0} x {:.0} m, over 1 km²", size.x, size.y),
            });
        }
        let cols = (size.x / BUCKET_M).ceil() as usize;
        let rows = (size.y / BUCKET_M).ceil() as usize;
        let mut buckets = vec![Vec::new(); cols * rows];
        for (i, (a, b)) in segments.iter().enumerate() {
            let (slo, shi) = (
                a.inf(b) - Vector2::repeat(reach_m),
                a.sup(b) + Vector2::repeat(reach_m),
            );
            let c0 = ((slo.x - min.x) / BUCKET_M).floor().max(0.0) as usize;
            let r0 = ((slo.y - min.y) / BUCKET_M).floor().max(0.0) as usize;
            let c1 = (((shi.x - min.x) / BUCKET_M).floor() as usize).min(cols - 1);
            let r1 = (((shi.y - min.y) / BUCKET_M).floor() as usize).min(rows - 1);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    // keep the segment only if it comes within reach of the bucket
                    let centre = min
                        + Vector2::new((c as f64 + 0.5) * BUCKET_M, (r as f64 + 0.5) * BUCKET_M);
                    let half_diag = BUCKET_M * std::f64::consts::FRAC_1_SQRT_2;
                    if (nearest_on(a, b, &centre) - centre).norm() <= reach_m + half_diag {
                        buckets[r * cols + c].push(i as u32);
                    }
                }
            }
        }
        let mut map = LocalizationMap {
            segments,
            landmarks,
            min,
            cols,
            rows,
            buckets,
            reach_m,
            field: Vec::new(),
            field_cols: (size.x / FIELD_CELL_M).ceil() as usize,
            field_rows: (size.y / FIELD_CELL_M).ceil() as usize,
        };
        let mut field = Vec::with_capacity(map.field_cols * map.field_rows);
        for r in 0..map.field_rows {
            for c in 0..map.field_cols {
                let p = min
                    + Vector2::new(
                        (c as f64 + 0.5) * FIELD_CELL_M,
                        (r as f64 + 0.5) * FIELD_CELL_M,
                    );
                field.push(map.nearest(&p).map_or(reach_m, |n| n.distance_m) as f32);
            }
        }
        map.field = field;
        Ok(map)
    }

    /// The landmarks.
    pub fn landmarks(&self) -> &[Landmark] {
        &self.landmarks
    }

    /// The segments.
    pub fn segments(&self) -> &[(Point2<f64>, Point2<f64>)] {
        &self.segments
    }

    /// How far from a segment queries answer, m.
    pub fn reach_m(&self) -> f64 {
        self.reach_m
    }

    /// The map's extent with the query margin: (lower-left, upper-right).
    pub fn bounds(&self) -> (Point2<f64>, Point2<f64>) {
        (
            self.min,
            self.min + Vector2::new(self.cols as f64, self.rows as f64) * BUCKET_M,
        )
    }

    /// The nearest segment point to `p` within [`Self::reach_m`], exactly.
    pub fn nearest(&self, p: &Point2<f64>) -> Option<Nearest> {
        let c = ((p.x - self.min.x) / BUCKET_M).floor();
        let r = ((p.y - self.min.y) / BUCKET_M).floor();
        if !(c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows) {
            return None;
        }
        let mut best: Option<(f64, Vector2<f64>)> = None;
        for &s in &self.buckets[r as usize * self.cols + c as usize] {
            let (a, b) = &self.segments[s as usize];
            let d = p - nearest_on(a, b, p);
            let n2 = d.norm_squared();
            if best.is_none_or(|(bd, _)| n2 < bd) {
                best = Some((n2, d));
            }
        }
        let (n2, d) = best?;
        let distance_m = n2.sqrt();
        (distance_m <= self.reach_m).then(|| Nearest {
            distance_m,
            normal: if distance_m > 1e-9 {
                d / distance_m
            } else {
                Vector2::zeros()
            },
        })
    }

    /// The distance grid's lower-left corner, cell size (m), columns and rows: cell `(c, r)`
    /// spans `min + cell * (c, r)` to `min + cell * (c + 1, r + 1)`.
    pub(crate) fn field_grid(&self) -> (Point2<f64>, f64, usize, usize) {
        (self.min, FIELD_CELL_M, self.field_cols, self.field_rows)
    }

    /// Distance to the nearest segment from the coarse grid (0.1 m cells, capped at the reach;
    /// outside the map: the reach). For the global search, where speed beats precision.
    pub fn field_distance(&self, x: f64, y: f64) -> f64 {
        let c = (x - self.min.x) / FIELD_CELL_M;
        let r = (y - self.min.y) / FIELD_CELL_M;
        if c >= 0.0 && r >= 0.0 && (c as usize) < self.field_cols && (r as usize) < self.field_rows
        {
            f64::from(self.field[r as usize * self.field_cols + c as usize])
        } else {
            self.reach_m
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_matches_brute_force() {
        let segs = vec![
            (Point2::new(0.0, 0.0), Point2::new(5.0, 0.0)),
            (Point2::new(5.0, 0.0), Point2::new(5.0, 3.0)),
            (Point2::new(1.0, 2.0), Point2::new(2.0, 2.5)),
        ];
        let map = LocalizationMap::new(segs.clone(), vec![], 1.0).unwrap();
        for k in 0..500 {
            let p = Point2::new((k % 25) as f64 * 0.27 - 0.5, (k / 25) as f64 * 0.19 - 0.5);
            let brute = segs
                .iter()
                .map(|(a, b)| (p - nearest_on(a, b, &p)).norm())
                .fold(f64::INFINITY, f64::min);
            match map.nearest(&p) {
                Some(n) => assert!((n.distance_m - brute).abs() < 1e-12, "{p:?}"),
                None => assert!(brute > 1.0 - 1e-9, "{p:?}: {brute}"),
            }
        }
    }

    #[test]
    fn empty_and_non_finite_maps_are_errors() {
        assert!(LocalizationMap::new(vec![], vec![], 1.0).is_err());
        let nan = vec![(Point2::new(f64::NAN, 0.0), Point2::new(1.0, 0.0))];
        assert!(LocalizationMap::new(nan, vec![], 1.0).is_err());
    }
}
