//! A simulated person driving with the IntellWheels head cap (thesis 3.3.1, 3.7.1): the
//! accelerometer's head tilt becomes linear and angular speed. The model follows a closed circuit
//! by pure pursuit, then degrades the intended command the way a head-gesture input does:
//! - reaction delay: the cap outputs what the person intended `reaction_delay_s` ago;
//! - tremor: correlated (first-order autoregressive) noise on both speeds;
//! - attention lapses: now and then the head stays put and the last command is held;
//! - coarse steering: speeds snap to a few levels (stop/half/full, five turn rates).
//!
//! When the chair makes no progress for a while (stuck against something) the person backs off and
//! tries again. Every person is a [`DriverProfile`] drawn from a seed; the same seed gives the same
//! person, and the same inputs give the same commands.

use std::collections::VecDeque;
use std::f64::consts::FRAC_PI_2;

use nalgebra::{Isometry2, Point2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::tactical::wrap_angle;
use crate::{ControlError, VelocityCommand};

/// A closed loop of waypoints in the world frame, driven in order, back to the first.
#[derive(Debug, Clone, PartialEq)]
pub struct Circuit {
    waypoints: Vec<Point2<f64>>,
    /// `starts[i]`: arc length at waypoint i; last entry = total length.
    starts: Vec<f64>,
}

impl Circuit {
    /// A circuit through `waypoints` (closed back to the first).
    pub fn new(waypoints: Vec<Point2<f64>>) -> Result<Self, ControlError> {
        for p in &waypoints {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(ControlError::NonFinitePose {
                    what: "waypoint",
                    x: p.x,
                    y: p.y,
                    theta: 0.0,
                });
            }
        }
        let mut starts = vec![0.0];
        for i in 0..waypoints.len() {
            let next = waypoints[(i + 1) % waypoints.len()];
            starts.push(starts[i] + (next - waypoints[i]).norm());
        }
        if waypoints.len() < 2 || starts.last().copied().unwrap_or(0.0) <= 0.0 {
            return Err(ControlError::ShortCircuit {
                count: waypoints.len(),
            });
        }
        Ok(Circuit { waypoints, starts })
    }

    /// Length of one lap, m.
    pub fn length_m(&self) -> f64 {
        self.starts[self.waypoints.len()]
    }

    /// The waypoints.
    pub fn waypoints(&self) -> &[Point2<f64>] {
        &self.waypoints
    }

    /// The point at arc length `s` (any real; wraps around laps).
    pub fn point_at(&self, s: f64) -> Point2<f64> {
        let s = s.rem_euclid(self.length_m());
        let i = self
            .starts
            .partition_point(|&start| start <= s)
            .saturating_sub(1)
            .min(self.waypoints.len() - 1);
        let a = self.waypoints[i];
        let b = self.waypoints[(i + 1) % self.waypoints.len()];
        let seg = self.starts[i + 1] - self.starts[i];
        if seg <= 0.0 {
            a
        } else {
            a + (b - a) * ((s - self.starts[i]) / seg)
        }
    }

    /// Direction of travel at arc length `s`, rad.
    pub fn heading_at(&self, s: f64) -> f64 {
        let d = self.point_at(s + 0.05) - self.point_at(s - 0.05);
        d.y.atan2(d.x)
    }

    /// The arc length (unwrapped, near `hint`) of the circuit point closest to `p`, searching
    /// `[hint - behind, hint + ahead]` in 5 cm steps refined on the best segment.
    fn project_near(&self, p: Point2<f64>, hint: f64, behind: f64, ahead: f64) -> f64 {
        let step = 0.05;
        let count = ((behind + ahead) / step).ceil() as usize;
        (0..=count)
            .map(|k| hint - behind + k as f64 * step)
            .min_by(|a, b| {
                (self.point_at(*a) - p)
                    .norm_squared()
                    .total_cmp(&(self.point_at(*b) - p).norm_squared())
            })
            .unwrap_or(hint)
    }
}

