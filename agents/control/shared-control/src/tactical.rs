//! Tactical layer (thesis 3.3.2): the seven basic actions (follow line, spin / turn to angle, go to
//! XY, follow left wall, follow right wall, wait, stop) and sequences of them, each next action
//! starting in the same period the current one reports done.
//!
//! Each action is a typed state machine: [`Action`] says what to do, [`ActionSequence`] starts it
//! against the pose at that moment (start heading, start time) and steps it with explicit time and
//! pose until it is done.

use std::collections::VecDeque;
use std::f64::consts::PI;

use nalgebra::{Isometry2, Point2, Vector2};

use crate::error::check_positive;
use crate::{ControlError, VelocityCommand};

/// Which side a wall is followed on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// Wall on the chair's left.
    Left,
    /// Wall on the chair's right.
    Right,
}

/// A basic action, as a user or the strategic layer configures it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "action", rename_all = "kebab-case")]
pub enum Action {
    /// Drive along the segment `from -> to` (world frame, m) until past `to`.
    FollowLine {
        /// Segment start, m.
        from: Point2<f64>,
        /// Segment end, m.
        to: Point2<f64>,
    },
    /// Turn in place by `angle_rad` (relative, may exceed a full turn; positive = left).
    Spin {
        /// Angle to turn, rad.
        angle_rad: f64,
    },
    /// Turn in place to the absolute heading `heading_rad` (world frame), the short way.
    TurnTo {
        /// Heading to reach, rad.
        heading_rad: f64,
    },
    /// Drive to the point `target` (world frame, m).
    GoTo {
        /// Where to stop, m.
        target: Point2<f64>,
    },
    /// Keep `distance_m` from the wall on `side` for `length_m` of travel.
    FollowWall {
        /// Which wall.
        side: Side,
        /// Clearance to keep, m.
        distance_m: f64,
        /// Travel before done, m.
        length_m: f64,
    },
    /// Stand still for `duration_ns`.
    Wait {
        /// How long, ns.
        duration_ns: u64,
    },
    /// Stop the chair (done at once; the chair stays stopped until the next action).
    Stop,
}

/// Gains and tolerances of the basic actions.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TacticalParams {
    /// Travel speed of moving actions, m/s.
    pub cruise_mps: f64,
    /// Turn-rate limit, rad/s.
    pub max_angular_radps: f64,
    /// A point counts as reached within this distance, m.
    pub position_tolerance_m: f64,
    /// An angle counts as reached within this, rad.
    pub angle_tolerance_rad: f64,
    /// Heading error to turn rate, 1/s.
    pub heading_gain: f64,
    /// Lateral error (line or wall) to heading correction, rad/m.
    pub lateral_gain: f64,
    /// Go-to turns in place first when the target is off by more than this, rad.
    pub turn_in_place_rad: f64,
}

impl Default for TacticalParams {
    fn default() -> Self {
        TacticalParams {
            cruise_mps: 0.5,
            max_angular_radps: 1.0,
            position_tolerance_m: 0.1,
            angle_tolerance_rad: 0.03,
            heading_gain: 2.0,
            lateral_gain: 1.5,
            turn_in_place_rad: 1.0,
        }
    }
}

/// What the tactical layer knows in one period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TacticalInput {
    /// Time, ns.
    pub time_ns: u64,
    /// Chair pose: maps chair coordinates into the world.
    pub t_world_chair: Isometry2<f64>,
    /// Clearance to the nearest obstacle on the left (side sonars), m.
    pub left_wall_m: Option<f64>,
    /// Clearance to the nearest obstacle on the right, m.
    pub right_wall_m: Option<f64>,
}

/// Where a sequence is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SequenceStatus {
    /// Running action number `index` (0-based, counted from the first ever pushed).
    Running {
        /// Index of the running action.
        index: usize,
    },
    /// Every action is done; the chair is stopped.
    Finished,
}

/// A command and where the sequence stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TacticalOutput {
    /// What to drive this period.
    pub command: VelocityCommand,
    /// Sequence progress.
    pub status: SequenceStatus,
}

