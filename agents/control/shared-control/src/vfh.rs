//! VFH+ (Ulrich and Borenstein, 1998) as a shared controller: the baseline the thesis's potential
//! field is compared against.
//!
//! Per period, in the motion frame (see [`MotionIntent`]):
//! 1. primary polar histogram: every obstacle point within `window_radius_m` raises the sectors its
//!    robot-enlarged angle `asin((r_robot + d_safe) / d)` covers to `1 - (d / window)^2`; a sector
//!    keeps the largest value (the maximum rather than VFH+'s sum, so a dense laser scan and a sparse
//!    sonar ring weigh the same);
//! 2. binary histogram with hysteresis (`threshold_high` blocks, below `threshold_low` frees);
//! 3. masked histogram: the turning circles at the user's speed and `max_angular_radps` block the
//!    side whose circle holds an obstacle;
//! 4. candidate valleys (runs of free sectors in the front half): a wide valley offers its two borders
//!    moved in by half `wide_valley_sectors`, plus the user's direction when it lies between them; a
//!    narrow valley offers its centre;
//! 5. cost `mu_target * |c - user| + mu_heading * |c - 0| + mu_previous * |c - previous|` picks one.
//!
//! The speed is the user's, cut linearly from `threshold_low` to a stop at `threshold_high` of the
//! chosen sector's obstacle value. When the user's own direction wins with nothing near it, the
//! user's command passes through unchanged.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Point2, Vector2};

use crate::error::{check_positive, check_range};
use crate::{
    ControlError, Intervention, MotionIntent, SensorMount, SharedController, SharedInput,
    SharedOutput,
};

/// VFH+ tuning; defaults suit a 0.7 m wide chair in an office.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VfhParams {
    /// Sectors in the polar histogram (72 = 5 degrees each).
    pub sector_count: usize,
    /// Obstacles farther than this are ignored, m.
    pub window_radius_m: f64,
    /// Half the chair's width, m (obstacle enlargement).
    pub robot_radius_m: f64,
    /// Extra clearance, m.
    pub safety_distance_m: f64,
    /// Histogram value below which a blocked sector frees, 0-1.
    pub threshold_low: f64,
    /// Histogram value above which a free sector blocks, 0-1.
    pub threshold_high: f64,
    /// Sectors a valley needs to count as wide.
    pub wide_valley_sectors: usize,
    /// Cost weight of leaving the user's direction (must exceed the other two together).
    pub mu_target: f64,
    /// Cost weight of turning away from the current heading.
    pub mu_heading: f64,
    /// Cost weight of changing the previous choice.
    pub mu_previous: f64,
    /// Horizon turning commands into directions, s.
    pub lookahead_s: f64,
    /// Fastest turn the chair makes, rad/s (sets the turning circles of the mask).
    pub max_angular_radps: f64,
}

impl Default for VfhParams {
    fn default() -> Self {
        VfhParams {
            sector_count: 72,
            window_radius_m: 1.6,
            robot_radius_m: 0.35,
            safety_distance_m: 0.05,
            threshold_low: 0.4,
            threshold_high: 0.6,
            wide_valley_sectors: 8,
            mu_target: 5.0,
            mu_heading: 2.0,
            mu_previous: 2.0,
            lookahead_s: 1.0,
            max_angular_radps: 1.5,
        }
    }
}

impl VfhParams {
    /// Checks the parameters are usable.
    pub fn validate(&self) -> Result<(), ControlError> {
        if self.sector_count < 8 {
            return Err(ControlError::BadParameter {
                name: "sector_count",
                value: self.sector_count as f64,
                why: "needs at least 8 sectors",
            });
        }
        check_positive("window_radius_m", self.window_radius_m)?;
        check_positive("robot_radius_m", self.robot_radius_m)?;
        check_positive("lookahead_s", self.lookahead_s)?;
        check_positive("max_angular_radps", self.max_angular_radps)?;
        if !(0.0 < self.threshold_low
            && self.threshold_low < self.threshold_high
            && self.threshold_high <= 1.0)
        {
            return Err(ControlError::BadParameter {
                name: "threshold_low",
                value: self.threshold_low,
                why: "need 0 < threshold_low < threshold_high <= 1",
            });
        }
        if self.mu_target <= self.mu_heading + self.mu_previous {
            return Err(ControlError::BadParameter {
                name: "mu_target",
                value: self.mu_target,
                why: "must exceed mu_heading + mu_previous so a free user direction always wins",
            });
        }
        Ok(())
    }
}

/// The VFH+ shared controller; keeps the binary histogram and the previous choice between periods.
#[derive(Debug, Clone)]
pub struct Vfh {
    params: VfhParams,
    sonar_mounts: Vec<SensorMount>,
    binary: Vec<bool>,
    previous_sector: Option<usize>,
    points: Vec<Point2<f64>>,
    primary: Vec<f64>,
}

