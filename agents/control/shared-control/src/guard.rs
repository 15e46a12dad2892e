//! A footprint guard along the commanded arc: the chair's rectangle is swept along the arc the
//! command would drive (turning in place included) for as long as the chair needs to stop, and
//! the command is changed as little as possible so that no obstacle point enters it.
//!
//! The potential field of thesis 3.6 does nothing while the chair spins in place (`F_a = 0`) and
//! looks only along sonar axes; a long-fronted chair turning beside a wall sweeps its front
//! corners through the wall. The guard checks exactly that sweep.

use iw_body::layout::Footprint;
use nalgebra::{Isometry2, Point2, Vector2};

use crate::error::check_positive;
use crate::{
    ControlError, Intervention, SensorMount, SharedController, SharedInput, SharedOutput,
    VelocityCommand,
};

/// Limits of the sweep; defaults suit the prototype.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ArcGuardParams {
    /// Clearance kept around the footprint, m (0.05).
    pub margin_m: f64,
    /// Linear braking the chair can count on, m/s^2 (1.0).
    pub decel_mps2: f64,
    /// Angular braking, rad/s^2 (3.0).
    pub angular_decel_radps2: f64,
    /// Reaction time added to the braking time, s (0.3).
    pub reaction_s: f64,
    /// Time between two checked poses on the arc, s (0.05).
    pub sample_s: f64,
    /// Full sonar cone, deg (45, thesis 3.4).
    pub cone_deg: f64,
}

impl Default for ArcGuardParams {
    fn default() -> Self {
        Self {
            margin_m: 0.05,
            decel_mps2: 1.0,
            angular_decel_radps2: 3.0,
            reaction_s: 0.3,
            sample_s: 0.05,
            cone_deg: 45.0,
        }
    }
}

/// Sweeps the footprint along the commanded arc and scales or steers the command minimally.
#[derive(Debug, Clone)]
pub struct ArcGuard {
    params: ArcGuardParams,
    footprint: Footprint,
    mounts: Vec<SensorMount>,
}

/// Scales of the user's command tried, largest first.
const SCALES: [f64; 6] = [1.0, 0.8, 0.6, 0.4, 0.2, 0.0];
/// Angular offsets tried when scaling alone does not clear the arc, rad/s.
const STEER_RADPS: [f64; 7] = [0.0, 0.15, -0.15, 0.3, -0.3, 0.5, -0.5];

impl ArcGuard {
    /// A guard for a chair of `footprint` with sonars at `mounts`.
    pub fn new(
        params: ArcGuardParams,
        footprint: Footprint,
        mounts: Vec<SensorMount>,
    ) -> Result<Self, ControlError> {
        check_positive("decel_mps2", params.decel_mps2)?;
        check_positive("angular_decel_radps2", params.angular_decel_radps2)?;
        check_positive("sample_s", params.sample_s)?;
        if params.margin_m.is_nan()
            || params.margin_m < 0.0
            || params.reaction_s.is_nan()
            || params.reaction_s < 0.0
        {
            return Err(ControlError::BadParameter {
                name: "margin_m/reaction_s",
                value: params.margin_m.min(params.reaction_s),
                why: "must be >= 0",
            });
        }
        Ok(Self {
            params,
            footprint,
            mounts,
        })
    }

    /// How long the chair needs to stop from `command`, s.
    fn horizon_s(&self, command: VelocityCommand) -> f64 {
        let p = &self.params;
        p.reaction_s
            + (command.linear_mps.abs() / p.decel_mps2)
                .max(command.angular_radps.abs() / p.angular_decel_radps2)
    }

