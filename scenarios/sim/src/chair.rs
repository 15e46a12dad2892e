//! The wheelchair body model: footprint, drive limits, encoder errors and the sensor layout of
//! thesis figure 3.4.

use iw_body::{SONAR_COUNT, WheelGeometry};
use nalgebra::{Isometry2, Point2, Vector2};

/// One sonar: where it sits on the body and where it looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SonarMount {
    /// Transducer pose in the body frame (x forward, y left), acoustic axis along its x.
    pub t_body_sonar: Isometry2<f64>,
}

/// The sonar model shared by all 16 transducers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SonarModel {
    /// Full cone angle, deg (45 in thesis 3.4).
    pub cone_deg: f64,
    /// Rays cast across the cone; the nearest echo is the reading.
    pub rays: usize,
    /// Closest measurable range, m (nearer objects read as this).
    pub min_range_m: f64,
    /// Farthest echo, m; beyond it the reading is `None`.
    pub max_range_m: f64,
    /// Standard deviation of the range noise, m.
    pub noise_std_m: f64,
}

/// A 2D laser scanner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserModel {
    /// Scanner pose in the body frame; beams are spread symmetrically around its x axis.
    pub t_body_laser: Isometry2<f64>,
    /// Field of view, deg (270 in thesis 3.4).
    pub fov_deg: f64,
    /// Number of beams (first at -fov/2, last at +fov/2).
    pub beams: usize,
    /// Maximum range, m; beams that hit nothing read this.
    pub max_range_m: f64,
    /// Standard deviation of the range noise, m.
    pub noise_std_m: f64,
}

/// The RGB-D camera (Kinect-like, thesis 3.4: 58 x 45 deg, 0.5 - 3.5 m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraModel {
    /// Camera position and heading in the body frame (optical axis along the body-frame x of
    /// this pose, level with the floor).
    pub t_body_camera: Isometry2<f64>,
    /// Lens height above the floor, m.
    pub height_m: f64,
    /// Image width, px.
    pub width_px: u32,
    /// Image height, px.
    pub height_px: u32,
    /// Horizontal field of view, deg.
    pub hfov_deg: f64,
    /// Nearest valid depth, m (nearer reads 0 = invalid, as a Kinect does).
    pub min_depth_m: f64,
    /// Farthest valid depth, m.
    pub max_depth_m: f64,
}

impl CameraModel {
    /// Pinhole intrinsics `(fx, fy, cx, cy)` in px (square pixels).
    pub fn intrinsics(&self) -> (f64, f64, f64, f64) {
        let fx = self.width_px as f64 / 2.0 / (self.hfov_deg.to_radians() / 2.0).tan();
        (
            fx,
            fx,
            self.width_px as f64 / 2.0 - 0.5,
            self.height_px as f64 / 2.0 - 0.5,
        )
    }
}

/// Encoder error model: what makes dead reckoning drift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderModel {
    /// Tyre compression range: each wheel's effective radius is the nominal one times
    /// `1 - c`, `c` drawn once per chair uniformly in this range (load, tyre pressure).
    pub compression: (f64, f64),
    /// Standard deviation of the per-step slip fraction (ground travel lost to slip).
    pub slip_std: f64,
    /// Extra slip per m/s^2 of wheel acceleration (wheels spin when accelerating hard).
    pub slip_per_mps2: f64,
}

/// Everything that defines a chair model.
#[derive(Debug, Clone, PartialEq)]
pub struct ChairSpec {
    /// Footprint reach in front of the drive axle, m.
    pub front_m: f64,
    /// Footprint reach behind the drive axle, m.
    pub rear_m: f64,
    /// Half the footprint width, m.
    pub half_width_m: f64,
    /// Drive geometry (nominal wheel radius, track, ticks per revolution).
    pub geometry: WheelGeometry,
    /// Top wheel speed, m/s.
    pub max_wheel_mps: f64,
    /// Wheel acceleration limit, m/s^2.
    pub max_wheel_accel_mps2: f64,
    /// Encoder errors.
    pub encoder: EncoderModel,
    /// The 16 sonars, S1 first.
    pub sonars: [SonarMount; SONAR_COUNT],
    /// Sonar physics.
    pub sonar: SonarModel,
    /// The laser scanner, if fitted.
    pub laser: Option<LaserModel>,
    /// The RGB-D camera.
    pub camera: CameraModel,
}