/// An action started against a pose and time: its running state.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Running {
    FollowLine {
        from: Point2<f64>,
        to: Point2<f64>,
    },
    Spin {
        remaining_rad: f64,
        last_heading_rad: f64,
    },
    TurnTo {
        heading_rad: f64,
    },
    GoTo {
        target: Point2<f64>,
    },
    FollowWall {
        side: Side,
        distance_m: f64,
        remaining_m: f64,
        last_position: Point2<f64>,
        last_clearance_m: Option<f64>,
        toward_wall_rad: f64,
    },
    Wait {
        until_ns: u64,
    },
    Stop,
}

/// `angle` wrapped into (-pi, pi].
pub fn wrap_angle(angle: f64) -> f64 {
    let wrapped = (angle + PI).rem_euclid(2.0 * PI) - PI;
    if wrapped == -PI { PI } else { wrapped }
}

fn check_point(what: &'static str, p: Point2<f64>) -> Result<(), ControlError> {
    if p.x.is_finite() && p.y.is_finite() {
        Ok(())
    } else {
        Err(ControlError::NonFinitePose {
            what,
            x: p.x,
            y: p.y,
            theta: 0.0,
        })
    }
}

fn check_angle(what: &'static str, a: f64) -> Result<(), ControlError> {
    if a.is_finite() {
        Ok(())
    } else {
        Err(ControlError::NonFinitePose {
            what,
            x: 0.0,
            y: 0.0,
            theta: a,
        })
    }
}

impl Running {
    fn start(action: Action, input: &TacticalInput) -> Result<Running, ControlError> {
        let heading = input.t_world_chair.rotation.angle();
        let position = Point2::from(input.t_world_chair.translation.vector);
        Ok(match action {
            Action::FollowLine { from, to } => {
                check_point("line start", from)?;
                check_point("line end", to)?;
                Running::FollowLine { from, to }
            }
            Action::Spin { angle_rad } => {
                check_angle("spin angle", angle_rad)?;
                Running::Spin {
                    remaining_rad: angle_rad,
                    last_heading_rad: heading,
                }
            }
            Action::TurnTo { heading_rad } => {
                check_angle("heading", heading_rad)?;
                Running::TurnTo { heading_rad }
            }
            Action::GoTo { target } => {
                check_point("target", target)?;
                Running::GoTo { target }
            }
            Action::FollowWall {
                side,
                distance_m,
                length_m,
            } => {
                check_positive("distance_m", distance_m)?;
                check_positive("length_m", length_m)?;
                Running::FollowWall {
                    side,
                    distance_m,
                    remaining_m: length_m,
                    last_position: position,
                    last_clearance_m: None,
                    toward_wall_rad: 0.0,
                }
            }
            Action::Wait { duration_ns } => Running::Wait {
                until_ns: input.time_ns.saturating_add(duration_ns),
            },
            Action::Stop => Running::Stop,
        })
    }