    /// Whether driving `command` until stopped keeps every point in `points` out of the footprint
    /// (inflated by the margin; points already inside the margin only count if they would enter
    /// the bare footprint).
    pub fn is_clear(&self, command: VelocityCommand, points: &[Point2<f64>]) -> bool {
        let (v, w) = (command.linear_mps, command.angular_radps);
        if v == 0.0 && w == 0.0 {
            return true;
        }
        let horizon = self.horizon_s(command);
        let fp = &self.footprint;
        let inside = |p: &Point2<f64>, m: f64| {
            p.x >= -fp.rear_m - m && p.x <= fp.front_m + m && p.y.abs() <= fp.half_width_m + m
        };
        let reach = fp.turning_radius_m() + self.params.margin_m + v.abs() * horizon;
        let steps = (horizon / self.params.sample_s).ceil().max(1.0) as usize;
        points.iter().filter(|p| p.coords.norm() <= reach).all(|p| {
            let m = if inside(p, self.params.margin_m) {
                0.0
            } else {
                self.params.margin_m
            };
            (1..=steps).all(|k| {
                let t = horizon * k as f64 / steps as f64;
                !inside(&(arc_pose(v, w, t).inverse() * p), m)
            })
        })
    }

    /// The obstacle points of one period in the chair frame: each sonar echo spread across the
    /// cone at its range (a sonar reports the nearest echo anywhere in its cone), and the dense
    /// points.
    fn points(&self, input: &SharedInput<'_>) -> Result<Vec<Point2<f64>>, ControlError> {
        if input.sonar_m.len() != self.mounts.len() {
            return Err(ControlError::SonarCount {
                expected: self.mounts.len(),
                got: input.sonar_m.len(),
            });
        }
        let mut points: Vec<Point2<f64>> =
            Vec::with_capacity(input.sonar_m.len() + input.points_chair.len());
        for (index, (mount, reading)) in self.mounts.iter().zip(input.sonar_m).enumerate() {
            let Some(d) = *reading else { continue };
            let d = crate::error::check_range("sonar", index, d)?;
            let half = self.params.cone_deg.to_radians() / 2.0;
            points.extend((-2..=2).map(|k| {
                mount
                    * Point2::new(
                        d * (half * k as f64 / 2.0).cos(),
                        d * (half * k as f64 / 2.0).sin(),
                    )
            }));
        }
        points.extend(
            input
                .points_chair
                .iter()
                .filter(|p| p.x.is_finite() && p.y.is_finite()),
        );
        Ok(points)
    }

    /// `command` changed as little as possible so the swept footprint stays clear of `points`:
    /// unchanged when clear; else the largest scale of it, then the smallest extra turn, that is
    /// clear; else a stop. Returns the command and whether it was changed.
    pub fn limit(
        &self,
        command: VelocityCommand,
        points: &[Point2<f64>],
    ) -> (VelocityCommand, bool) {
        if self.is_clear(command, points) {
            return (command, false);
        }
        let mut best: Option<(f64, VelocityCommand)> = None;
        for steer in STEER_RADPS {
            for scale in SCALES {
                let candidate = VelocityCommand::new(
                    command.linear_mps * scale,
                    command.angular_radps * scale + steer * scale.max(0.2),
                );
                let cost = (1.0 - scale) + steer.abs();
                if best.is_some_and(|(c, _)| c <= cost) {
                    continue;
                }
                if self.is_clear(candidate, points) {
                    best = Some((cost, candidate));
                }
            }
        }
        (best.map_or(VelocityCommand::STOP, |(_, c)| c), true)
    }
}

/// The chair's pose after driving `v`, `w` for `t` from the origin (exact unicycle arc).
fn arc_pose(v: f64, w: f64, t: f64) -> Isometry2<f64> {
    let th = w * t;
    let (x, y) = if w.abs() < 1e-9 {
        (v * t, 0.0)
    } else {
        (v / w * th.sin(), v / w * (1.0 - th.cos()))
    };
    Isometry2::new(Vector2::new(x, y), th)
}

impl SharedController for ArcGuard {
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError> {
        let user = input.user.validate()?;
        let points = self.points(input)?;
        let (command, changed) = self.limit(user, &points);
        let active = if changed { points.len() } else { 0 };
        Ok(SharedOutput {
            command,
            intervention: if changed {
                Intervention::between(user, command, active)
            } else {
                Intervention::default()
            },
        })
    }
}