impl Default for ChairSpec {
    /// A mid-size rear-wheel-drive powered wheelchair, 0.65 x 1.1 m, with the IntellWheels
    /// sensor bars.
    fn default() -> Self {
        let iw_body::layout::Footprint {
            front_m,
            rear_m,
            half_width_m,
        } = iw_body::layout::Footprint::PROTOTYPE;
        Self {
            front_m,
            rear_m,
            half_width_m,
            geometry: WheelGeometry::default(),
            max_wheel_mps: 1.5,
            max_wheel_accel_mps2: 1.2,
            encoder: EncoderModel {
                compression: (0.005, 0.03),
                slip_std: 0.01,
                slip_per_mps2: 0.02,
            },
            sonars: sonar_layout(front_m, rear_m, half_width_m),
            sonar: SonarModel {
                cone_deg: 45.0,
                rays: 7,
                min_range_m: 0.05,
                max_range_m: 3.0,
                noise_std_m: 0.01,
            },
            laser: Some(LaserModel {
                t_body_laser: Isometry2::new(Vector2::new(front_m - 0.05, half_width_m), 0.0),
                fov_deg: 270.0,
                beams: 271,
                max_range_m: 10.0,
                noise_std_m: 0.01,
            }),
            camera: CameraModel {
                t_body_camera: Isometry2::new(Vector2::new(front_m, 0.0), 0.0),
                height_m: 0.9,
                width_px: 320,
                height_px: 240,
                hfov_deg: 58.0,
                min_depth_m: 0.5,
                max_depth_m: 3.5,
            },
        }
    }
}

/// The sensor-bar layout of thesis figure 3.4 for a footprint (body frame: x forward, y left,
/// origin at the drive axle centre): [`iw_body::layout::Footprint::sonar_mounts`], the layout
/// the control agent uses too.
pub fn sonar_layout(front_m: f64, rear_m: f64, half_width_m: f64) -> [SonarMount; SONAR_COUNT] {
    iw_body::layout::Footprint {
        front_m,
        rear_m,
        half_width_m,
    }
    .sonar_mounts()
    .map(|t_body_sonar| SonarMount { t_body_sonar })
}

impl ChairSpec {
    /// The footprint rectangle as the body crate describes it (what the control agent's guard
    /// and sonar layout take).
    pub fn body_footprint(&self) -> iw_body::layout::Footprint {
        iw_body::layout::Footprint {
            front_m: self.front_m,
            rear_m: self.rear_m,
            half_width_m: self.half_width_m,
        }
    }

    /// Footprint corners in the body frame, counter-clockwise.
    pub fn footprint(&self) -> [Point2<f64>; 4] {
        [
            Point2::new(-self.rear_m, -self.half_width_m),
            Point2::new(self.front_m, -self.half_width_m),
            Point2::new(self.front_m, self.half_width_m),
            Point2::new(-self.rear_m, self.half_width_m),
        ]
    }

    /// Unit ray directions spread evenly across the sonar cone, in the sonar frame.
    pub fn sonar_ray_dirs(&self) -> Vec<Vector2<f64>> {
        let rays = self.sonar.rays.max(1);
        let half_cone = self.sonar.cone_deg.to_radians() / 2.0;
        (0..rays)
            .map(|k| {
                if rays == 1 {
                    0.0
                } else {
                    -half_cone + 2.0 * half_cone * k as f64 / (rays - 1) as f64
                }
            })
            .map(|a| Vector2::new(a.cos(), a.sin()))
            .collect()
    }

