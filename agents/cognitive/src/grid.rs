//! [`OccupancyGrid`] and A* between points of the world frame.
//!
//! Cells are square, `resolution_m` wide; cell `(0, 0)` has its lower-left corner at `origin`.
//! Paths are 8-connected; a diagonal step may not cut the corner of an occupied cell. The
//! heuristic (octile distance) is admissible and consistent, so the path is the cheapest.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use nalgebra::Point2;

/// Why a path could not be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GridError {
    /// A grid whose cell count does not match its size.
    #[error("grid of {width}x{height} cells needs {expected} occupancy values, got {got}")]
    BadSize {
        /// Width, cells.
        width: usize,
        /// Height, cells.
        height: usize,
        /// Cells expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// The resolution is not a positive finite length.
    #[error("cell size must be positive and finite, got {resolution_m} m")]
    BadResolution {
        /// Given cell size, m.
        resolution_m: f64,
    },
    /// Start or goal lies outside the grid or in an occupied cell.
    #[error("the {which} ({x:.2}, {y:.2}) m is {why}")]
    BadEndpoint {
        /// `start` or `goal`.
        which: &'static str,
        /// World x, m.
        x: f64,
        /// World y, m.
        y: f64,
        /// `outside the map` or `inside an obstacle`.
        why: &'static str,
    },
    /// No free path joins start and goal.
    #[error("no free path from start to goal")]
    NoPath,
}

/// A boolean occupancy grid in the world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct OccupancyGrid {
    width: usize,
    height: usize,
    resolution_m: f64,
    origin: Point2<f64>,
    occupied: Vec<bool>,
    /// Clearance below which a cell costs more to cross, cells (0: plain shortest paths).
    comfort_cells: f64,
}

/// How much more a step costs right next to an obstacle than at the comfort distance.
const CLOSE_COST: f64 = 3.0;

/// A planned path: waypoints in the world frame, first the start, last the goal.
#[derive(Debug, Clone, PartialEq)]
pub struct Path2 {
    /// Waypoints, m.
    pub waypoints: Vec<Point2<f64>>,
    /// Length along the cell centres, m.
    pub length_m: f64,
}

impl OccupancyGrid {
    /// A grid of `width` x `height` cells, row-major from the bottom row.
    pub fn new(
        width: usize,
        height: usize,
        resolution_m: f64,
        origin: Point2<f64>,
        occupied: Vec<bool>,
    ) -> Result<Self, GridError> {
        if !(resolution_m.is_finite() && resolution_m > 0.0) {
            return Err(GridError::BadResolution { resolution_m });
        }
        let expected = width.saturating_mul(height);
        if occupied.len() != expected {
            return Err(GridError::BadSize {
                width,
                height,
                expected,
                got: occupied.len(),
            });
        }
        Ok(OccupancyGrid {
            width,
            height,
            resolution_m,
            origin,
            occupied,
            comfort_cells: 0.0,
        })
    }

    /// The same grid planning paths that keep away from obstacles: a step closer than
    /// `comfort_m` to an occupied cell costs up to `CLOSE_COST` (3) times more (linearly), and a
    /// straight leg of the pruned path may not cost more than the cells it replaces. Paths
    /// then run down the middle of corridors and round corners with room for a chair's front.
    pub fn with_comfort(mut self, comfort_m: f64) -> Self {
        self.comfort_cells = if comfort_m.is_finite() {
            (comfort_m / self.resolution_m).max(0.0)
        } else {
            0.0
        };
        self
    }

    /// Width and height, cells.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Whether cell `(col, row)` is occupied; outside the grid counts as occupied.
    pub fn is_occupied(&self, col: i64, row: i64) -> bool {
        self.index(col, row).is_none_or(|i| self.occupied[i])
    }

    fn index(&self, col: i64, row: i64) -> Option<usize> {
        (col >= 0 && row >= 0 && (col as usize) < self.width && (row as usize) < self.height)
            .then(|| row as usize * self.width + col as usize)
    }

    /// The cell holding world point `p`, if inside the grid.
    pub fn cell_of(&self, p: &Point2<f64>) -> Option<(i64, i64)> {
        let c = ((p.x - self.origin.x) / self.resolution_m).floor();
        let r = ((p.y - self.origin.y) / self.resolution_m).floor();
        let (c, r) = (c as i64, r as i64);
        self.index(c, r).map(|_| (c, r))
    }

    /// World position of the centre of a cell.
    pub fn centre(&self, col: i64, row: i64) -> Point2<f64> {
        self.origin + nalgebra::Vector2::new(col as f64 + 0.5, row as f64 + 0.5) * self.resolution_m
    }

