//! Segment and polygon math and the uniform-grid broad phase used for collisions and ray casts.

use nalgebra::{Point2, Vector2};

/// What a segment belongs to: decides who sees it, who collides with it and how it is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Owner {
    /// A wall of the building.
    Wall,
    /// Furniture (boxes, polygons).
    Furniture,
    /// Door number `.0` in [`crate::Map::doors`]; only present while the door is closed.
    Door(usize),
    /// The footprint of chair number `.0`.
    Chair(usize),
}

/// A solid segment of the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Start point, world frame, m.
    pub a: Point2<f64>,
    /// End point, world frame, m.
    pub b: Point2<f64>,
    /// Who it belongs to.
    pub owner: Owner,
    /// Height of the solid above the floor, m (the RGB-D camera sees over low furniture).
    pub height_m: f64,
    /// Texture index for the renderer.
    pub texture: usize,
}

/// `t` along the ray `origin + t * dir` (|dir| = 1) where it meets segment `a`-`b`, if `t >= 0`;
/// also the hit's fraction along the segment.
pub fn ray_segment(
    origin: &Point2<f64>,
    dir: &Vector2<f64>,
    a: &Point2<f64>,
    b: &Point2<f64>,
) -> Option<(f64, f64)> {
    let e = b - a;
    let denom = cross(dir, &e);
    if denom.abs() < 1e-12 {
        return None;
    }
    let w = a - origin;
    let t = cross(&w, &e) / denom;
    let u = cross(&w, dir) / denom;
    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some((t, u))
}

/// 2D cross product (z of the 3D one).
pub fn cross(a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Whether closed segments `p1`-`p2` and `q1`-`q2` touch.
pub fn segments_intersect(
    p1: &Point2<f64>,
    p2: &Point2<f64>,
    q1: &Point2<f64>,
    q2: &Point2<f64>,
) -> bool {
    let d1 = orient(q1, q2, p1);
    let d2 = orient(q1, q2, p2);
    let d3 = orient(p1, p2, q1);
    let d4 = orient(p1, p2, q2);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on_segment(q1, q2, p1))
        || (d2 == 0.0 && on_segment(q1, q2, p2))
        || (d3 == 0.0 && on_segment(p1, p2, q1))
        || (d4 == 0.0 && on_segment(p1, p2, q2))
}

fn orient(a: &Point2<f64>, b: &Point2<f64>, c: &Point2<f64>) -> f64 {
    cross(&(b - a), &(c - a))
}

fn on_segment(a: &Point2<f64>, b: &Point2<f64>, p: &Point2<f64>) -> bool {
    p.x >= a.x.min(b.x) && p.x <= a.x.max(b.x) && p.y >= a.y.min(b.y) && p.y <= a.y.max(b.y)
}

/// Whether `p` lies inside the simple polygon `poly` (even-odd rule).
pub fn point_in_polygon(p: &Point2<f64>, poly: &[Point2<f64>]) -> bool {
    let mut inside = false;
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (&poly[i], &poly[(i + n - 1) % n]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
    }
    inside
}

/// Whether segment `a`-`b` touches the convex or simple polygon `poly` (edge crossing or inside).
pub fn segment_hits_polygon(a: &Point2<f64>, b: &Point2<f64>, poly: &[Point2<f64>]) -> bool {
    let n = poly.len();
    (0..n).any(|i| segments_intersect(a, b, &poly[i], &poly[(i + 1) % n]))
        || point_in_polygon(a, poly)
}

/// Most cells along one grid axis: a 1 km building still gets 1 m cells, a huge map coarser ones.
pub const MAX_CELLS_PER_AXIS: usize = 1024;

/// Uniform grid over the world's bounding box; each cell lists the segments crossing it.
#[derive(Debug, Clone)]
pub struct Grid {
    origin: Point2<f64>,
    cell_m: f64,
    cols: usize,
    rows: usize,
    cells: Vec<Vec<u32>>,
    touched: Vec<usize>,
}

