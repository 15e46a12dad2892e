//! The prototype's sonars as the simulator reads them, for the echo memory's unit tests (which
//! include this file by path) and its bench.

use iw_body::layout::Footprint;
use nalgebra::{Isometry2, Point2};

/// What the 16 sonars of `Footprint::PROTOTYPE` read at `pose` (odometry frame) among obstacle
/// points `world`: the nearest point inside each continuous 45 degree cone, 5 cm to 3 m.
pub fn sonars(pose: &Isometry2<f64>, world: &[Point2<f64>]) -> Vec<Option<f64>> {
    let half = 22.5f64.to_radians();
    Footprint::PROTOTYPE
        .sonar_mounts()
        .iter()
        .map(|mount| {
            let inv = (pose * mount).inverse();
            world
                .iter()
                .map(|p| inv * p)
                .filter(|q| q.y.atan2(q.x).abs() <= half)
                .map(|q| q.coords.norm().max(0.05))
                .filter(|&r| r <= 3.0)
                .min_by(f64::total_cmp)
        })
        .collect()
}