    /// A copy with every cell within `radius_m` of an occupied cell occupied: planning the
    /// chair's centre on it keeps its footprint clear of obstacles.
    pub fn inflated(&self, radius_m: f64) -> OccupancyGrid {
        let r = (radius_m / self.resolution_m).ceil().max(0.0) as i64;
        let mut out = self.clone();
        for row in 0..self.height as i64 {
            for col in 0..self.width as i64 {
                if !self.is_occupied(col, row) {
                    continue;
                }
                for dr in -r..=r {
                    for dc in -r..=r {
                        if dr * dr + dc * dc <= r * r
                            && let Some(i) = out.index(col + dc, row + dr)
                        {
                            out.occupied[i] = true;
                        }
                    }
                }
            }
        }
        out
    }

    /// The cheapest 8-connected path from `start` to `goal`, then pruned to the waypoints where
    /// it turns (each straight leg stays in free cells).
    pub fn astar(&self, start: Point2<f64>, goal: Point2<f64>) -> Result<Path2, GridError> {
        let endpoint = |which, p: Point2<f64>| -> Result<(i64, i64), GridError> {
            let cell = self.cell_of(&p).ok_or(GridError::BadEndpoint {
                which,
                x: p.x,
                y: p.y,
                why: "outside the map",
            })?;
            if self.is_occupied(cell.0, cell.1) {
                return Err(GridError::BadEndpoint {
                    which,
                    x: p.x,
                    y: p.y,
                    why: "inside an obstacle",
                });
            }
            Ok(cell)
        };
        let s = endpoint("start", start)?;
        let g = endpoint("goal", goal)?;
        let clearance = self.clearance();
        let cells = self
            .astar_cells(s, g, clearance.as_deref())
            .ok_or(GridError::NoPath)?;
        let length_m = cells
            .windows(2)
            .map(|w| cell_distance(w[0], w[1]))
            .sum::<f64>()
            * self.resolution_m;
        let weight = |c: (i64, i64)| match (&clearance, self.index(c.0, c.1)) {
            (Some(d), Some(i)) => self.weight(d[i]),
            _ => 1.0,
        };
        let mut cost_to = vec![0.0; cells.len()];
        for i in 1..cells.len() {
            cost_to[i] = cost_to[i - 1] + cell_distance(cells[i - 1], cells[i]) * weight(cells[i]);
        }
        // A shortcut may not cost more than the cells it replaces (so it keeps their clearance).
        let shortcut_cost = |a: (i64, i64), b: (i64, i64)| {
            let samples: Vec<f64> = self.cells_on(a, b).map(weight).collect();
            cell_distance(a, b) * samples.iter().sum::<f64>() / samples.len().max(1) as f64
        };
        let mut waypoints = vec![start];
        let mut anchor = 0;
        for i in 1..cells.len() {
            let keeps_clear = clearance.is_none()
                || shortcut_cost(cells[anchor], cells[i]) <= cost_to[i] - cost_to[anchor] + 1e-9;
            if !(keeps_clear && self.line_of_sight(cells[anchor], cells[i])) {
                waypoints.push(self.centre(cells[i - 1].0, cells[i - 1].1));
                anchor = i - 1;
            }
        }
        waypoints.push(goal);
        Ok(Path2 {
            waypoints,
            length_m,
        })
    }

    /// What a unit of length costs in a cell `clearance` cells from the nearest obstacle (1 at
    /// the comfort distance and beyond).
    fn weight(&self, clearance: f64) -> f64 {
        1.0 + CLOSE_COST * (1.0 - clearance / self.comfort_cells).max(0.0)
    }

    /// Distance of every cell to the nearest occupied cell (outside the grid counts as
    /// occupied), cells, by a two-pass chamfer transform; `None` for plain shortest paths.
    fn clearance(&self) -> Option<Vec<f64>> {
        if self.comfort_cells <= 0.0 {
            return None;
        }
        let (w, h) = (self.width as i64, self.height as i64);
        let mut d: Vec<f64> = self
            .occupied
            .iter()
            .map(|&o| if o { 0.0 } else { f64::INFINITY })
            .collect();
        let diagonal = std::f64::consts::SQRT_2;
        let relax = |d: &mut Vec<f64>, c: i64, r: i64, neighbours: &[(i64, i64, f64)]| {
            let i = (r * w + c) as usize;
            for &(dc, dr, step) in neighbours {
                let (nc, nr) = (c + dc, r + dr);
                let from = if nc < 0 || nr < 0 || nc >= w || nr >= h {
                    0.0
                } else {
                    d[(nr * w + nc) as usize]
                };
                d[i] = d[i].min(from + step);
            }
        };
        let before = [
            (-1, 0, 1.0),
            (0, -1, 1.0),
            (-1, -1, diagonal),
            (1, -1, diagonal),
        ];
        let after = [
            (1, 0, 1.0),
            (0, 1, 1.0),
            (1, 1, diagonal),
            (-1, 1, diagonal),
        ];
        for r in 0..h {
            for c in 0..w {
                relax(&mut d, c, r, &before);
            }
        }
        for r in (0..h).rev() {
            for c in (0..w).rev() {
                relax(&mut d, c, r, &after);
            }
        }
        Some(d)
    }