/// A shared controller whose command then passes the [`ArcGuard`]: the control agent's policy for
/// the user's commands (the thesis's potential field, then the footprint sweep it lacks).
#[derive(Debug, Clone)]
pub struct Guarded<C> {
    /// The controller that corrects the user's command first.
    pub inner: C,
    /// The sweep applied to whatever `inner` produced.
    pub guard: ArcGuard,
}

impl<C: SharedController> SharedController for Guarded<C> {
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError> {
        let first = self.inner.step(input)?;
        let second = self.guard.step(&SharedInput {
            user: first.command,
            ..*input
        })?;
        let active = first.intervention.active_readings + second.intervention.active_readings;
        Ok(SharedOutput {
            command: second.command,
            intervention: Intervention::between(input.user, second.command, active),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn guard() -> ArcGuard {
        let fp = Footprint::PROTOTYPE;
        ArcGuard::new(ArcGuardParams::default(), fp, fp.sonar_mounts().to_vec()).unwrap()
    }

    #[test]
    fn turning_in_place_beside_a_wall_is_stopped_before_the_front_corner_hits() {
        // A wall 0.2 m to the right of the chair's side: spinning clockwise swings the front
        // right corner (0.75 m ahead) into it.
        let wall: Vec<Point2<f64>> = (-10..=20)
            .map(|k| Point2::new(k as f64 * 0.1, -0.525))
            .collect();
        let g = guard();
        assert!(!g.is_clear(VelocityCommand::new(0.0, -0.8), &wall));
        let (out, changed) = g.limit(VelocityCommand::new(0.0, -0.8), &wall);
        assert!(changed);
        assert!(g.is_clear(out, &wall), "{out:?}");
        // driving along the wall is left alone
        let (out, changed) = g.limit(VelocityCommand::new(0.5, 0.0), &wall);
        assert!(!changed && out == VelocityCommand::new(0.5, 0.0));
    }

    #[test]
    fn guarded_reports_the_change_against_the_users_command() {
        // Sonars S1.. all echo at 0.2 m: spinning in place would sweep the corners through them.
        let mut g = Guarded {
            inner: crate::Manual,
            guard: guard(),
        };
        let sonar = [Some(0.2); iw_body::SONAR_COUNT];
        let user = VelocityCommand::new(0.0, -0.8);
        let out = g
            .step(&SharedInput {
                user,
                speed_mps: 0.0,
                sonar_m: &sonar,
                points_chair: &[],
            })
            .unwrap();
        assert_ne!(out.command, user);
        assert_eq!(
            out.intervention,
            Intervention::between(user, out.command, out.intervention.active_readings)
        );
        assert!(out.intervention.changed() && out.intervention.active_readings > 0);
    }

    #[test]
    fn free_space_passes_the_command_bit_for_bit() {
        let mut g = guard();
        let sonar = [None; iw_body::SONAR_COUNT];
        let user = VelocityCommand::new(0.7, -0.3);
        let out = g
            .step(&SharedInput {
                user,
                speed_mps: 0.7,
                sonar_m: &sonar,
                points_chair: &[],
            })
            .unwrap();
        assert_eq!(out.command, user);
        assert_eq!(out.intervention, Intervention::default());
    }

    #[test]
    fn an_obstacle_ahead_slows_the_chair_to_a_stop_in_front_of_it() {
        let g = guard();
        let box_ahead = [
            Point2::new(1.2, 0.0),
            Point2::new(1.2, 0.2),
            Point2::new(1.2, -0.2),
        ];
        let (out, changed) = g.limit(VelocityCommand::new(1.0, 0.0), &box_ahead);
        assert!(changed && out.linear_mps < 1.0, "{out:?}");
        assert!(g.is_clear(out, &box_ahead));
    }
}
