//! The map as an occupancy grid for the cognitive layer's A*, and paths as action sequences.

use iw_cognitive::{OccupancyGrid, Path2};
use iw_ontology::wheelchair::WheelchairAction;
use iw_sim::Map;
use nalgebra::{Point2, Vector2};

use crate::FleetError;

/// Grid resolution, m.
pub const RESOLUTION_M: f64 = 0.1;
/// Clearance kept from walls, furniture and closed doors, m (the chair's half width plus margin).
pub const CLEARANCE_M: f64 = 0.4;

/// Rasterises walls, furniture and the doors that are closed (`closed(door id)`).
pub fn occupancy(map: &Map, closed: impl Fn(&str) -> bool) -> Result<OccupancyGrid, FleetError> {
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
    let grid = OccupancyGrid::new(width, height, RESOLUTION_M, origin, occupied)
        .map_err(|source| FleetError::Plan { reason: source.to_string() })?;
    Ok(grid.inflated(CLEARANCE_M))
}

/// Keeps the turns of an A* path and a point every `spacing_m`, ending at the goal: the
/// waypoints the control agent drives to one after the other.
pub fn waypoints(path: &Path2, spacing_m: f64) -> Vec<Point2<f64>> {
    let points = &path.waypoints;
    let mut kept: Vec<Point2<f64>> = Vec::new();
    let mut last = points.first().copied();
    for i in 1..points.len() {
        let here = points[i];
        let turn = points.get(i + 1).is_some_and(|next| {
            let d_in: Vector2<f64> = here - points[i - 1];
            let d_out: Vector2<f64> = next - here;
            d_in.normalize().dot(&d_out.normalize()) < 0.99
        });
        let far = last.is_some_and(|l| (here - l).norm() >= spacing_m);
        if turn || far || i + 1 == points.len() {
            kept.push(here);
            last = Some(here);
        }
    }
    kept
}

/// The action sequence that drives along `points`.
pub fn drive_along(points: &[Point2<f64>]) -> WheelchairAction {
    WheelchairAction::Sequence { steps: points.iter().map(|p| WheelchairAction::GotoXy { x_m: p.x, y_m: p.y }).collect() }
}