/// One simulated person: how they drive with the head cap.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DriverProfile {
    /// Speed they aim for on straights, m/s.
    pub preferred_speed_mps: f64,
    /// Delay between intending and the cap's output, s.
    pub reaction_delay_s: f64,
    /// Standard deviation of the turn-rate tremor, rad/s.
    pub tremor_radps: f64,
    /// Standard deviation of the speed tremor, m/s.
    pub tremor_mps: f64,
    /// Correlation time of the tremor, s.
    pub tremor_time_s: f64,
    /// Mean attention lapses per second.
    pub lapse_rate_hz: f64,
    /// Length of a lapse, s.
    pub lapse_s: f64,
    /// Pure-pursuit lookahead, m.
    pub lookahead_m: f64,
    /// Fastest turn the cap commands, rad/s (full tilt).
    pub max_angular_radps: f64,
    /// Turn levels each side of straight (2 = half and full tilt).
    pub turn_levels: u32,
}

impl DriverProfile {
    /// A person drawn from `seed`: 8 seeds give 8 different volunteers.
    pub fn from_seed(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ PROFILE_SEED_MIX);
        DriverProfile {
            preferred_speed_mps: rng.random_range(0.55..0.85),
            reaction_delay_s: rng.random_range(0.3..0.7),
            tremor_radps: rng.random_range(0.15..0.4),
            tremor_mps: rng.random_range(0.03..0.08),
            tremor_time_s: rng.random_range(0.3..0.8),
            lapse_rate_hz: rng.random_range(0.02..0.08),
            lapse_s: rng.random_range(0.5..1.2),
            lookahead_m: rng.random_range(0.8..1.3),
            max_angular_radps: 1.0,
            turn_levels: 2,
        }
    }
}

/// Mixed into profile seeds so a person's traits and their drive noise are independent streams.
const PROFILE_SEED_MIX: u64 = 0x9e37_79b9_7f4a_7c15;

/// What the driver does in one period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriverOutput {
    /// The head cap's command.
    pub command: VelocityCommand,
    /// Laps completed so far.
    pub laps: usize,
    /// Distance along the circuit since the first period (all laps), m.
    pub progress_m: f64,
}

/// The driver's state between periods.
#[derive(Debug, Clone)]
pub struct HeadGestureDriver {
    profile: DriverProfile,
    circuit: Circuit,
    rng: ChaCha8Rng,
    progress_m: f64,
    start_m: Option<f64>,
    intended: VecDeque<(u64, VelocityCommand)>,
    tremor: VelocityCommand,
    held: VelocityCommand,
    lapse_until_ns: u64,
    reverse_until_ns: u64,
    reverse_turn_radps: f64,
    checkpoint: (u64, f64),
    last_ns: Option<u64>,
}

/// Seconds without 20 cm of progress after which the person backs off.
const STUCK_S: f64 = 4.0;
/// How long they back off, s.
const REVERSE_S: f64 = 1.5;

impl HeadGestureDriver {
    /// A person with `profile` starting a lap of `circuit`, drive noise drawn from `seed`.
    pub fn new(profile: DriverProfile, circuit: Circuit, seed: u64) -> Self {
        HeadGestureDriver {
            profile,
            circuit,
            rng: ChaCha8Rng::seed_from_u64(seed),
            progress_m: 0.0,
            start_m: None,
            intended: VecDeque::new(),
            tremor: VelocityCommand::STOP,
            held: VelocityCommand::STOP,
            lapse_until_ns: 0,
            reverse_until_ns: 0,
            reverse_turn_radps: 0.0,
            checkpoint: (0, 0.0),
            last_ns: None,
        }
    }

    /// The person's traits.
    pub fn profile(&self) -> &DriverProfile {
        &self.profile
    }

    /// The circuit driven.
    pub fn circuit(&self) -> &Circuit {
        &self.circuit
    }