impl Grid {
    /// An empty grid covering `min`..`max` with square cells of `cell_m`, grown as needed to
    /// keep at most [`MAX_CELLS_PER_AXIS`] cells along each axis.
    pub fn new(min: Point2<f64>, max: Point2<f64>, cell_m: f64) -> Self {
        let extent = (max.x - min.x).max(max.y - min.y);
        let cell_m = cell_m.max(extent / MAX_CELLS_PER_AXIS as f64);
        let cols = (((max.x - min.x) / cell_m).ceil() as usize).clamp(1, MAX_CELLS_PER_AXIS);
        let rows = (((max.y - min.y) / cell_m).ceil() as usize).clamp(1, MAX_CELLS_PER_AXIS);
        Self {
            origin: min,
            cell_m,
            cols,
            rows,
            cells: vec![Vec::new(); cols * rows],
            touched: Vec::new(),
        }
    }

    /// Empties the cells filled since the last clear (cheap for sparse dynamic content).
    pub fn clear(&mut self) {
        for &c in &self.touched {
            self.cells[c].clear();
        }
        self.touched.clear();
    }

    fn cell_of(&self, p: &Point2<f64>) -> (usize, usize) {
        let cx = ((p.x - self.origin.x) / self.cell_m)
            .floor()
            .clamp(0.0, (self.cols - 1) as f64) as usize;
        let cy = ((p.y - self.origin.y) / self.cell_m)
            .floor()
            .clamp(0.0, (self.rows - 1) as f64) as usize;
        (cx, cy)
    }

    /// Registers segment `index` in every cell its bounding box covers.
    pub fn insert(&mut self, index: u32, a: &Point2<f64>, b: &Point2<f64>) {
        let (x0, y0) = self.cell_of(&Point2::new(a.x.min(b.x), a.y.min(b.y)));
        let (x1, y1) = self.cell_of(&Point2::new(a.x.max(b.x), a.y.max(b.y)));
        for cy in y0..=y1 {
            for cx in x0..=x1 {
                let c = cy * self.cols + cx;
                if self.cells[c].is_empty() {
                    self.touched.push(c);
                }
                self.cells[c].push(index);
            }
        }
    }

    /// Calls `f` with the segment indices of every cell overlapping the box `min`..`max`
    /// (an index may come more than once).
    pub fn query_box(&self, min: &Point2<f64>, max: &Point2<f64>, mut f: impl FnMut(u32)) {
        let (x0, y0) = self.cell_of(min);
        let (x1, y1) = self.cell_of(max);
        for cy in y0..=y1 {
            for cx in x0..=x1 {
                self.cells[cy * self.cols + cx].iter().for_each(|&i| f(i));
            }
        }
    }

    /// An empty grid with the same cells (cell indices are interchangeable between the two).
    pub fn empty_like(&self) -> Self {
        Self {
            cells: vec![Vec::new(); self.cells.len()],
            touched: Vec::new(),
            ..*self
        }
    }

    /// The segment indices in cell `cell` (as passed by [`Self::walk_ray`]).
    pub fn cell(&self, cell: usize) -> &[u32] {
        self.cells.get(cell).map_or(&[], Vec::as_slice)
    }