impl Vfh {
    /// A controller that also turns echoes of sonars at `sonar_mounts` into obstacle points.
    pub fn new(params: VfhParams, sonar_mounts: Vec<SensorMount>) -> Result<Self, ControlError> {
        params.validate()?;
        Ok(Vfh {
            binary: vec![false; params.sector_count],
            primary: vec![0.0; params.sector_count],
            previous_sector: None,
            points: Vec::new(),
            params,
            sonar_mounts,
        })
    }

    fn sector_width(&self) -> f64 {
        2.0 * PI / self.params.sector_count as f64
    }

    /// Centre angle of sector `k`, rad in (-pi, pi).
    pub fn sector_angle(&self, k: usize) -> f64 {
        -PI + (k as f64 + 0.5) * self.sector_width()
    }

    /// The sector holding `angle` (rad).
    pub fn sector_of(&self, angle: f64) -> usize {
        let wrapped = (angle + PI).rem_euclid(2.0 * PI);
        ((wrapped / self.sector_width()) as usize).min(self.params.sector_count - 1)
    }

    /// Which sectors are blocked after the last step (binary histogram).
    pub fn blocked(&self) -> &[bool] {
        &self.binary
    }

    /// Gathers sonar echoes and dense points into the motion frame.
    fn collect_points(
        &mut self,
        input: &SharedInput<'_>,
        intent: &MotionIntent,
    ) -> Result<(), ControlError> {
        if input.sonar_m.len() != self.sonar_mounts.len() {
            return Err(ControlError::SonarCount {
                expected: self.sonar_mounts.len(),
                got: input.sonar_m.len(),
            });
        }
        self.points.clear();
        for (index, (mount, reading)) in self.sonar_mounts.iter().zip(input.sonar_m).enumerate() {
            if let Some(d) = *reading {
                let d = check_range("sonar", index, d)?;
                self.points.push(Point2::from(
                    intent.to_motion_frame((mount * Point2::new(d, 0.0)).coords),
                ));
            }
        }
        for (index, p) in input.points_chair.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(ControlError::BadReading {
                    sensor: "laser point",
                    index,
                    value: p.x + p.y,
                });
            }
            self.points
                .push(Point2::from(intent.to_motion_frame(p.coords)));
        }
        Ok(())
    }

    /// Steps 1-3: primary, binary and masked histograms; returns the masked one and the number of
    /// points that raised a sector above `threshold_low`.
    fn masked_histogram(&mut self, speed_mps: f64) -> (Vec<bool>, usize) {
        let p = self.params;
        let enlarge = p.robot_radius_m + p.safety_distance_m;
        self.primary.iter_mut().for_each(|h| *h = 0.0);
        let mut active = 0;
        let turn_radius = speed_mps / p.max_angular_radps;
        let (mut right_limit, mut left_limit) = (-PI, PI);
        for point in &self.points {
            let d = point.coords.norm();
            if d >= p.window_radius_m {
                continue;
            }
            let value = 1.0 - (d / p.window_radius_m).powi(2);
            if value > p.threshold_low {
                active += 1;
            }
            let beta = point.y.atan2(point.x);
            let gamma = if d > enlarge {
                (enlarge / d).asin()
            } else {
                FRAC_PI_2
            };
            let first = beta - gamma;
            let sectors = ((2.0 * gamma) / self.sector_width()).ceil() as usize + 1;
            for step in 0..sectors.min(p.sector_count) {
                let angle = (first + step as f64 * self.sector_width()).min(beta + gamma);
                let k = self.sector_of(angle);
                self.primary[k] = self.primary[k].max(value);
            }
            // Turning circles at the current speed: an obstacle inside one closes that side.
            let right_centre = Vector2::new(0.0, -turn_radius);
            let left_centre = Vector2::new(0.0, turn_radius);
            if beta < 0.0 && (point.coords - right_centre).norm() < turn_radius + enlarge {
                right_limit = right_limit.max(beta);
            }
            if beta > 0.0 && (point.coords - left_centre).norm() < turn_radius + enlarge {
                left_limit = left_limit.min(beta);
            }
        }
        for (blocked, &h) in self.binary.iter_mut().zip(&self.primary) {
            if h > p.threshold_high {
                *blocked = true;
            } else if h < p.threshold_low {
                *blocked = false;
            }
        }
        let masked = (0..p.sector_count)
            .map(|k| {
                let angle = self.sector_angle(k);
                self.binary[k] || angle <= right_limit || angle >= left_limit
            })
            .collect();
        (masked, active)
    }

    /// Steps 4-5: the best free sector for a user aiming at `target`, or `None` when all are blocked.
    fn choose(&self, masked: &[bool], target: usize) -> Option<usize> {
        let p = self.params;
        let half = p.wide_valley_sectors / 2;
        let front = |k: usize| self.sector_angle(k).abs() <= FRAC_PI_2;
        let mut candidates = Vec::new();
        let mut k = 0;
        while k < p.sector_count {
            if masked[k] || !front(k) {
                k += 1;
                continue;
            }
            let start = k;
            while k < p.sector_count && !masked[k] && front(k) {
                k += 1;
            }
            let end = k - 1;
            if end + 1 - start >= p.wide_valley_sectors {
                let (right, left) = (start + half, end - half);
                candidates.extend([right, left]);
                if (right..=left).contains(&target) {
                    candidates.push(target);
                }
            } else {
                candidates.push((start + end) / 2);
            }
        }
        let heading = self.sector_of(0.0);
        let distance = |a: usize, b: usize| a.abs_diff(b) as f64;
        let cost = |c: usize| {
            p.mu_target * distance(c, target)
                + p.mu_heading * distance(c, heading)
                + p.mu_previous * self.previous_sector.map_or(0.0, |prev| distance(c, prev))
        };
        candidates
            .into_iter()
            .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
    }
}