    /// One period at `time_ns` with the chair at `t_world_chair` (the person sees the real pose).
    pub fn step(
        &mut self,
        time_ns: u64,
        t_world_chair: Isometry2<f64>,
    ) -> Result<DriverOutput, ControlError> {
        let position = Point2::from(t_world_chair.translation.vector);
        let heading = t_world_chair.rotation.angle();
        if !(position.x.is_finite() && position.y.is_finite() && heading.is_finite()) {
            return Err(ControlError::NonFinitePose {
                what: "chair pose",
                x: position.x,
                y: position.y,
                theta: heading,
            });
        }
        let dt_s = self
            .last_ns
            .map_or(0.0, |last| time_ns.saturating_sub(last) as f64 * 1e-9);
        self.last_ns = Some(time_ns);
        let start_m = match self.start_m {
            Some(start) => start,
            None => {
                // First period: find the chair anywhere on the loop; laps count from there.
                let start = self
                    .circuit
                    .project_near(position, 0.0, 0.0, self.circuit.length_m());
                self.progress_m = start;
                self.checkpoint = (time_ns, start);
                *self.start_m.insert(start)
            }
        };
        self.progress_m = self
            .circuit
            .project_near(position, self.progress_m, 0.5, 1.5)
            .max(self.progress_m - 0.5);
        let intended = self.intend(time_ns, position, heading);
        self.intended.push_back((time_ns, intended));
        let delay_ns = (self.profile.reaction_delay_s * 1e9) as u64;
        // The cap lags: use the newest intention at least `delay` old.
        while self.intended.len() > 1 && self.intended[1].0 + delay_ns <= time_ns {
            self.intended.pop_front();
        }
        let delayed = match self.intended.front() {
            Some(&(t, c)) if t + delay_ns <= time_ns => c,
            _ => VelocityCommand::STOP,
        };
        let command = self.head_cap(time_ns, dt_s, delayed);
        let driven_m = self.progress_m - start_m;
        let laps = (driven_m / self.circuit.length_m()).floor().max(0.0) as usize;
        Ok(DriverOutput {
            command,
            laps,
            progress_m: driven_m,
        })
    }

    /// What the person wants now: pure pursuit along the circuit, or backing off when stuck.
    fn intend(&mut self, time_ns: u64, position: Point2<f64>, heading: f64) -> VelocityCommand {
        let p = self.profile;
        if time_ns < self.reverse_until_ns {
            return VelocityCommand::new(-0.25, self.reverse_turn_radps);
        }
        let target = self.circuit.point_at(self.progress_m + p.lookahead_m);
        let to_target = target - position;
        let alpha = wrap_angle(to_target.y.atan2(to_target.x) - heading);
        if self.progress_m > self.checkpoint.1 + 0.2 {
            self.checkpoint = (time_ns, self.progress_m);
        } else if time_ns.saturating_sub(self.checkpoint.0) as f64 * 1e-9 > STUCK_S {
            self.reverse_until_ns = time_ns + (REVERSE_S * 1e9) as u64;
            self.reverse_turn_radps = if alpha > 0.0 { -0.5 } else { 0.5 };
            self.checkpoint = (self.reverse_until_ns, self.progress_m);
            return VelocityCommand::new(-0.25, self.reverse_turn_radps);
        }
        // Slow down for sharp turns, turn in place when facing away.
        let speed = p.preferred_speed_mps * (1.0 - (alpha.abs() / FRAC_PI_2).min(1.0)).max(0.0);
        let angular = 2.0 * p.preferred_speed_mps.max(0.3) * alpha.sin() / p.lookahead_m;
        VelocityCommand::new(speed, angular)
    }

    /// The head cap: tremor, lapses and coarse levels on top of the delayed intention.
    fn head_cap(&mut self, time_ns: u64, dt_s: f64, delayed: VelocityCommand) -> VelocityCommand {
        let p = self.profile;
        if time_ns < self.lapse_until_ns {
            return self.held;
        }
        if self
            .rng
            .random_bool((p.lapse_rate_hz * dt_s).clamp(0.0, 1.0))
        {
            self.lapse_until_ns = time_ns + (p.lapse_s * 1e9) as u64;
            return self.held;
        }
        // First-order autoregressive tremor with stationary deviation tremor_*.
        let keep = (-dt_s / p.tremor_time_s).exp();
        let fresh = (1.0 - keep * keep).sqrt();
        self.tremor.linear_mps =
            keep * self.tremor.linear_mps + fresh * p.tremor_mps * self.gaussian();
        self.tremor.angular_radps =
            keep * self.tremor.angular_radps + fresh * p.tremor_radps * self.gaussian();
        let linear = delayed.linear_mps + self.tremor.linear_mps;
        let angular = delayed.angular_radps + self.tremor.angular_radps;
        // Coarse levels: stop / half / full tilt forward, one reverse level; n turn levels a side.
        let full = p.preferred_speed_mps;
        let linear = if linear < -0.1 {
            -0.25
        } else {
            (linear / (full / 2.0)).round().clamp(0.0, 2.0) * full / 2.0
        };
        let levels = f64::from(p.turn_levels.max(1));
        let step = p.max_angular_radps / levels;
        let angular = (angular / step).round().clamp(-levels, levels) * step;
        self.held = VelocityCommand::new(linear, angular);
        self.held
    }

