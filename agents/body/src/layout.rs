//! The one source of truth for the chair's shape and where its 16 sonars sit (thesis figure
//! 3.4): the simulator builds its virtual body from it and the control agent configures its
//! shared controller from it, so both agree on which sonar looks where.
//!
//! Body frame: x forward, y left, origin at the centre of the drive axle.

use nalgebra::{Isometry2, Point2, Vector2};

use crate::SONAR_COUNT;

/// The chair's rectangular footprint around the drive axle centre.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Footprint {
    /// Reach in front of the drive axle, m.
    pub front_m: f64,
    /// Reach behind the drive axle, m.
    pub rear_m: f64,
    /// Half the width, m.
    pub half_width_m: f64,
}

impl Footprint {
    /// The IntellWheels prototype: a mid-size rear-wheel-drive powered wheelchair, 0.65 x 1.1 m.
    pub const PROTOTYPE: Footprint = Footprint {
        front_m: 0.75,
        rear_m: 0.35,
        half_width_m: 0.325,
    };

    /// Corners in the body frame, counter-clockwise from rear right.
    pub fn corners(&self) -> [Point2<f64>; 4] {
        [
            Point2::new(-self.rear_m, -self.half_width_m),
            Point2::new(self.front_m, -self.half_width_m),
            Point2::new(self.front_m, self.half_width_m),
            Point2::new(-self.rear_m, self.half_width_m),
        ]
    }

    /// Radius of the circle the footprint sweeps when the chair turns in place (distance from
    /// the axle centre to the farthest corner), m.
    ///
    /// ```
    /// let r = iw_body::layout::Footprint::PROTOTYPE.turning_radius_m();
    /// assert!((r - (0.75f64.powi(2) + 0.325f64.powi(2)).sqrt()).abs() < 1e-12);
    /// ```
    pub fn turning_radius_m(&self) -> f64 {
        self.corners()
            .iter()
            .map(|p| p.coords.norm())
            .fold(0.0, f64::max)
    }

    /// The 16 sonar poses of thesis figure 3.4 for this footprint, S1 first; each pose's x axis
    /// is the transducer's acoustic axis.
    ///
    /// Right bar: S1 (ahead) and S2 (45 deg right) on the front tip, S3-S6 facing right 22 cm
    /// apart front to back, S7 (135 deg right) and S8 (behind) on the rear tip. The left bar
    /// mirrors it back to front: S9 (behind), S10, S11-S14 facing left rear to front, S15, S16
    /// (ahead). Lateral 45 deg cones 22 cm apart overlap from 0.22 / (2 tan 22.5) = 27 cm; the
    /// two forward cones, 0.65 m apart, close the gap straight ahead at 0.325 / tan 22.5 = 80 cm:
    /// the 27-80 cm safety perimeter of the thesis.
    pub fn sonar_mounts(&self) -> [Isometry2<f64>; SONAR_COUNT] {
        use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
        let mid = (self.front_m - self.rear_m) / 2.0;
        let lateral = [mid + 0.33, mid + 0.11, mid - 0.11, mid - 0.33];
        let at = |x: f64, y: f64, heading: f64| Isometry2::new(Vector2::new(x, y), heading);
        let (f, r, w) = (self.front_m, -self.rear_m, self.half_width_m);
        [
            at(f, -w, 0.0),
            at(f - 0.03, -w, -FRAC_PI_4),
            at(lateral[0], -w, -FRAC_PI_2),
            at(lateral[1], -w, -FRAC_PI_2),
            at(lateral[2], -w, -FRAC_PI_2),
            at(lateral[3], -w, -FRAC_PI_2),
            at(r + 0.03, -w, -3.0 * FRAC_PI_4),
            at(r, -w, PI),
            at(r, w, PI),
            at(r + 0.03, w, 3.0 * FRAC_PI_4),
            at(lateral[3], w, FRAC_PI_2),
            at(lateral[2], w, FRAC_PI_2),
            at(lateral[1], w, FRAC_PI_2),
            at(lateral[0], w, FRAC_PI_2),
            at(f - 0.03, w, FRAC_PI_4),
            at(f, w, 0.0),
        ]
    }
}

impl Default for Footprint {
    fn default() -> Self {
        Self::PROTOTYPE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sonars_sit_on_the_footprint_edge_and_look_outwards() {
        let fp = Footprint::PROTOTYPE;
        for (k, m) in fp.sonar_mounts().iter().enumerate() {
            let p = m.translation.vector;
            assert!(
                p.y.abs() <= fp.half_width_m + 1e-12
                    && p.x <= fp.front_m + 1e-12
                    && p.x >= -fp.rear_m - 1e-12,
                "S{}",
                k + 1
            );
            // the acoustic axis never points back into the chair across its centre line
            let axis = m.rotation * Vector2::x();
            assert!(axis.dot(&p) > 0.0, "S{} looks inwards", k + 1);
        }
    }
}