    /// Unit beam directions of the laser, first at -fov/2, in the laser frame (empty without
    /// a laser).
    pub fn laser_beam_dirs(&self) -> Vec<Vector2<f64>> {
        let Some(laser) = &self.laser else {
            return Vec::new();
        };
        let n = laser.beams.max(1);
        let fov = laser.fov_deg.to_radians();
        (0..n)
            .map(|k| {
                if n == 1 {
                    0.0
                } else {
                    -fov / 2.0 + fov * k as f64 / (n - 1) as f64
                }
            })
            .map(|a| Vector2::new(a.cos(), a.sin()))
            .collect()
    }

    /// Distance from the body origin to the farthest footprint corner, m.
    pub fn reach_m(&self) -> f64 {
        self.footprint()
            .iter()
            .map(|p| p.coords.norm())
            .fold(0.0, f64::max)
    }

    /// Footprint corners in the world for a body at `t_world_body`.
    pub fn footprint_at(&self, t_world_body: &Isometry2<f64>) -> [Point2<f64>; 4] {
        self.footprint().map(|p| t_world_body * p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lateral_sonars_are_22cm_apart_and_cones_overlap_from_27cm() {
        let spec = ChairSpec::default();
        let s = &spec.sonars;
        for k in 2..5 {
            let d = (s[k].t_body_sonar.translation.vector
                - s[k + 1].t_body_sonar.translation.vector)
                .norm();
            assert!((d - 0.22).abs() < 1e-12);
        }
        let half_cone = (spec.sonar.cone_deg / 2.0).to_radians();
        let overlap_from = 0.22 / (2.0 * half_cone.tan());
        assert!(overlap_from > 0.26 && overlap_from < 0.28, "{overlap_from}");
    }

    /// Whether some sonar's cone (within range) contains body-frame point `p`.
    fn covered(spec: &ChairSpec, p: Point2<f64>) -> bool {
        let half_cone = (spec.sonar.cone_deg / 2.0).to_radians();
        spec.sonars.iter().any(|s| {
            let local = s.t_body_sonar.inverse() * p;
            local.coords.norm() <= spec.sonar.max_range_m
                && local.y.atan2(local.x).abs() <= half_cone + 1e-12
        })
    }

    #[test]
    fn safety_perimeter_sides_from_27cm_everywhere_from_80cm() {
        let spec = ChairSpec::default();
        let (f, r, w) = (spec.front_m, spec.rear_m, spec.half_width_m);
        let lateral: Vec<f64> = [2, 5]
            .iter()
            .map(|&k| spec.sonars[k].t_body_sonar.translation.x)
            .collect();
        // beside the lateral sonars: every point from 27 cm out is seen
        for d in [0.27, 0.4, 0.6, 0.8] {
            for k in 0..=50 {
                let x = lateral[1] + (lateral[0] - lateral[1]) * k as f64 / 50.0;
                assert!(
                    covered(&spec, Point2::new(x, -w - d)) && covered(&spec, Point2::new(x, w + d)),
                    "side x {x} d {d}"
                );
            }
        }
        // all four sides: every point 80 cm out is seen (the corner arcs between a tip pair and the
        // lateral row keep small gaps with a 1.1 m footprint and a 0.66 m lateral row)
        let d = 0.8;
        let mut ring = Vec::new();
        for k in 0..=100 {
            let t = k as f64 / 100.0;
            let (x, y) = (-r + (f + r) * t, -w + 2.0 * w * t);
            ring.extend([
                Point2::new(f + d, y),
                Point2::new(-r - d, y),
                Point2::new(x, w + d),
                Point2::new(x, -w - d),
            ]);
        }
        for p in ring {
            assert!(
                covered(&spec, p),
                "point {p:?} 80 cm out is in no sonar cone"
            );
        }
    }

    #[test]
    fn front_and_rear_pairs_differ_by_45_degrees() {
        let s = ChairSpec::default().sonars;
        for (a, b) in [(0, 1), (6, 7), (8, 9), (14, 15)] {
            let d = s[a]
                .t_body_sonar
                .rotation
                .angle_to(&s[b].t_body_sonar.rotation)
                .abs();
            assert!((d - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        }
    }
}