    /// A standard normal draw (Box-Muller).
    fn gaussian(&mut self) -> f64 {
        let u1: f64 = self.rng.random_range(f64::MIN_POSITIVE..1.0);
        let u2: f64 = self.rng.random();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn square() -> Circuit {
        Circuit::new(vec![
            Point2::new(0.0, 0.0),
            Point2::new(6.0, 0.0),
            Point2::new(6.0, 4.0),
            Point2::new(0.0, 4.0),
        ])
        .unwrap()
    }

    /// Drives a unicycle in free space with the driver; returns laps done and the worst distance
    /// from the circuit.
    fn drive(seed: u64, seconds: f64) -> (usize, f64) {
        let circuit = square();
        let mut driver =
            HeadGestureDriver::new(DriverProfile::from_seed(seed), circuit.clone(), seed);
        let mut pose = Isometry2::new(Vector2::zeros(), 0.0);
        let mut worst: f64 = 0.0;
        let mut laps = 0;
        let dt = 0.05;
        for k in 0..(seconds / dt) as u64 {
            let out = driver.step(k * 50_000_000, pose).unwrap();
            laps = out.laps;
            let h = pose.rotation.angle();
            let (v, w) = (out.command.linear_mps, out.command.angular_radps);
            pose = Isometry2::new(
                pose.translation.vector + Vector2::new(v * h.cos(), v * h.sin()) * dt,
                h + w * dt,
            );
            let p = Point2::from(pose.translation.vector);
            let near = circuit.project_near(p, out.progress_m, 1.0, 1.0);
            worst = worst.max((circuit.point_at(near) - p).norm());
        }
        (laps, worst)
    }

    #[test]
    fn drivers_complete_laps_near_the_circuit() {
        for seed in 0..4 {
            let (laps, worst) = drive(seed, 120.0);
            assert!(laps >= 2, "seed {seed}: {laps} laps");
            assert!(worst < 1.0, "seed {seed}: strayed {worst} m");
        }
    }

    #[test]
    fn same_seed_same_commands_and_levels_are_coarse() {
        let run = |seed| {
            let mut d = HeadGestureDriver::new(DriverProfile::from_seed(seed), square(), seed);
            (0..200u64)
                .map(|k| {
                    d.step(
                        k * 50_000_000,
                        Isometry2::new(Vector2::new(0.01 * k as f64, 0.0), 0.0),
                    )
                    .unwrap()
                    .command
                })
                .collect::<Vec<_>>()
        };
        let a = run(7);
        assert_eq!(a, run(7));
        assert_ne!(a, run(8));
        let levels: std::collections::BTreeSet<i64> = a
            .iter()
            .map(|c| (c.angular_radps * 1000.0).round() as i64)
            .collect();
        assert!(levels.len() <= 5, "{levels:?}");
    }

    #[test]
    fn reaction_delay_holds_the_start() {
        let mut d = HeadGestureDriver::new(DriverProfile::from_seed(1), square(), 1);
        let first = d.step(0, Isometry2::identity()).unwrap();
        assert_eq!(first.command, VelocityCommand::STOP);
    }

    #[test]
    fn degenerate_circuit_is_an_error() {
        assert!(Circuit::new(vec![Point2::new(1.0, 1.0), Point2::new(1.0, 1.0)]).is_err());
        assert!(Circuit::new(vec![Point2::new(1.0, 1.0)]).is_err());
    }
}