    /// One period: `None` when done, else the command.
    fn step(&mut self, p: &TacticalParams, input: &TacticalInput) -> Option<VelocityCommand> {
        let heading = input.t_world_chair.rotation.angle();
        let position = Point2::from(input.t_world_chair.translation.vector);
        let turn =
            |error: f64| (p.heading_gain * error).clamp(-p.max_angular_radps, p.max_angular_radps);
        match self {
            Running::FollowLine { from, to } => {
                let along = *to - *from;
                let length = along.norm();
                let u = along.try_normalize(1e-9)?;
                let offset = position - *from;
                if u.dot(&offset) >= length - p.position_tolerance_m {
                    return None;
                }
                let lateral = u.perp(&offset);
                let desired = u.y.atan2(u.x) - (p.lateral_gain * lateral).atan();
                let error = wrap_angle(desired - heading);
                Some(VelocityCommand::new(
                    p.cruise_mps * error.cos().max(0.0),
                    turn(error),
                ))
            }
            Running::Spin {
                remaining_rad,
                last_heading_rad,
            } => {
                *remaining_rad -= wrap_angle(heading - *last_heading_rad);
                *last_heading_rad = heading;
                if remaining_rad.abs() <= p.angle_tolerance_rad {
                    return None;
                }
                Some(VelocityCommand::new(0.0, turn(*remaining_rad)))
            }
            Running::TurnTo { heading_rad } => {
                let error = wrap_angle(*heading_rad - heading);
                if error.abs() <= p.angle_tolerance_rad {
                    return None;
                }
                Some(VelocityCommand::new(0.0, turn(error)))
            }
            Running::GoTo { target } => {
                let to_target: Vector2<f64> = *target - position;
                let distance = to_target.norm();
                if distance <= p.position_tolerance_m {
                    return None;
                }
                let error = wrap_angle(to_target.y.atan2(to_target.x) - heading);
                let linear = if error.abs() > p.turn_in_place_rad {
                    0.0
                } else {
                    (p.cruise_mps.min(p.heading_gain * distance)) * error.cos()
                };
                Some(VelocityCommand::new(linear, turn(error)))
            }
            Running::FollowWall {
                side,
                distance_m,
                remaining_m,
                last_position,
                last_clearance_m,
                toward_wall_rad,
            } => {
                let travelled = (position - *last_position).norm();
                *remaining_m -= travelled;
                *last_position = position;
                if *remaining_m <= 0.0 {
                    return None;
                }
                let (clearance, toward_wall) = match side {
                    Side::Left => (input.left_wall_m, 1.0),
                    Side::Right => (input.right_wall_m, -1.0),
                };
                // The wall's direction is unknown: estimate the heading towards it from how fast the
                // clearance shrinks per metre travelled, and steer that heading to a setpoint that
                // grows with the clearance error (a P controller on distance alone would oscillate).
                if let (Some(now), Some(before)) = (clearance, *last_clearance_m)
                    && travelled > 1e-3
                {
                    *toward_wall_rad = (before - now).atan2(travelled);
                }
                *last_clearance_m = clearance;
                let Some(clearance) = clearance else {
                    return Some(VelocityCommand::new(p.cruise_mps, 0.0));
                };
                let setpoint = (p.lateral_gain * (clearance - *distance_m))
                    .atan()
                    .clamp(-0.6, 0.6);
                Some(VelocityCommand::new(
                    p.cruise_mps,
                    toward_wall * turn(setpoint - *toward_wall_rad),
                ))
            }
            Running::Wait { until_ns } => {
                (input.time_ns < *until_ns).then_some(VelocityCommand::STOP)
            }
            Running::Stop => None,
        }
    }
}

/// A queue of actions; the next one starts when the current one is done.
#[derive(Debug, Clone)]
pub struct ActionSequence {
    params: TacticalParams,
    pending: VecDeque<Action>,
    current: Option<Running>,
    index: usize,
}

impl ActionSequence {
    /// A sequence that will run `actions` in order.
    pub fn new(
        params: TacticalParams,
        actions: impl IntoIterator<Item = Action>,
    ) -> Result<Self, ControlError> {
        check_positive("cruise_mps", params.cruise_mps)?;
        check_positive("max_angular_radps", params.max_angular_radps)?;
        check_positive("position_tolerance_m", params.position_tolerance_m)?;
        check_positive("angle_tolerance_rad", params.angle_tolerance_rad)?;
        Ok(ActionSequence {
            params,
            pending: actions.into_iter().collect(),
            current: None,
            index: 0,
        })
    }

    /// Appends an action after the ones already queued.
    pub fn push(&mut self, action: Action) {
        self.pending.push_back(action);
    }

