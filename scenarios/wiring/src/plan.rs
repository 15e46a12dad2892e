//! The map as an occupancy grid for the cognitive layer's A* (and for finding its rooms).

use iw_cognitive::OccupancyGrid;
use iw_sim::Map;
use nalgebra::Point2;

use crate::WiringError;

/// Grid resolution, m.
pub const RESOLUTION_M: f64 = 0.1;

/// Rasterises walls, furniture and the doors that are closed (`closed(door id)`), not inflated.
pub fn raster(map: &Map, closed: impl Fn(&str) -> bool) -> Result<OccupancyGrid, WiringError> {
    let (lo, hi) = map.bounds();
    let origin = Point2::new(lo.x - RESOLUTION_M, lo.y - RESOLUTION_M);
    let width = ((hi.x - origin.x) / RESOLUTION_M).ceil() as usize + 2;
    let height = ((hi.y - origin.y) / RESOLUTION_M).ceil() as usize + 2;
    let mut occupied = vec![false; width.saturating_mul(height)];
    let mut mark = |p: Point2<f64>| {
        let col = ((p.x - origin.x) / RESOLUTION_M).floor();
        let row = ((p.y - origin.y) / RESOLUTION_M).floor();
        if col >= 0.0 && row >= 0.0 && (col as usize) < width && (row as usize) < height {
            occupied[row as usize * width + col as usize] = true;
        }
    };
    let mut segment = |a: Point2<f64>, b: Point2<f64>| {
        let steps = ((b - a).norm() / (RESOLUTION_M / 2.0)).ceil().max(1.0) as usize;
        for i in 0..=steps {
            mark(a + (b - a) * (i as f64 / steps as f64));
        }
    };
    for wall in &map.walls {
        for pair in wall.windows(2) {
            segment(pair[0], pair[1]);
        }
    }
    for item in &map.furniture {
        let n = item.polygon.len();
        for i in 0..n {
            segment(item.polygon[i], item.polygon[(i + 1) % n]);
        }
    }
    for door in map.doors.iter().filter(|d| closed(&d.id)) {
        segment(door.a, door.b);
    }
    Ok(OccupancyGrid::new(
        width,
        height,
        RESOLUTION_M,
        origin,
        occupied,
    )?)
}