impl SharedController for Vfh {
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError> {
        let user = input.user.validate()?;
        let intent = MotionIntent::from_command(user, self.params.lookahead_s);
        self.collect_points(input, &intent)?;
        if intent.sign == 0.0 {
            return Ok(SharedOutput {
                command: user,
                intervention: Intervention::default(),
            });
        }
        let (masked, active) = self.masked_histogram(intent.speed_mps);
        let target = self.sector_of(intent.direction_rad);
        let Some(chosen) = self.choose(&masked, target) else {
            // Boxed in: stop moving, leave the user free to spin away.
            self.previous_sector = None;
            let command = crate::VelocityCommand::new(0.0, user.angular_radps);
            return Ok(SharedOutput {
                command,
                intervention: Intervention::between(user, command, active),
            });
        };
        self.previous_sector = Some(chosen);
        let p = self.params;
        let slow = ((p.threshold_high - self.primary[chosen])
            / (p.threshold_high - p.threshold_low))
            .clamp(0.0, 1.0);
        if chosen == target && slow == 1.0 {
            return Ok(SharedOutput {
                command: user,
                intervention: Intervention::default(),
            });
        }
        let direction_rad = if chosen == target {
            intent.direction_rad
        } else {
            self.sector_angle(chosen)
        };
        let corrected = MotionIntent {
            sign: intent.sign,
            speed_mps: intent.speed_mps * slow,
            direction_rad,
        };
        let command = corrected.to_command(p.lookahead_s);
        Ok(SharedOutput {
            command,
            intervention: Intervention::between(user, command, active),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::VelocityCommand;

    fn wall(x: f64, y0: f64, y1: f64) -> Vec<Point2<f64>> {
        let n = ((y1 - y0) / 0.05) as usize;
        (0..=n)
            .map(|i| Point2::new(x, y0 + i as f64 * 0.05))
            .collect()
    }

    fn step(vfh: &mut Vfh, user: VelocityCommand, points: &[Point2<f64>]) -> SharedOutput {
        vfh.step(&SharedInput {
            user,
            speed_mps: user.linear_mps.abs(),
            sonar_m: &[],
            points_chair: points,
            motion: None,
        })
        .unwrap()
    }

    #[test]
    fn free_space_passes_the_user_through() {
        let mut vfh = Vfh::new(VfhParams::default(), vec![]).unwrap();
        let user = VelocityCommand::new(0.8, 0.3);
        let out = step(&mut vfh, user, &wall(3.0, -1.0, 1.0));
        assert_eq!(out.command, user);
        assert!(!out.intervention.changed());
    }

    #[test]
    fn picks_the_free_valley_beside_a_wall_ahead() {
        // A wall ahead from y = -2 to y = 0.2: the only way past is to the left.
        let mut vfh = Vfh::new(VfhParams::default(), vec![]).unwrap();
        let points = wall(0.9, -2.0, 0.2);
        let out = step(&mut vfh, VelocityCommand::new(0.6, 0.0), &points);
        assert!(out.intervention.changed());
        assert!(out.command.angular_radps > 0.0, "{out:?}");
        let chosen = vfh.previous_sector.unwrap();
        assert!(!vfh.blocked()[chosen]);
        // The chosen direction clears the wall's end by the chair's enlarged radius.
        let angle = vfh.sector_angle(chosen);
        let end = 0.2f64.atan2(0.9);
        assert!(angle > end, "chose {angle} rad, wall ends at {end} rad");
    }

    #[test]
    fn boxed_in_stops() {
        let mut vfh = Vfh::new(VfhParams::default(), vec![]).unwrap();
        let ring: Vec<_> = (0..72)
            .map(|i| {
                let a = i as f64 * 5f64.to_radians();
                Point2::new(0.5 * a.cos(), 0.5 * a.sin())
            })
            .collect();
        let out = step(&mut vfh, VelocityCommand::new(0.5, 0.2), &ring);
        assert_eq!(out.command.linear_mps, 0.0);
        assert_eq!(out.command.angular_radps, 0.2);
    }

    #[test]
    fn rejects_weights_that_override_the_user() {
        let params = VfhParams {
            mu_target: 1.0,
            ..VfhParams::default()
        };
        assert!(Vfh::new(params, vec![]).is_err());
    }
}