    /// One period.
    pub fn step(&mut self, input: &TacticalInput) -> Result<TacticalOutput, ControlError> {
        let t = input.t_world_chair;
        if !(t.translation.x.is_finite()
            && t.translation.y.is_finite()
            && t.rotation.angle().is_finite())
        {
            return Err(ControlError::NonFinitePose {
                what: "chair pose",
                x: t.translation.x,
                y: t.translation.y,
                theta: t.rotation.angle(),
            });
        }
        loop {
            let running = match self.current.as_mut() {
                Some(running) => running,
                None => {
                    let Some(next) = self.pending.pop_front() else {
                        return Ok(TacticalOutput {
                            command: VelocityCommand::STOP,
                            status: SequenceStatus::Finished,
                        });
                    };
                    self.current.insert(Running::start(next, input)?)
                }
            };
            if let Some(command) = running.step(&self.params, input) {
                return Ok(TacticalOutput {
                    command,
                    status: SequenceStatus::Running { index: self.index },
                });
            }
            self.current = None;
            self.index += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unicycle integrated at 20 Hz; optional straight wall at y = `wall_y` on the left.
    struct Kinematic {
        pose: Isometry2<f64>,
        time_ns: u64,
        wall_y: Option<f64>,
    }

    impl Kinematic {
        fn input(&self) -> TacticalInput {
            let left_wall_m = self.wall_y.map(|y| {
                let heading = self.pose.rotation.angle();
                (y - self.pose.translation.y) / heading.cos().max(0.1)
            });
            TacticalInput {
                time_ns: self.time_ns,
                t_world_chair: self.pose,
                left_wall_m,
                right_wall_m: None,
            }
        }

        fn run(&mut self, seq: &mut ActionSequence, max_steps: usize) -> usize {
            let dt = 0.05;
            for step in 0..max_steps {
                let out = seq.step(&self.input()).unwrap();
                if out.status == SequenceStatus::Finished {
                    return step;
                }
                let heading = self.pose.rotation.angle();
                let v = out.command.linear_mps;
                let w = out.command.angular_radps;
                let x = self.pose.translation.x + v * heading.cos() * dt;
                let y = self.pose.translation.y + v * heading.sin() * dt;
                self.pose = Isometry2::new(Vector2::new(x, y), heading + w * dt);
                self.time_ns += 50_000_000;
            }
            panic!("sequence did not finish in {max_steps} steps");
        }
    }

    fn at(x: f64, y: f64, theta: f64) -> Kinematic {
        Kinematic {
            pose: Isometry2::new(Vector2::new(x, y), theta),
            time_ns: 0,
            wall_y: None,
        }
    }

    #[test]
    fn go_to_reaches_the_target() {
        let mut sim = at(0.0, 0.0, 0.0);
        let target = Point2::new(-2.0, 3.0);
        let mut seq =
            ActionSequence::new(TacticalParams::default(), [Action::GoTo { target }]).unwrap();
        sim.run(&mut seq, 2000);
        let p = Point2::from(sim.pose.translation.vector);
        assert!((p - target).norm() <= 0.1 + 1e-9, "ended at {p}");
    }

    #[test]
    fn spin_reaches_the_angle_even_beyond_a_turn() {
        let mut sim = at(1.0, 1.0, 0.3);
        let mut seq = ActionSequence::new(
            TacticalParams::default(),
            [Action::Spin {
                angle_rad: 1.5 * 2.0 * PI,
            }],
        )
        .unwrap();
        sim.run(&mut seq, 2000);
        assert!(wrap_angle(sim.pose.rotation.angle() - (0.3 + PI)).abs() < 0.05);
        assert!((sim.pose.translation.x - 1.0).abs() < 1e-12);
    }

    #[test]
    fn sequence_runs_every_action_in_order() {
        let mut sim = at(0.0, 0.0, 0.0);
        let actions = [
            Action::FollowLine {
                from: Point2::new(0.0, 0.5),
                to: Point2::new(3.0, 0.5),
            },
            Action::TurnTo {
                heading_rad: -PI / 2.0,
            },
            Action::Wait {
                duration_ns: 1_000_000_000,
            },
            Action::GoTo {
                target: Point2::new(3.0, -2.0),
            },
            Action::Stop,
        ];
        let mut seq = ActionSequence::new(TacticalParams::default(), actions).unwrap();
        let steps = sim.run(&mut seq, 4000);
        assert!(steps > 20, "the wait alone takes 20 periods");
        assert!((sim.pose.translation.y + 2.0).abs() < 0.11);
    }

    #[test]
    fn follow_left_wall_converges_to_the_clearance() {
        let mut sim = at(0.0, 0.0, 0.0);
        sim.wall_y = Some(1.2);
        let wall = Action::FollowWall {
            side: Side::Left,
            distance_m: 0.5,
            length_m: 6.0,
        };
        let mut seq = ActionSequence::new(TacticalParams::default(), [wall]).unwrap();
        sim.run(&mut seq, 2000);
        assert!(
            (1.2 - sim.pose.translation.y - 0.5).abs() < 0.05,
            "y = {}",
            sim.pose.translation.y
        );
        assert!(sim.pose.translation.x > 5.0);
    }

    #[test]
    fn bad_target_is_an_error() {
        let sim = at(0.0, 0.0, 0.0);
        let mut seq = ActionSequence::new(
            TacticalParams::default(),
            [Action::GoTo {
                target: Point2::new(f64::NAN, 0.0),
            }],
        )
        .unwrap();
        assert!(seq.step(&sim.input()).is_err());
    }
}
