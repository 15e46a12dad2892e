//! Walls as a dense sensor sees them, for the docking module's unit tests (which include this
//! file by path) and the recovery rig test.

use nalgebra::Point2;

/// Points every 2 cm from `a` to `b`.
pub fn segment(a: (f64, f64), b: (f64, f64)) -> Vec<Point2<f64>> {
    let n = (((b.0 - a.0).hypot(b.1 - a.1)) / 0.02).ceil() as usize;
    (0..=n)
        .map(|k| {
            let t = k as f64 / n as f64;
            Point2::new(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
        })
        .collect()
}
