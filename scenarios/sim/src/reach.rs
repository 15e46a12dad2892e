//! Whether a point is in the map's free space: not inside furniture or on a wall, and joined to
//! the map's places (not in a wall's hollow, nor outside the building's outer wall). A chair's
//! footprint check alone passes both: a chair can fit inside a big table's outline or a hollow.

use std::collections::VecDeque;
use std::fmt;

use nalgebra::{Point2, Vector2};

use crate::geom::point_in_polygon;
use crate::map::Map;

/// Finest cell of the raster, m: well under a wall's thickness and a doorway's width.
const CELL_M: f64 = 0.05;
/// Most cells of the raster; a larger map gets coarser cells (a 10 km map still fits).
const MAX_CELLS: f64 = 4e6;

/// Why a point is not in a map's free space ([`Map::free_space_at`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NotFree {
    /// On a wall or inside furniture.
    Occupied,
    /// In a region of free space that no place, named start or route point of the map is in:
    /// enclosed by walls, or outside the building.
    Unconnected,
}

impl fmt::Display for NotFree {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NotFree::Occupied => "on a wall or inside furniture of the map",
            NotFree::Unconnected => {
                "in free space walled off from every place, start and route of the map (inside \
                 a wall's hollow or outside the building)"
            }
        })
    }
}

/// The map's walls and furniture rasterised; doors are left open (a door agent opens them).
struct Raster {
    origin: Point2<f64>,
    cell_m: f64,
    cols: usize,
    rows: usize,
    blocked: Vec<bool>,
}

impl Raster {
    fn new(map: &Map) -> Self {
        let (min, max) = map.bounds();
        let extent = max - min;
        let cell_m = CELL_M.max((extent.x * extent.y / MAX_CELLS).sqrt());
        // two free cells round the bounds, so the outside is one region
        let origin = min - Vector2::repeat(2.0 * cell_m);
        let cols = (extent.x / cell_m).ceil() as usize + 4;
        let rows = (extent.y / cell_m).ceil() as usize + 4;
        let mut raster = Raster {
            origin,
            cell_m,
            cols,
            rows,
            blocked: vec![false; cols * rows],
        };
        for wall in &map.walls {
            for pair in wall.windows(2) {
                raster.block_segment(&pair[0], &pair[1]);
            }
        }
        for furniture in &map.furniture {
            let poly = &furniture.polygon;
            for i in 0..poly.len() {
                raster.block_segment(&poly[i], &poly[(i + 1) % poly.len()]);
            }
            raster.block_inside(poly);
        }
        raster
    }

    fn cell_of(&self, p: &Point2<f64>) -> Option<usize> {
        let c = ((p.x - self.origin.x) / self.cell_m).floor();
        let r = ((p.y - self.origin.y) / self.cell_m).floor();
        (c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows)
            .then(|| r as usize * self.cols + c as usize)
    }

    /// Blocks every cell the segment passes: samples a quarter cell apart land in the same or
    /// a neighbouring cell, so the blocked cells join up and a 4-connected fill cannot slip
    /// between them.
    fn block_segment(&mut self, a: &Point2<f64>, b: &Point2<f64>) {
        let steps = ((b - a).norm() / (self.cell_m * 0.25)).ceil() as usize;
        for k in 0..=steps {
            let t = if steps == 0 {
                0.0
            } else {
                k as f64 / steps as f64
            };
            if let Some(i) = self.cell_of(&(a + (b - a) * t)) {
                self.blocked[i] = true;
            }
        }
    }

    /// Blocks the cells whose centre is inside `poly`.
    fn block_inside(&mut self, poly: &[Point2<f64>]) {
        let (Some(lo), Some(hi)) = (
            poly.iter().copied().reduce(|a, b| a.inf(&b)),
            poly.iter().copied().reduce(|a, b| a.sup(&b)),
        ) else {
            return;
        };
        let (Some(first), Some(last)) = (self.cell_of(&lo), self.cell_of(&hi)) else {
            return;
        };
        for r in first / self.cols..=last / self.cols {
            for c in first % self.cols..=last % self.cols {
                let centre =
                    self.origin + Vector2::new(c as f64 + 0.5, r as f64 + 0.5) * self.cell_m;
                if point_in_polygon(&centre, poly) {
                    self.blocked[r * self.cols + c] = true;
                }
            }
        }
    }

