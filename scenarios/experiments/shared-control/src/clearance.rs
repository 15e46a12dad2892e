//! True clearance between the chair's footprint and the map: what "near obstacles" means in the
//! report, independent of what the sensors (and so the controllers) see.

use iw_sim::Map;
use nalgebra::Point2;

/// Every solid segment of a map: walls, furniture outlines, closed doors.
pub(crate) struct Obstacles {
    segments: Vec<(Point2<f64>, Point2<f64>)>,
}

impl Obstacles {
    pub(crate) fn from_map(map: &Map) -> Self {
        let mut segments = Vec::new();
        for wall in &map.walls {
            segments.extend(wall.windows(2).map(|w| (w[0], w[1])));
        }
        for item in &map.furniture {
            let n = item.polygon.len();
            segments.extend((0..n).map(|i| (item.polygon[i], item.polygon[(i + 1) % n])));
        }
        segments.extend(map.doors.iter().filter(|d| !d.open).map(|d| (d.a, d.b)));
        Obstacles { segments }
    }

    /// Smallest distance from the footprint polygon to any segment, m (0 when touching); segments
    /// farther than `cutoff_m` from the footprint are skipped, so the result saturates at `cutoff_m`.
    pub(crate) fn clearance(&self, footprint: &[Point2<f64>; 4], cutoff_m: f64) -> f64 {
        // Every footprint point lies within the diagonal of corner 0.
        let diagonal = (footprint[2] - footprint[0]).norm();
        let mut best = cutoff_m;
        for &(a, b) in &self.segments {
            if point_segment(footprint[0], a, b) > cutoff_m + diagonal {
                continue;
            }
            for i in 0..4 {
                best = best.min(segment_segment(footprint[i], footprint[(i + 1) % 4], a, b));
            }
        }
        best
    }
}

fn point_segment(p: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).norm()
}

fn cross(o: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    (a - o).perp(&(b - o))
}

fn segment_segment(p: Point2<f64>, q: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    let (d1, d2) = (cross(a, b, p), cross(a, b, q));
    let (d3, d4) = (cross(p, q, a), cross(p, q, b));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    point_segment(p, a, b)
        .min(point_segment(q, a, b))
        .min(point_segment(a, p, q))
        .min(point_segment(b, p, q))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        let p = |x, y| Point2::new(x, y);
        assert_eq!(
            segment_segment(p(0.0, 0.0), p(2.0, 0.0), p(1.0, -1.0), p(1.0, 1.0)),
            0.0
        );
        assert!(
            (segment_segment(p(0.0, 0.0), p(2.0, 0.0), p(0.0, 1.0), p(2.0, 1.5)) - 1.0).abs()
                < 1e-12
        );
        let map = Map::parse("wall 0 1 10 1\n", "t").unwrap();
        let obstacles = Obstacles::from_map(&map);
        let footprint = [p(0.0, -0.5), p(1.0, -0.5), p(1.0, 0.5), p(0.0, 0.5)];
        assert!((obstacles.clearance(&footprint, 5.0) - 0.5).abs() < 1e-12);
    }
}