    /// Walks the cells along the ray from `origin` in direction `dir` (unit) up to `max_t`, in
    /// order (Amanatides-Woo). `visit(cell)` returns the best hit `t` found so far; the walk
    /// stops once that hit lies before the current cell's exit.
    pub fn walk_ray(
        &self,
        origin: &Point2<f64>,
        dir: &Vector2<f64>,
        max_t: f64,
        mut visit: impl FnMut(usize) -> f64,
    ) {
        let (mut cx, mut cy) = self.cell_of(origin);
        let step_x: isize = if dir.x >= 0.0 { 1 } else { -1 };
        let step_y: isize = if dir.y >= 0.0 { 1 } else { -1 };
        let next_boundary = |c: usize, s: isize, o: f64| self.origin_axis(o, c, s);
        let mut t_max_x = if dir.x.abs() < 1e-12 {
            f64::INFINITY
        } else {
            (next_boundary(cx, step_x, self.origin.x) - origin.x) / dir.x
        };
        let mut t_max_y = if dir.y.abs() < 1e-12 {
            f64::INFINITY
        } else {
            (next_boundary(cy, step_y, self.origin.y) - origin.y) / dir.y
        };
        let t_delta_x = if dir.x.abs() < 1e-12 {
            f64::INFINITY
        } else {
            self.cell_m / dir.x.abs()
        };
        let t_delta_y = if dir.y.abs() < 1e-12 {
            f64::INFINITY
        } else {
            self.cell_m / dir.y.abs()
        };
        loop {
            let t_exit = t_max_x.min(t_max_y);
            let best = visit(cy * self.cols + cx);
            if best <= t_exit || t_exit > max_t {
                return;
            }
            if t_max_x < t_max_y {
                let nx = cx as isize + step_x;
                if nx < 0 || nx >= self.cols as isize {
                    return;
                }
                cx = nx as usize;
                t_max_x += t_delta_x;
            } else {
                let ny = cy as isize + step_y;
                if ny < 0 || ny >= self.rows as isize {
                    return;
                }
                cy = ny as usize;
                t_max_y += t_delta_y;
            }
        }
    }

    fn origin_axis(&self, axis_origin: f64, cell: usize, step: isize) -> f64 {
        axis_origin + (cell as f64 + if step > 0 { 1.0 } else { 0.0 }) * self.cell_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn ray_hits_segment_at_analytic_distance() {
        let (t, u) = ray_segment(
            &Point2::new(0.0, 0.0),
            &Vector2::new(1.0, 0.0),
            &Point2::new(3.0, -1.0),
            &Point2::new(3.0, 1.0),
        )
        .unwrap();
        assert_relative_eq!(t, 3.0);
        assert_relative_eq!(u, 0.5);
        assert!(
            ray_segment(
                &Point2::new(0.0, 0.0),
                &Vector2::new(-1.0, 0.0),
                &Point2::new(3.0, -1.0),
                &Point2::new(3.0, 1.0)
            )
            .is_none()
        );
    }

    #[test]
    fn polygon_tests() {
        let sq = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(1.0, 1.0),
            Point2::new(0.0, 1.0),
        ];
        assert!(point_in_polygon(&Point2::new(0.5, 0.5), &sq));
        assert!(!point_in_polygon(&Point2::new(1.5, 0.5), &sq));
        assert!(segment_hits_polygon(
            &Point2::new(0.2, 0.2),
            &Point2::new(0.3, 0.3),
            &sq
        ));
        assert!(segment_hits_polygon(
            &Point2::new(-1.0, 0.5),
            &Point2::new(2.0, 0.5),
            &sq
        ));
        assert!(!segment_hits_polygon(
            &Point2::new(-1.0, 2.0),
            &Point2::new(2.0, 2.0),
            &sq
        ));
    }

    #[test]
    fn grid_walk_visits_cells_in_order_and_finds_far_segment() {
        let mut g = Grid::new(Point2::new(0.0, 0.0), Point2::new(10.0, 10.0), 1.0);
        g.insert(7, &Point2::new(8.5, 0.0), &Point2::new(8.5, 10.0));
        let mut seen = Vec::new();
        g.walk_ray(
            &Point2::new(0.5, 5.5),
            &Vector2::new(1.0, 0.0),
            20.0,
            |cell| {
                let ids = g.cell(cell);
                seen.extend_from_slice(ids);
                if ids.is_empty() { f64::INFINITY } else { 8.0 }
            },
        );
        assert_eq!(seen, vec![7]);
    }
}