    /// Whether a 4-connected fill of free cells from `from` reaches one of `targets`.
    fn joins(&self, from: usize, targets: &[usize]) -> bool {
        let mut wanted = vec![false; self.blocked.len()];
        for &t in targets {
            wanted[t] = true;
        }
        let mut seen = vec![false; self.blocked.len()];
        let mut queue = VecDeque::from([from]);
        seen[from] = true;
        while let Some(i) = queue.pop_front() {
            if wanted[i] {
                return true;
            }
            let (r, c) = (i / self.cols, i % self.cols);
            let neighbours = [
                (c > 0).then(|| i - 1),
                (c + 1 < self.cols).then(|| i + 1),
                (r > 0).then(|| i - self.cols),
                (r + 1 < self.rows).then(|| i + self.cols),
            ];
            for n in neighbours.into_iter().flatten() {
                if !seen[n] && !self.blocked[n] {
                    seen[n] = true;
                    queue.push_back(n);
                }
            }
        }
        false
    }
}

impl Map {
    /// Whether `p` is in the map's free space: not on a wall or inside furniture, and in the
    /// same region of free space as one of the map's places, named starts or route points
    /// (doors count as open). A map with none of those is only checked for the first.
    /// Resolution 5 cm (coarser on maps over 100 m across): a gap narrower than a cell may
    /// count as closed.
    pub fn free_space_at(&self, p: &Point2<f64>) -> Result<(), NotFree> {
        let raster = Raster::new(self);
        let Some(from) = raster.cell_of(p).filter(|&i| !raster.blocked[i]) else {
            // outside the raster is outside the bounds: nothing of the map is there
            return Err(match raster.cell_of(p) {
                Some(_) => NotFree::Occupied,
                None => NotFree::Unconnected,
            });
        };
        let anchors: Vec<usize> = self
            .places
            .iter()
            .map(|place| place.position)
            .chain(
                self.starts
                    .iter()
                    .map(|s| Point2::from(s.t_world_body.translation.vector)),
            )
            .chain(self.routes.iter().flat_map(|r| r.points.iter().copied()))
            .filter_map(|q| raster.cell_of(&q))
            .filter(|&i| !raster.blocked[i])
            .collect();
        if anchors.is_empty() || raster.joins(from, &anchors) {
            Ok(())
        } else {
            Err(NotFree::Unconnected)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = include_str!("../../maps/sample-building.map");

    #[test]
    fn rooms_are_free_walls_furniture_and_walled_off_regions_are_not() {
        let map = Map::parse(SAMPLE, "sample-building.map").unwrap();
        let at = |x, y| map.free_space_at(&Point2::new(x, y));
        // the corridor, a bedroom, the bathroom behind its closed door
        for (x, y) in [(1.0, 6.0), (7.5, 8.5), (10.0, 3.0), (19.9, 11.9)] {
            assert_eq!(at(x, y), Ok(()), "({x}, {y})");
        }
        // on the corridor's wall, inside the dining hall's table
        assert_eq!(at(0.7, 7.0), Err(NotFree::Occupied));
        assert_eq!(at(13.0, 9.5), Err(NotFree::Occupied));
        // a hollow: a room walled in on every side, with nothing of the map in it
        let hollow = format!("{SAMPLE}\nwall closed 6 1 7 1 7 2 6 2\n");
        let map = Map::parse(&hollow, "hollow.map").unwrap();
        assert_eq!(
            map.free_space_at(&Point2::new(6.5, 1.5)),
            Err(NotFree::Unconnected)
        );
        assert_eq!(map.free_space_at(&Point2::new(5.5, 1.5)), Ok(()));
        // outside an L-shaped building, inside its bounds
        let l_shape = "wall closed 0 0 10 0 10 4 4 4 4 10 0 10\nplace inside 1 1\n";
        let map = Map::parse(l_shape, "l.map").unwrap();
        assert_eq!(map.free_space_at(&Point2::new(2.0, 8.0)), Ok(()));
        assert_eq!(
            map.free_space_at(&Point2::new(8.0, 8.0)),
            Err(NotFree::Unconnected)
        );
        // a map without places, starts or routes: only walls and furniture are known
        let bare = "wall closed 0 0 10 0 10 4 4 4 4 10 0 10\n";
        let map = Map::parse(bare, "bare.map").unwrap();
        assert_eq!(map.free_space_at(&Point2::new(8.0, 8.0)), Ok(()));
    }

    #[test]
    fn a_diagonal_wall_seals_as_well_as_a_straight_one() {
        let diamond = "wall closed 5 0 10 5 5 10 0 5\nplace middle 5 5\n";
        let map = Map::parse(diamond, "diamond.map").unwrap();
        assert_eq!(map.free_space_at(&Point2::new(5.0, 8.0)), Ok(()));
        for (x, y) in [(1.0, 1.0), (9.0, 9.0), (1.5, 8.5)] {
            assert_eq!(
                map.free_space_at(&Point2::new(x, y)),
                Err(NotFree::Unconnected),
                "({x}, {y})"
            );
        }
    }
}
