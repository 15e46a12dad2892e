//! Synthetic rooms and a ray-cast laser, shared by the tests and the bench.
#![allow(dead_code)] // each test target uses a subset

use iw_localization::{LaserGeometry, ScanPoint};
use iw_vo::Pose2;
use nalgebra::{Point2, Vector2};

pub type Seg = (Point2<f64>, Point2<f64>);

pub fn p(x: f64, y: f64) -> Point2<f64> {
    Point2::new(x, y)
}

pub fn polygon(points: &[(f64, f64)]) -> Vec<Seg> {
    (0..points.len())
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % points.len()]);
            (p(a.0, a.1), p(b.0, b.1))
        })
        .collect()
}

/// An L-shaped room with a cupboard and a pillar: no symmetry.
pub fn room() -> Vec<Seg> {
    let mut s = polygon(&[
        (0.0, 0.0),
        (10.0, 0.0),
        (10.0, 4.0),
        (4.0, 4.0),
        (4.0, 8.0),
        (0.0, 8.0),
    ]);
    s.extend(polygon(&[(7.0, 0.0), (8.0, 0.0), (8.0, 0.6), (7.0, 0.6)]));
    s.extend(polygon(&[(1.5, 5.5), (1.9, 5.5), (1.9, 5.9), (1.5, 5.9)]));
    s
}

pub fn laser() -> LaserGeometry {
    LaserGeometry {
        t_base_laser: Pose2::new(0.3, 0.0, 0.0),
        fov_rad: 270f64.to_radians(),
        max_range_m: 10.0,
        sigma_m: 0.02,
    }
}

/// Ranges of a 271-beam laser at `pose` against `world`, with deterministic pseudo-noise.
pub fn scan(world: &[Seg], pose: &Pose2, noise_m: f64, salt: u64) -> Vec<f64> {
    let l = laser();
    let origin = pose.compose(&l.t_base_laser);
    (0..271)
        .map(|k| {
            let a = origin.theta - l.fov_rad / 2.0 + l.fov_rad * k as f64 / 270.0;
            let dir = Vector2::new(a.cos(), a.sin());
            let o = p(origin.x, origin.y);
            let hit = world
                .iter()
                .filter_map(|(s0, s1)| {
                    let e = s1 - s0;
                    let denom = dir.x * e.y - dir.y * e.x;
                    if denom.abs() < 1e-12 {
                        return None;
                    }
                    let w = s0 - o;
                    let t = (w.x * e.y - w.y * e.x) / denom;
                    let u = (w.x * dir.y - w.y * dir.x) / denom;
                    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
                })
                .fold(l.max_range_m, f64::min);
            let h = (k as u64 + salt).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
            let u = h as f64 / (1u64 << 53) as f64 - 0.5;
            (hit + u * noise_m * 3.4).min(l.max_range_m)
        })
        .collect()
}

pub fn points(ranges: &[f64]) -> Vec<ScanPoint> {
    let mut out = Vec::new();
    laser().points(ranges, &mut out);
    out
}
