//! Range sensors as the matcher sees them: each reading becomes a point in the chair's base
//! frame with a standard deviation.

use nalgebra::{Point2, Vector2};

use iw_vo::Pose2;

/// A planar laser scanner on the base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserGeometry {
    /// Scanner pose in the base frame.
    pub t_base_laser: Pose2,
    /// Field of view, rad; beams spread evenly from -fov/2 to +fov/2.
    pub fov_rad: f64,
    /// Maximum range, m: a beam at (or past) it hit nothing.
    pub max_range_m: f64,
    /// Range noise the matcher assumes per beam, m.
    pub sigma_m: f64,
}

/// The sonar ring: one pose per transducer (acoustic axis along its x).
#[derive(Debug, Clone, PartialEq)]
pub struct SonarGeometry {
    /// Transducer poses in the base frame.
    pub t_base_sonar: Vec<Pose2>,
    /// Maximum range, m.
    pub max_range_m: f64,
    /// Range noise the matcher assumes, m: large, since the echo may come from anywhere in
    /// the cone, not only along the axis.
    pub sigma_m: f64,
}

/// One scan endpoint in the base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanPoint {
    /// Endpoint, base frame, m.
    pub p_base: Point2<f64>,
    /// Its range's standard deviation, m.
    pub sigma_m: f64,
    /// Unit direction of the beam that measured it, base frame: a range error moves the point
    /// along it, so it reaches a wall's normal by the cosine of the incidence. Zero where the
    /// error has no one direction (a sonar's echo may come from anywhere in its cone).
    pub beam_base: Vector2<f64>,
}

/// What became of one sensor's readings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ReadingCount {
    /// Readings received.
    pub total: usize,
    /// Readings that hit something and were kept.
    pub kept: usize,
    /// Readings that were not a number, negative or past the maximum (garbage).
    pub invalid: usize,
}

fn endpoint(mount: &Pose2, range_m: f64) -> Point2<f64> {
    let (s, c) = mount.theta.sin_cos();
    Point2::new(mount.x + c * range_m, mount.y + s * range_m)
}

/// A reading is kept when it is finite, above 5 cm and below the maximum (an echo).
fn classify(range_m: f64, max_range_m: f64) -> Option<bool> {
    if !range_m.is_finite() || range_m < 0.0 || range_m > max_range_m * 1.001 {
        None
    } else {
        Some(range_m > 0.05 && range_m < max_range_m * 0.999)
    }
}

impl LaserGeometry {
    /// Appends the endpoints of `ranges_m` (beam `k` of `n` at `-fov/2 + fov * k / (n - 1)`).
    pub fn points(&self, ranges_m: &[f64], out: &mut Vec<ScanPoint>) -> ReadingCount {
        let n = ranges_m.len();
        let mut count = ReadingCount {
            total: n,
            ..ReadingCount::default()
        };
        for (k, &range_m) in ranges_m.iter().enumerate() {
            match classify(range_m, self.max_range_m) {
                None => count.invalid += 1,
                Some(false) => {}
                Some(true) => {
                    let angle = if n > 1 {
                        -self.fov_rad / 2.0 + self.fov_rad * k as f64 / (n - 1) as f64
                    } else {
                        0.0
                    };
                    let beam = Pose2::new(self.t_base_laser.x, self.t_base_laser.y, 0.0)
                        .compose(&Pose2::new(0.0, 0.0, self.t_base_laser.theta + angle));
                    out.push(ScanPoint {
                        p_base: endpoint(&beam, range_m),
                        sigma_m: self.sigma_m,
                        beam_base: Vector2::new(beam.theta.cos(), beam.theta.sin()),
                    });
                    count.kept += 1;
                }
            }
        }
        count
    }
}

impl SonarGeometry {
    /// Appends the endpoints of `ranges_m` (one per transducer, `None`: no echo).
    pub fn points(&self, ranges_m: &[Option<f64>], out: &mut Vec<ScanPoint>) -> ReadingCount {
        let mut count = ReadingCount {
            total: ranges_m.len(),
            ..ReadingCount::default()
        };
        for (mount, range) in self.t_base_sonar.iter().zip(ranges_m) {
            let Some(range_m) = *range else { continue };
            match classify(range_m, self.max_range_m) {
                None => count.invalid += 1,
                Some(false) => {}
                Some(true) => {
                    out.push(ScanPoint {
                        p_base: endpoint(mount, range_m),
                        sigma_m: self.sigma_m,
                        beam_base: Vector2::zeros(),
                    });
                    count.kept += 1;
                }
            }
        }
        count.invalid += ranges_m.len().saturating_sub(self.t_base_sonar.len());
        count
    }
}

/// `p_base` seen from the map for a base at `pose`.
pub(crate) fn to_map(pose: &Pose2, p_base: &Point2<f64>) -> Point2<f64> {
    let (s, c) = pose.theta.sin_cos();
    Point2::new(
        pose.x + c * p_base.x - s * p_base.y,
        pose.y + s * p_base.x + c * p_base.y,
    )
}

/// d(map point)/d(theta) for a base at heading `theta`.
pub(crate) fn d_dtheta(theta: f64, p_base: &Point2<f64>) -> Vector2<f64> {
    let (s, c) = theta.sin_cos();
    Vector2::new(-s * p_base.x - c * p_base.y, c * p_base.x - s * p_base.y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn garbage_and_no_echo_are_told_apart() {
        let laser = LaserGeometry {
            t_base_laser: Pose2::new(0.5, 0.0, 0.0),
            fov_rad: std::f64::consts::PI,
            max_range_m: 10.0,
            sigma_m: 0.01,
        };
        let mut out = Vec::new();
        let c = laser.points(&[1.0, f64::NAN, 10.0, -3.0, 2.0], &mut out);
        assert_eq!((c.total, c.kept, c.invalid), (5, 2, 2));
        // beam 0 looks right (-90 deg), beam 4 left
        assert!((out[0].p_base - Point2::new(0.5, -1.0)).norm() < 1e-12);
        assert!((out[1].p_base - Point2::new(0.5, 2.0)).norm() < 1e-12);
    }
}