    /// The cells the segment between two cell centres passes (sampled at a quarter cell).
    fn cells_on(&self, a: (i64, i64), b: (i64, i64)) -> impl Iterator<Item = (i64, i64)> {
        let (dx, dy) = ((b.0 - a.0) as f64, (b.1 - a.1) as f64);
        let steps = (dx.abs().max(dy.abs()) * 4.0).ceil().max(1.0) as i64;
        (0..=steps).map(move |k| {
            let t = k as f64 / steps as f64;
            (
                (a.0 as f64 + 0.5 + t * dx).floor() as i64,
                (a.1 as f64 + 0.5 + t * dy).floor() as i64,
            )
        })
    }

    fn astar_cells(
        &self,
        s: (i64, i64),
        g: (i64, i64),
        clearance: Option<&[f64]>,
    ) -> Option<Vec<(i64, i64)>> {
        #[derive(PartialEq)]
        struct Open(f64, usize);
        impl Eq for Open {}
        impl Ord for Open {
            fn cmp(&self, other: &Self) -> Ordering {
                other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
            }
        }
        impl PartialOrd for Open {
            fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
                Some(self.cmp(other))
            }
        }
        let h = |(c, r): (i64, i64)| {
            let (dx, dy) = ((c - g.0).abs() as f64, (r - g.1).abs() as f64);
            dx.max(dy) + (std::f64::consts::SQRT_2 - 1.0) * dx.min(dy)
        };
        let n = self.width * self.height;
        let mut cost = vec![f64::INFINITY; n];
        let mut came = vec![usize::MAX; n];
        let si = self.index(s.0, s.1)?;
        let gi = self.index(g.0, g.1)?;
        cost[si] = 0.0;
        let mut open = BinaryHeap::from([Open(h(s), si)]);
        while let Some(Open(_, i)) = open.pop() {
            if i == gi {
                let mut path = vec![g];
                let mut j = gi;
                while j != si {
                    j = came[j];
                    path.push(((j % self.width) as i64, (j / self.width) as i64));
                }
                path.reverse();
                return Some(path);
            }
            let (c, r) = ((i % self.width) as i64, (i / self.width) as i64);
            for (dc, dr) in [
                (1, 0),
                (-1, 0),
                (0, 1),
                (0, -1),
                (1, 1),
                (1, -1),
                (-1, 1),
                (-1, -1),
            ] {
                let (nc, nr) = (c + dc, r + dr);
                if self.is_occupied(nc, nr)
                    || (dc != 0
                        && dr != 0
                        && (self.is_occupied(c + dc, r) || self.is_occupied(c, r + dr)))
                {
                    continue;
                }
                let Some(j) = self.index(nc, nr) else {
                    continue;
                };
                let step =
                    cell_distance((c, r), (nc, nr)) * clearance.map_or(1.0, |d| self.weight(d[j]));
                let candidate = cost[i] + step;
                if candidate < cost[j] {
                    cost[j] = candidate;
                    came[j] = i;
                    open.push(Open(candidate + h((nc, nr)), j));
                }
            }
        }
        None
    }

    /// Whether the straight segment between two cell centres crosses only free cells (sampled
    /// at a quarter cell, conservative at corners).
    fn line_of_sight(&self, a: (i64, i64), b: (i64, i64)) -> bool {
        let (dx, dy) = ((b.0 - a.0) as f64, (b.1 - a.1) as f64);
        let steps = (dx.abs().max(dy.abs()) * 4.0).ceil().max(1.0) as i64;
        (0..=steps).all(|k| {
            let t = k as f64 / steps as f64;
            let (x, y) = (a.0 as f64 + 0.5 + t * dx, a.1 as f64 + 0.5 + t * dy);
            [(-0.45, -0.45), (0.45, -0.45), (-0.45, 0.45), (0.45, 0.45)]
                .iter()
                .all(|(ox, oy)| !self.is_occupied((x + ox).floor() as i64, (y + oy).floor() as i64))
        })
    }
}

/// Distance between two cell centres, cells.
fn cell_distance(a: (i64, i64), b: (i64, i64)) -> f64 {
    (((b.0 - a.0).pow(2) + (b.1 - a.1).pow(2)) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn grid(rows: &[&str]) -> OccupancyGrid {
        let height = rows.len();
        let width = rows[0].len();
        let occupied = rows
            .iter()
            .rev()
            .flat_map(|r| r.chars().map(|c| c == '#'))
            .collect();
        OccupancyGrid::new(width, height, 0.5, Point2::origin(), occupied).unwrap()
    }

    #[test]
    fn path_goes_round_the_wall_and_is_shortest() {
        let g = grid(&[
            "..........",
            "....#.....",
            "....#.....",
            "....#.....",
            "..........",
        ]);
        let start = g.centre(1, 2);
        let goal = g.centre(8, 2);
        let path = g.astar(start, goal).unwrap();
        // Over the 3-cell wall without cutting its corners: 4 diagonals and 3 straight steps.
        let expected = (4.0 * 2f64.sqrt() + 3.0) * 0.5;
        assert!(
            (path.length_m - expected).abs() < 1e-9,
            "{} != {expected}",
            path.length_m
        );
        assert!(
            path.waypoints.len() >= 3,
            "must turn to get round: {:?}",
            path.waypoints
        );
        for w in path.waypoints.windows(2) {
            let (a, b) = (g.cell_of(&w[0]).unwrap(), g.cell_of(&w[1]).unwrap());
            assert!(g.line_of_sight(a, b), "leg {a:?}->{b:?} crosses the wall");
        }
    }

    #[test]
    fn comfort_keeps_the_path_in_the_middle_of_a_corridor() {
        let wall = "####################";
        let free = "....................";
        let g = grid(&[wall, free, free, free, free, free, wall]);
        let (start, goal) = (g.centre(1, 1), g.centre(18, 1));
        // Shortest: straight along the wall.
        assert_eq!(g.astar(start, goal).unwrap().waypoints, vec![start, goal]);
        // With comfort: over to the middle row (y = 3.5 cells) and back, never nearer the walls
        // than the start and goal rows.
        let path = g.clone().with_comfort(1.5).astar(start, goal).unwrap();
        let inner = &path.waypoints[1..path.waypoints.len() - 1];
        assert!(
            inner.iter().any(|p| (p.y - 1.75).abs() < 1e-9),
            "{:?}",
            path.waypoints
        );
        assert!(
            path.waypoints
                .iter()
                .all(|p| p.y >= 0.75 - 1e-9 && p.y <= 2.75 + 1e-9),
            "{:?}",
            path.waypoints
        );
    }

    #[test]
    fn endpoints_and_dead_ends_are_reported() {
        let g = grid(&["..#..", "..#..", "..#.."]);
        assert_eq!(
            g.astar(g.centre(0, 0), g.centre(4, 0)),
            Err(GridError::NoPath)
        );
        assert!(matches!(
            g.astar(g.centre(2, 0), g.centre(4, 0)),
            Err(GridError::BadEndpoint { which: "start", .. })
        ));
        assert!(matches!(
            g.astar(g.centre(0, 0), Point2::new(99.0, 0.0)),
            Err(GridError::BadEndpoint {
                which: "goal",
                why: "outside the map",
                ..
            })
        ));
        assert!(matches!(
            OccupancyGrid::new(2, 2, 0.5, Point2::origin(), vec![false; 3]),
            Err(GridError::BadSize { .. })
        ));
    }

    #[test]
    fn inflation_closes_gaps_narrower_than_the_chair() {
        let g = grid(&["..#..", ".....", "..#.."]);
        assert!(g.astar(g.centre(0, 1), g.centre(4, 1)).is_ok());
        let fat = g.inflated(0.5);
        assert!(fat.is_occupied(2, 1));
    }

    proptest! {
        /// On random maps A* agrees with breadth-first reachability and never enters an obstacle.
        #[test]
        fn astar_is_sound_and_complete(cells in prop::collection::vec(prop::bool::weighted(0.3), 64)) {
            let mut cells = cells;
            cells[0] = false;
            cells[63] = false;
            let g = OccupancyGrid::new(8, 8, 1.0, Point2::origin(), cells).unwrap();
            // Reachability by flood fill with the same moves.
            let mut seen = [false; 64];
            let mut stack = vec![(0i64, 0i64)];
            seen[0] = true;
            while let Some((c, r)) = stack.pop() {
                for (dc, dr) in [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)] {
                    let (nc, nr) = (c + dc, r + dr);
                    if g.is_occupied(nc, nr) || (dc != 0 && dr != 0 && (g.is_occupied(c + dc, r) || g.is_occupied(c, r + dr))) { continue; }
                    let i = (nr * 8 + nc) as usize;
                    if !seen[i] { seen[i] = true; stack.push((nc, nr)); }
                }
            }
            match g.astar_cells((0, 0), (7, 7), None) {
                Some(path) => {
                    prop_assert!(seen[63]);
                    prop_assert!(path.iter().all(|&(c, r)| !g.is_occupied(c, r)));
                }
                None => prop_assert!(!seen[63]),
            }
        }
    }
}
