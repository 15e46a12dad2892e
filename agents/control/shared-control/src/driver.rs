//! A simulated person who sees (thesis 3.7.1's volunteers, modelled): they follow a closed
//! circuit, perceive the clearance around the chair, slow down and steer around obstacles
//! imperfectly, and react when the chair does not do what they asked.
//!
//! Model, per control period:
//! - **route**: pure pursuit of a point `lookahead_m` ahead on the circuit ([`DriverModel::Steady`]:
//!   shifted across it by the person's own line, which wanders with deviation [`LINE_SPREAD_M`]
//!   and correlation time [`LINE_TIME_S`]: the volunteers judged distances poorly in the
//!   simulator's view, so nobody holds the drawn line to the centimetre);
//! - **perception**: the true clearance between the chair's footprint and the nearest solid thing
//!   along a fan of bearings (given by the caller), each reading scaled by `1 + noise`, noise
//!   normal with the driver's `perception_noise` (people misjudge depth; the thesis's volunteers
//!   said so of its simulator, section 3.8);
//! - **avoidance**: the person never steers towards a side (bearings 0-110 degrees left or
//!   right) whose nearest clearance is under `comfort_m`, and steers away from it the harder the
//!   closer it is (`avoid_gain`); with both sides close they balance; the speed falls with the
//!   clearance ahead, down to a stop at `stop_m`, and in narrow places;
//! - **reacting when slowed**: when the chair moves at under 40 % of the commanded speed for
//!   0.8 s, the person backs off for a second if something is right ahead, else edges towards
//!   the most open bearing for a second; when there is no progress for 5 s they back off;
//! - **a bump** ([`DriverModel::Steady`] only): the person feels the chair touch something
//!   ([`Perception::touching`]), backs straight off for [`BUMP_BACK_S`] if it was in front, and
//!   within [`WARY_WITHIN_M`] of any bump remembered this trial drives warily: slowly
//!   ([`WARY_INPUT`]), with gentle corrections ([`WARY_GAIN`]), without turning on the spot
//!   ([`WARY_TURN`]), and judging "ahead" by the bearings nearest straight ahead
//!   ([`WARY_AHEAD_RAD`]). Traced: without it a person stopped by a front corner in a narrow
//!   passage turned on the spot, swung the other corner into the other side, and repeated that
//!   dozens of times (docs/results/shared-control.md);
//! - **reaction delay**: the device outputs what the person intended `reaction_delay_s` ago;
//! - **device**: a joystick (proportional, with tremor) or the head cap (tremor, lapses, the
//!   forward axis on three speed levels (a third, two thirds and full tilt) besides stop, and one
//!   reverse level; the
//!   lateral axis proportional with a dead zone). The thesis's text calls the cap a proportional
//!   controller (3.3.1); the three levels are the project's reading, not the text's.
//!
//! How the judgement moves in time is the [`DriverModel`]. The default,
//! [`DriverModel::Steady`], is a person who judges steadily over a reaction time, as thesis
//! 3.7.1's volunteers, told that safety came first and given 10 minutes of practice, would: each
//! bearing's misjudgement is an Ornstein-Uhlenbeck process (correlation time 0.3-0.7 s) whose
//! deviation is [`PERSISTING_SPREAD`] of the per-period one (the per-period error averaged over
//! about ten periods), and a head-cap step changes only when the wish leaves its band by
//! [`STEP_MARGIN`] after a least dwell of 0.42-0.78 s (the lateral dead zone has the same
//! margin). [`DriverModel::PerPeriod`] (`--driver-model per-period`, the default until this
//! calibration) draws each bearing's misjudgement afresh every period, so by an obstacle the
//! head cap's forward step flickers (about 3 switches a second, traced on the cluttered
//! circuits). Why the steady model was calibrated this way, part by part, is on the results page
//! (docs/results/shared-control.md).
//!
//! Every person is a [`DriverProfile`] drawn from a seed around a personal `skill` in [0, 1]:
//! skill shortens the delay and lowers perception noise and tremor. Inputs and outputs are 2-D
//! input vectors (x forward, y left, each in [-1, 1]); [`crate::JoystickMapping`] turns them
//! into speeds. The same seed and inputs give the same outputs.
use std::collections::VecDeque;
use std::f64::consts::FRAC_PI_2;

use nalgebra::{Isometry2, Point2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::ControlError;
use crate::tactical::wrap_angle;

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

/// The input device the person drives with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InputDevice {
    /// The IntellWheels head cap (thesis 3.3.1), as the volunteers drove in 3.7.1.
    HeadCap,
    /// A proportional joystick.
    Joystick,
}

/// How the person's judgement moves in time.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DriverModel {
    /// Each bearing's misjudgement drawn afresh every period, head-cap steps taken as they come:
    /// at a 50 ms period the cap's forward step flickers by obstacles (about 3 switches a
    /// second), which the thesis's volunteers did not do. The default until the steady model was
    /// calibrated; kept as a named variant.
    PerPeriod,
    /// A person whose judgement is steady over a reaction time: each bearing's misjudgement is a
    /// first-order (Ornstein-Uhlenbeck) process with correlation time
    /// [`DriverProfile::perception_time_s`] and deviation [`PERSISTING_SPREAD`] times
    /// [`DriverProfile::perception_noise`]; a head-cap step changes only when the wish leaves
    /// the step's band by [`STEP_MARGIN`] and the step has been kept
    /// [`DriverProfile::dwell_s`]; the lateral dead zone has the same margin.
    #[default]
    Steady,
}

/// One simulated person: how they perceive and drive.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DriverProfile {
    /// Overall skill, 0 (poor) to 1 (good); the traits below are drawn around it.
    pub skill: f64,
    /// Forward deflection aimed for on straights, 0-1.
    pub preferred_input: f64,
    /// Delay between intending and the device's output, s.
    pub reaction_delay_s: f64,
    /// Relative standard deviation of a perceived clearance drawn afresh each period
    /// ([`DriverModel::PerPeriod`]; the steady model's persisting one is
    /// [`PERSISTING_SPREAD`] of it).
    pub perception_noise: f64,
    /// Clearance the person tries to keep from obstacles, m.
    pub comfort_m: f64,
    /// Clearance ahead at which the person stops, m.
    pub stop_m: f64,
    /// Clearance ahead from which the person starts slowing, m.
    pub slow_m: f64,
    /// Standard deviation of the input tremor, deflection units.
    pub tremor: f64,
    /// Correlation time of the tremor, s.
    pub tremor_time_s: f64,
    /// Mean attention lapses per second (head cap only).
    pub lapse_rate_hz: f64,
    /// Length of a lapse, s.
    pub lapse_s: f64,
    /// Pure-pursuit lookahead, m.
    pub lookahead_m: f64,
    /// How strongly perceived obstacles turn the person, deflection per unit weight.
    pub avoid_gain: f64,
    /// [`DriverModel::Steady`]: correlation time of each bearing's misjudgement, s.
    pub perception_time_s: f64,
    /// [`DriverModel::Steady`]: least time a head-cap step is kept before it changes, s.
    pub dwell_s: f64,
}

impl DriverProfile {
    /// A person drawn from `seed`: 8 seeds give 8 different volunteers.
    pub fn from_seed(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ PROFILE_SEED_MIX);
        let skill: f64 = rng.random_range(0.0..1.0);
        let mut around =
            |centre: f64, spread: f64| centre * rng.random_range(1.0 - spread..1.0 + spread);
        DriverProfile {
            skill,
            preferred_input: around(0.75, 0.15).min(1.0),
            reaction_delay_s: around(0.6 - 0.3 * skill, 0.2),
            perception_noise: around(0.5 - 0.3 * skill, 0.2),
            comfort_m: around(0.15, 0.3),
            stop_m: around(0.08, 0.3),
            slow_m: around(0.5, 0.2),
            tremor: around(0.12 - 0.06 * skill, 0.2),
            tremor_time_s: around(0.5, 0.4),
            lapse_rate_hz: around(0.1 - 0.06 * skill, 0.3),
            lapse_s: around(0.8, 0.3),
            lookahead_m: around(1.0, 0.2),
            avoid_gain: around(0.6, 0.3),
            // Drawn last so the per-period model's people keep their traits.
            perception_time_s: around(0.5, 0.4),
            dwell_s: around(0.6, 0.3),
        }
    }
}

/// Mixed into drive seeds for the stream of the person's line.
const LINE_SEED_MIX: u64 = 0x5851_f42d_4c95_7f2d;

/// Mixed into profile seeds so a person's traits and their drive noise are independent streams.
const PROFILE_SEED_MIX: u64 = 0x9e37_79b9_7f4a_7c15;

/// What the person sees in one period: the clearance from the chair's footprint to the nearest
/// solid thing along each bearing (chair frame, rad, 0 = ahead, positive = left), m.
#[derive(Debug, Clone, Copy)]
pub struct Perception<'a> {
    /// Bearings, rad.
    pub bearings_rad: &'a [f64],
    /// Clearance along each bearing, m (`f64::INFINITY` for nothing in sight).
    pub clearance_m: &'a [f64],
    /// The chair is pressed against something: the person feels the bump (a new contact is
    /// the rising edge, as the simulator counts collisions).
    pub touching: bool,
}

/// What the driver does in one period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriverOutput {
    /// The device's input vector (x forward, y left, each in [-1, 1]).
    pub input: Vector2<f64>,
    /// Laps completed so far.
    pub laps: usize,
    /// Distance along the circuit since the first period (all laps), m.
    pub progress_m: f64,
}

/// The driver's state between periods.
#[derive(Debug, Clone)]
pub struct SeeingDriver {
    profile: DriverProfile,
    device: InputDevice,
    circuit: Circuit,
    rng: ChaCha8Rng,
    progress_m: f64,
    start_m: Option<f64>,
    intended: VecDeque<(u64, Vector2<f64>)>,
    tremor: Vector2<f64>,
    held: Vector2<f64>,
    lapse_until_ns: u64,
    reverse_until_ns: u64,
    reverse_turn: f64,
    detour_until_ns: u64,
    detour_turn: f64,
    slowed_since_ns: Option<u64>,
    checkpoint: (u64, f64),
    last_ns: Option<u64>,
    model: DriverModel,
    /// [`DriverModel::Steady`]: each bearing's relative misjudgement.
    misjudged: Vec<f64>,
    /// [`DriverModel::Steady`]: when the head-cap step last changed.
    step_since_ns: u64,
    /// [`DriverModel::Steady`]: where the chair was at each bump this trial (world frame, the
    /// newest [`MAX_BUMPS`]).
    bumps: Vec<Point2<f64>>,
    /// Whether the chair was touching something last period.
    touching: bool,
    /// [`DriverModel::Steady`]: how far left of the drawn route the person steers, m (`None`
    /// before the first period).
    line_m: Option<f64>,
    /// [`DriverModel::Steady`]: the line's own stream, so the other draws stay as they were.
    line_rng: ChaCha8Rng,
}

/// [`DriverModel::Steady`]: bumps a person remembers at once (the oldest is forgotten first).
const MAX_BUMPS: usize = 32;
/// [`DriverModel::Steady`]: within this of a remembered bump the person drives warily, m. The
/// repeated contacts traced on the ward corridor were 0.3-3 m apart along one passage.
pub const WARY_WITHIN_M: f64 = 2.5;
/// [`DriverModel::Steady`]: how long the person backs straight off after bumping something in
/// front, s.
pub const BUMP_BACK_S: f64 = 0.5;
/// [`DriverModel::Steady`]: when wary, only bearings within this of straight ahead count as
/// "ahead" (the 0 and 15 degree bearings), rad: in a passage the 30 degree bearings see the side
/// walls past the front corners, and stopping on them left the person turning on the spot.
pub const WARY_AHEAD_RAD: f64 = 0.27;
/// [`DriverModel::Steady`]: when wary, the avoidance gain is scaled by this: small corrections,
/// not a swing from one side to the other.
pub const WARY_GAIN: f64 = 0.25;
/// [`DriverModel::Steady`]: when wary, the forward wish is at most this (just above the head
/// cap's lowest step, a third).
pub const WARY_INPUT: f64 = 0.34;
/// [`DriverModel::Steady`]: when wary, the turn wish is at most this, or the forward wish if
/// larger: no turning on the spot, which swings the corners into what is beside them.
pub const WARY_TURN: f64 = 0.15;
/// [`DriverModel::Steady`]: deviation of the person's line from the drawn route, m. The thesis's
/// volunteers said the simulator's 3-D view gave no accurate sense of depth and distance to
/// objects (3.8): a person places the chair across a passage by judging the distance to what is
/// beside it, so they hold a line of their own, the same for every person (the view, not the
/// person, was poor). Calibrated on the thesis-like circuit: at 0.12 m about 7 in 8 drivers
/// collide at least once, as the volunteers did; the guarded policy, serving the same people,
/// then loses laps in the two rooms (docs/results/shared-control.md).
pub const LINE_SPREAD_M: f64 = 0.12;
/// [`DriverModel::Steady`]: correlation time of the person's line, s: a judgement of the room
/// that persists over seconds, not a glance.
pub const LINE_TIME_S: f64 = 3.0;
/// Seconds without 20 cm of progress after which the person backs off.
const STUCK_S: f64 = 5.0;
/// How long they back off or detour, s.
const REACT_S: f64 = 1.0;
/// Seconds at under [`SLOWED_RATIO`] of the commanded speed after which the person reacts.
const SLOWED_S: f64 = 0.8;
/// Measured / commanded speed under which the person feels slowed.
const SLOWED_RATIO: f64 = 0.4;
/// Bearings within this of straight ahead make up the clearance ahead, rad (35 degrees).
const AHEAD_RAD: f64 = 0.61;
/// Lateral head tilt below this is read as straight (head cap dead zone), deflection units.
const DEAD_ZONE: f64 = 0.1;
/// [`DriverModel::Steady`]: how far past a head-cap step's band (or the dead zone's edge) the
/// wish must go before the step changes, deflection units (a quarter of a step's width).
pub const STEP_MARGIN: f64 = 0.1;
/// [`DriverModel::Steady`]: deviation of the persisting misjudgement as a fraction of the
/// per-period one. A fresh error every 50 ms averaged over a reaction time (about ten periods)
/// has a third of its deviation; a person who judges over that time errs about that much, and
/// persistently. Measured: at the full per-period deviation the guarded policy lost 6 of 16 laps
/// in the two rooms (drivers deflected by a misjudgement held for half a second into spots they
/// could not turn out of); at a third, 16 of 16 (docs/results/shared-control.md).
pub const PERSISTING_SPREAD: f64 = 1.0 / 3.0;

impl SeeingDriver {
    /// A person with `profile` on `device` starting a lap of `circuit`, drive noise from `seed`.
    pub fn new(profile: DriverProfile, device: InputDevice, circuit: Circuit, seed: u64) -> Self {
        SeeingDriver {
            profile,
            device,
            circuit,
            rng: ChaCha8Rng::seed_from_u64(seed),
            progress_m: 0.0,
            start_m: None,
            intended: VecDeque::new(),
            tremor: Vector2::zeros(),
            held: Vector2::zeros(),
            lapse_until_ns: 0,
            reverse_until_ns: 0,
            reverse_turn: 0.0,
            detour_until_ns: 0,
            detour_turn: 0.0,
            slowed_since_ns: None,
            checkpoint: (0, 0.0),
            last_ns: None,
            model: DriverModel::default(),
            misjudged: Vec::new(),
            step_since_ns: 0,
            bumps: Vec::new(),
            touching: false,
            line_m: None,
            line_rng: ChaCha8Rng::seed_from_u64(seed ^ LINE_SEED_MIX),
        }
    }

    /// The same person with judgement moving as `model` says.
    pub fn with_model(mut self, model: DriverModel) -> Self {
        self.model = model;
        self
    }

    /// The person's traits.
    pub fn profile(&self) -> &DriverProfile {
        &self.profile
    }

    /// The circuit driven.
    pub fn circuit(&self) -> &Circuit {
        &self.circuit
    }

    /// One period at `time_ns` with the chair at `t_world_chair` moving at `speed_mps` (the
    /// person sees the real pose and feels the real speed) and seeing `perception`.
    pub fn step(
        &mut self,
        time_ns: u64,
        t_world_chair: Isometry2<f64>,
        speed_mps: f64,
        perception: &Perception<'_>,
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
        if perception.bearings_rad.len() != perception.clearance_m.len() {
            return Err(ControlError::UnpairedSamples {
                left: perception.bearings_rad.len(),
                right: perception.clearance_m.len(),
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
        self.react(time_ns, speed_mps, perception);
        self.feel(time_ns, position, perception);
        self.drift_line(dt_s);
        let intended = self.intend(time_ns, dt_s, position, heading, perception);
        self.intended.push_back((time_ns, intended));
        let delay_ns = (self.profile.reaction_delay_s * 1e9) as u64;
        // The device lags: use the newest intention at least `delay` old.
        while self.intended.len() > 1 && self.intended[1].0 + delay_ns <= time_ns {
            self.intended.pop_front();
        }
        let delayed = match self.intended.front() {
            Some(&(t, c)) if t + delay_ns <= time_ns => c,
            _ => Vector2::zeros(),
        };
        let input = self.device_output(time_ns, dt_s, delayed);
        let driven_m = self.progress_m - start_m;
        let laps = (driven_m / self.circuit.length_m()).floor().max(0.0) as usize;
        Ok(DriverOutput {
            input,
            laps,
            progress_m: driven_m,
        })
    }

    /// Notices being slowed or stuck and plans a detour or a back-off.
    fn react(&mut self, time_ns: u64, speed_mps: f64, perception: &Perception<'_>) {
        if time_ns < self.reverse_until_ns || time_ns < self.detour_until_ns {
            return;
        }
        let asked = self.held.x.max(0.0);
        // The device's forward deflection is compared with the speed it should give at 0.8 m/s
        // full scale; only the ratio matters, so the scale is the mapping's default.
        if asked > 0.2 && speed_mps.abs() < SLOWED_RATIO * asked * 0.8 {
            let since = *self.slowed_since_ns.get_or_insert(time_ns);
            if time_ns.saturating_sub(since) as f64 * 1e-9 > SLOWED_S {
                self.slowed_since_ns = None;
                let ahead = perception
                    .bearings_rad
                    .iter()
                    .zip(perception.clearance_m)
                    .filter(|(b, _)| b.abs() <= AHEAD_RAD)
                    .map(|(_, c)| *c)
                    .fold(f64::INFINITY, f64::min);
                if ahead < self.profile.stop_m {
                    // Up against something: back off, turning away from the nearer side.
                    self.back_off(time_ns, perception);
                } else {
                    // Held back: edge towards the most open bearing within 60 degrees.
                    let open = perception
                        .bearings_rad
                        .iter()
                        .zip(perception.clearance_m)
                        .filter(|(b, _)| b.abs() <= 1.05)
                        .max_by(|a, b| a.1.total_cmp(b.1))
                        .map_or(0.0, |(b, _)| *b);
                    self.detour_turn = 0.4 * open.signum();
                    self.detour_until_ns = time_ns + (REACT_S * 1e9) as u64;
                }
            }
        } else {
            self.slowed_since_ns = None;
        }
        if self.progress_m > self.checkpoint.1 + 0.2 {
            self.checkpoint = (time_ns, self.progress_m);
        } else if time_ns.saturating_sub(self.checkpoint.0) as f64 * 1e-9 > STUCK_S {
            self.back_off(time_ns, perception);
        }
    }

    /// [`DriverModel::Steady`]: a new bump is remembered where it happened and, if it was in
    /// front, the person backs straight off for [`BUMP_BACK_S`].
    fn feel(&mut self, time_ns: u64, position: Point2<f64>, perception: &Perception<'_>) {
        let new = perception.touching && !self.touching;
        self.touching = perception.touching;
        if !new || self.model != DriverModel::Steady {
            return;
        }
        if self.bumps.len() == MAX_BUMPS {
            self.bumps.remove(0);
        }
        self.bumps.push(position);
        // The person knows where they bumped: the bearing of the least true clearance.
        let touched = perception
            .bearings_rad
            .iter()
            .zip(perception.clearance_m)
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map_or(0.0, |(b, _)| *b);
        if touched.abs() < FRAC_PI_2 {
            // Straight: turning while backing swings a front corner too (tried, more contacts).
            self.reverse_turn = 0.0;
            self.reverse_until_ns = time_ns + (BUMP_BACK_S * 1e9) as u64;
            self.checkpoint = (self.reverse_until_ns, self.progress_m);
            self.slowed_since_ns = None;
        }
    }

    /// Whether a remembered bump is within [`WARY_WITHIN_M`] of `position`.
    fn wary_at(&self, position: Point2<f64>) -> bool {
        self.bumps
            .iter()
            .any(|b| (b - position).norm() < WARY_WITHIN_M)
    }

    /// Reverses for [`REACT_S`], the rear swinging towards the more open side.
    fn back_off(&mut self, time_ns: u64, perception: &Perception<'_>) {
        let (left, right) = side_clearance(perception);
        self.reverse_turn = if left < right { -0.4 } else { 0.4 };
        self.reverse_until_ns = time_ns + (REACT_S * 1e9) as u64;
        self.checkpoint = (self.reverse_until_ns, self.progress_m);
    }

    /// What the person wants now, as an input vector.
    fn intend(
        &mut self,
        time_ns: u64,
        dt_s: f64,
        position: Point2<f64>,
        heading: f64,
        perception: &Perception<'_>,
    ) -> Vector2<f64> {
        let p = self.profile;
        if time_ns < self.reverse_until_ns {
            // Backing off: the chair's rear swings the other way, so turn the other way.
            return Vector2::new(-0.5, self.reverse_turn);
        }
        let wary = self.wary_at(position);
        let ahead_m = self.progress_m + p.lookahead_m;
        let mut target = self.circuit.point_at(ahead_m);
        if self.model == DriverModel::Steady {
            let across = self.circuit.heading_at(ahead_m) + FRAC_PI_2;
            target += Vector2::new(across.cos(), across.sin()) * self.line_m.unwrap_or(0.0);
        }
        let to_target = target - position;
        let alpha = wrap_angle(to_target.y.atan2(to_target.x) - heading);
        // Perceived clearances, each misjudged by its own factor.
        let mut ahead = f64::INFINITY;
        let (mut left, mut right) = (f64::INFINITY, f64::INFINITY);
        let ahead_rad = if wary { WARY_AHEAD_RAD } else { AHEAD_RAD };
        self.misjudge(dt_s, perception.bearings_rad.len());
        for (i, (&bearing, &clearance)) in perception
            .bearings_rad
            .iter()
            .zip(perception.clearance_m)
            .enumerate()
        {
            let error = match self.model {
                DriverModel::PerPeriod => p.perception_noise * self.gaussian(),
                DriverModel::Steady => self.misjudged[i],
            };
            let seen = (clearance * (1.0 + error)).max(0.0);
            if bearing.abs() <= ahead_rad {
                ahead = ahead.min(seen);
            }
            if bearing > 0.0 && bearing <= 1.9 {
                left = left.min(seen);
            } else if (-1.9..0.0).contains(&bearing) {
                right = right.min(seen);
            }
        }
        let narrowest = left.min(right);
        // Pure pursuit at the speed they mean to go (full deflection taken as about 1 rad/s).
        let pursuit = 2.0 * (0.8 * p.preferred_input).max(0.3) * alpha.sin() / p.lookahead_m;
        let mut turn = pursuit.clamp(-1.0, 1.0);
        // Never towards a side closer than comfort; away from it the closer it is.
        let gain = if wary {
            p.avoid_gain * WARY_GAIN
        } else {
            p.avoid_gain
        };
        let urge = |c: f64| gain * (1.0 - c / p.comfort_m).max(0.0);
        let (away_from_left, away_from_right) = (urge(left), urge(right));
        if away_from_left > 0.0 && away_from_right > 0.0 {
            turn = away_from_right - away_from_left;
        } else if away_from_left > 0.0 {
            turn = turn.min(-away_from_left);
        } else if away_from_right > 0.0 {
            turn = turn.max(away_from_right);
        }
        if time_ns < self.detour_until_ns {
            turn = self.detour_turn;
        }
        // Slow down for obstacles ahead, in narrow places, and for sharp turns.
        let room = ((ahead - p.stop_m) / (p.slow_m - p.stop_m)).clamp(0.0, 1.0);
        let narrow = 0.5 + 0.5 * (narrowest / p.comfort_m).clamp(0.0, 1.0);
        let facing = (1.0 - alpha.abs() / FRAC_PI_2).clamp(0.0, 1.0);
        let mut forward = p.preferred_input * room.min(facing) * narrow;
        if wary {
            forward = forward.min(WARY_INPUT);
            let most = WARY_TURN.max(forward);
            turn = turn.clamp(-most, most);
        }
        Vector2::new(forward, turn.clamp(-1.0, 1.0))
    }

    /// [`DriverModel::Steady`]: moves each bearing's misjudgement one period on (stationary
    /// deviation [`PERSISTING_SPREAD`] times `perception_noise`, correlation time
    /// `perception_time_s`; a new bearing starts from a fresh draw).
    fn misjudge(&mut self, dt_s: f64, bearings: usize) {
        if self.model != DriverModel::Steady {
            return;
        }
        let p = self.profile;
        let keep = (-dt_s / p.perception_time_s).exp();
        let fresh = (1.0 - keep * keep).sqrt();
        let spread = PERSISTING_SPREAD * p.perception_noise;
        let old = self.misjudged.len().min(bearings);
        self.misjudged.truncate(bearings);
        for i in 0..old {
            self.misjudged[i] = keep * self.misjudged[i] + fresh * spread * self.gaussian();
        }
        while self.misjudged.len() < bearings {
            let draw = spread * self.gaussian();
            self.misjudged.push(draw);
        }
    }

    /// The device: tremor, and for the head cap lapses and levels, on the delayed intention.
    fn device_output(&mut self, time_ns: u64, dt_s: f64, delayed: Vector2<f64>) -> Vector2<f64> {
        let p = self.profile;
        if self.device == InputDevice::HeadCap {
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
        }
        // First-order autoregressive tremor with stationary deviation `tremor`.
        let keep = (-dt_s / p.tremor_time_s).exp();
        let fresh = (1.0 - keep * keep).sqrt();
        let noise = Vector2::new(self.gaussian(), self.gaussian());
        self.tremor = keep * self.tremor + fresh * p.tremor * noise;
        let raw = delayed + self.tremor;
        self.held = match self.device {
            InputDevice::Joystick => Vector2::new(raw.x.clamp(-1.0, 1.0), raw.y.clamp(-1.0, 1.0)),
            InputDevice::HeadCap => {
                let x = match self.model {
                    DriverModel::PerPeriod => cap_step(raw.x),
                    DriverModel::Steady => self.steady_step(time_ns, raw.x),
                };
                let dead_zone = match (self.model, self.held.y == 0.0) {
                    (DriverModel::PerPeriod, _) => DEAD_ZONE,
                    (DriverModel::Steady, true) => DEAD_ZONE + STEP_MARGIN,
                    (DriverModel::Steady, false) => (DEAD_ZONE - STEP_MARGIN).max(0.0),
                };
                let y = if raw.y.abs() < dead_zone {
                    0.0
                } else {
                    raw.y.clamp(-1.0, 1.0)
                };
                Vector2::new(x, y)
            }
        };
        self.held
    }

    /// [`DriverModel::Steady`]: the head cap's forward step with hysteresis and a least dwell.
    fn steady_step(&mut self, time_ns: u64, wish: f64) -> f64 {
        let now = self.held.x;
        let (low, high) = cap_band(now);
        let dwelt =
            time_ns.saturating_sub(self.step_since_ns) as f64 * 1e-9 >= self.profile.dwell_s;
        if !dwelt || (wish >= low - STEP_MARGIN && wish <= high + STEP_MARGIN) {
            return now;
        }
        self.step_since_ns = time_ns;
        cap_step(wish)
    }

    /// [`DriverModel::Steady`]: moves the person's line one period on (an Ornstein-Uhlenbeck
    /// process, deviation [`LINE_SPREAD_M`], correlation time [`LINE_TIME_S`], from a fresh draw).
    fn drift_line(&mut self, dt_s: f64) {
        if self.model != DriverModel::Steady {
            return;
        }
        let draw = LINE_SPREAD_M * iw_stats::standard_normal(&mut self.line_rng);
        self.line_m = Some(match self.line_m {
            Some(line) => {
                let keep = (-dt_s / LINE_TIME_S).exp();
                keep * line + (1.0 - keep * keep).sqrt() * draw
            }
            None => draw,
        });
    }

    /// A standard normal draw from the driver's own stream.
    fn gaussian(&mut self) -> f64 {
        iw_stats::standard_normal(&mut self.rng)
    }
}

/// The head cap's forward axis: stop or one of three speed levels (a third, two thirds, full
/// tilt); tilting back is the one reverse level.
fn cap_step(wish: f64) -> f64 {
    if wish < -0.25 {
        -0.5
    } else {
        (wish * 3.0).round().clamp(0.0, 3.0) / 3.0
    }
}

/// The wishes [`cap_step`] reads as `step`: (lowest, highest).
fn cap_band(step: f64) -> (f64, f64) {
    if step < 0.0 {
        (f64::NEG_INFINITY, -0.25)
    } else if step == 0.0 {
        (-0.25, 0.5 / 3.0)
    } else if step >= 1.0 {
        (2.5 / 3.0, f64::INFINITY)
    } else {
        (step - 0.5 / 3.0, step + 0.5 / 3.0)
    }
}

/// The smallest clearance on the left (bearings 30-150 degrees) and on the right, m.
fn side_clearance(perception: &Perception<'_>) -> (f64, f64) {
    let mut left = f64::INFINITY;
    let mut right = f64::INFINITY;
    for (&b, &c) in perception.bearings_rad.iter().zip(perception.clearance_m) {
        if (0.52..=2.62).contains(&b) {
            left = left.min(c);
        } else if (-2.62..=-0.52).contains(&b) {
            right = right.min(c);
        }
    }
    (left, right)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Circuit {
        Circuit::new(vec![
            Point2::new(0.0, 0.0),
            Point2::new(6.0, 0.0),
            Point2::new(6.0, 4.0),
            Point2::new(0.0, 4.0),
        ])
        .unwrap()
    }

    const BEARINGS: [f64; 4] = [0.0, FRAC_PI_2, -FRAC_PI_2, std::f64::consts::PI];
    const OPEN: [f64; 4] = [f64::INFINITY; 4];

    /// Drives a unicycle in free space (0.8 m/s, 1 rad/s full scale); returns laps done and the
    /// worst distance from the circuit.
    fn drive(seed: u64, device: InputDevice, seconds: f64) -> (usize, f64) {
        let circuit = square();
        let mut driver = SeeingDriver::new(
            DriverProfile::from_seed(seed),
            device,
            circuit.clone(),
            seed,
        );
        let mut pose = Isometry2::new(Vector2::zeros(), 0.0);
        let mut worst: f64 = 0.0;
        let mut laps = 0;
        let mut v = 0.0;
        let dt = 0.05;
        let seen = Perception {
            bearings_rad: &BEARINGS,
            clearance_m: &OPEN,
            touching: false,
        };
        for k in 0..(seconds / dt) as u64 {
            let out = driver.step(k * 50_000_000, pose, v, &seen).unwrap();
            laps = out.laps;
            let h = pose.rotation.angle();
            v = out.input.x * 0.8;
            let w = out.input.y;
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
    fn drivers_complete_laps_near_the_circuit_with_either_device() {
        for seed in 0..4 {
            for device in [InputDevice::HeadCap, InputDevice::Joystick] {
                let (laps, worst) = drive(seed, device, 120.0);
                assert!(laps >= 2, "seed {seed} {device:?}: {laps} laps");
                assert!(worst < 1.0, "seed {seed} {device:?}: strayed {worst} m");
            }
        }
    }

    /// Root mean square distance of a person of `seed` from the route over two minutes of
    /// free space on the joystick (no head-cap steps), m.
    fn rms_off_route(seed: u64, model: DriverModel) -> f64 {
        let circuit = Circuit::new(vec![Point2::new(0.0, 0.0), Point2::new(40.0, 0.0)]).unwrap();
        let mut driver = SeeingDriver::new(
            DriverProfile::from_seed(seed),
            InputDevice::Joystick,
            circuit.clone(),
            seed,
        )
        .with_model(model);
        let seen = Perception {
            bearings_rad: &BEARINGS,
            clearance_m: &OPEN,
            touching: false,
        };
        let (mut pose, mut v, dt) = (Isometry2::new(Vector2::new(1.0, 0.0), 0.0), 0.0, 0.05);
        let (mut sum, mut count) = (0.0, 0);
        for k in 0..2400u64 {
            let out = driver.step(k * 50_000_000, pose, v, &seen).unwrap();
            let h = pose.rotation.angle();
            v = out.input.x * 0.8;
            pose = Isometry2::new(
                pose.translation.vector + Vector2::new(v * h.cos(), v * h.sin()) * dt,
                h + out.input.y * dt,
            );
            // Only the outbound leg, after the start's settling.
            let (x, y) = (pose.translation.x, pose.translation.y);
            if k > 100 && (5.0..35.0).contains(&x) && h.cos() > 0.9 {
                sum += y * y;
                count += 1;
            }
        }
        assert!(count > 100, "seed {seed}: {count} samples on the leg");
        (sum / count as f64).sqrt()
    }

    #[test]
    fn a_steady_person_holds_a_line_of_their_own_the_per_period_one_the_drawn_route() {
        let mean = |model| (0..6).map(|seed| rms_off_route(seed, model)).sum::<f64>() / 6.0;
        let (steady, per_period) = (mean(DriverModel::Steady), mean(DriverModel::PerPeriod));
        // Pure pursuit a metre ahead filters the line: the chair follows most of its wander.
        // Without the line the steady person keeps about as close as the per-period one.
        assert!(
            steady > 0.75 * LINE_SPREAD_M && steady > 1.5 * per_period,
            "steady {steady} m off the route, per-period {per_period} m, line {LINE_SPREAD_M} m"
        );
    }

    fn first_outputs(seed: u64, device: InputDevice, clearance: &[f64; 4]) -> Vec<Vector2<f64>> {
        let mut d = SeeingDriver::new(DriverProfile::from_seed(seed), device, square(), seed);
        let seen = Perception {
            bearings_rad: &BEARINGS,
            clearance_m: clearance,
            touching: false,
        };
        (0..100u64)
            .map(|k| {
                let pose = Isometry2::new(Vector2::new(0.01 * k as f64, 0.0), 0.0);
                d.step(k * 50_000_000, pose, 0.3, &seen).unwrap().input
            })
            .collect()
    }

    #[test]
    fn same_seed_same_inputs_and_the_cap_has_three_forward_levels() {
        let a = first_outputs(7, InputDevice::HeadCap, &OPEN);
        assert_eq!(a, first_outputs(7, InputDevice::HeadCap, &OPEN));
        assert_ne!(a, first_outputs(8, InputDevice::HeadCap, &OPEN));
        assert!(
            a.iter()
                .all(|u| [0.0, 1.0, 2.0, 3.0].contains(&(u.x * 3.0).round()) && u.x >= 0.0),
            "{a:?}"
        );
    }

    #[test]
    fn an_obstacle_close_on_the_left_turns_the_person_right_and_one_ahead_stops_them() {
        let mean_turn = |c: &[f64; 4]| {
            let out = first_outputs(3, InputDevice::Joystick, c);
            out[40..].iter().map(|u| u.y).sum::<f64>() / 60.0
        };
        let free = mean_turn(&OPEN);
        let left = mean_turn(&[f64::INFINITY, 0.05, f64::INFINITY, f64::INFINITY]);
        assert!(left < free - 0.2, "free {free}, wall on the left {left}");
        let ahead = first_outputs(3, InputDevice::Joystick, &[0.05, 2.0, 2.0, 2.0]);
        let forward = ahead[40..].iter().map(|u| u.x).sum::<f64>() / 60.0;
        assert!(forward < 0.15, "{forward}");
    }

    /// Forward-step changes per second of a head-cap driver rolling slowly with things 0.25-0.3 m
    /// away ahead and on both sides (between stopping and slowing), over 30 s.
    fn cap_switches_per_s(seed: u64, model: DriverModel) -> f64 {
        let mut d = SeeingDriver::new(
            DriverProfile::from_seed(seed),
            InputDevice::HeadCap,
            square(),
            seed,
        )
        .with_model(model);
        let near = [0.3, 0.25, 0.25, f64::INFINITY];
        let seen = Perception {
            bearings_rad: &BEARINGS,
            clearance_m: &near,
            touching: false,
        };
        let periods = 600u64;
        let xs: Vec<f64> = (0..periods)
            .map(|k| {
                d.step(k * 50_000_000, Isometry2::identity(), 0.2, &seen)
                    .unwrap()
                    .input
                    .x
            })
            .collect();
        let switches = xs.windows(2).filter(|w| w[0] != w[1]).count();
        switches as f64 / (periods as f64 * 0.05)
    }

    #[test]
    fn by_an_obstacle_the_steady_cap_does_not_flicker_and_the_per_period_one_does() {
        for seed in 0..6 {
            let steady = cap_switches_per_s(seed, DriverModel::Steady);
            let per_period = cap_switches_per_s(seed, DriverModel::PerPeriod);
            println!("seed {seed}: steady {steady:.2}/s, per period {per_period:.2}/s");
            assert!(steady < 1.5, "seed {seed}: steady {steady:.2} switches/s");
            assert!(
                per_period > 2.0 * steady.max(0.5),
                "seed {seed}: per period {per_period:.2}, steady {steady:.2}"
            );
        }
    }

    /// Joystick outputs of a person rolling along x (1 cm a period) in the open, who bumps
    /// something straight ahead at period `bump` if given (touching for 3 periods); the pose
    /// jumps `jump_m` further along x from period 100 on.
    fn outputs_around_a_bump(
        model: DriverModel,
        bump: Option<u64>,
        jump_m: f64,
    ) -> Vec<Vector2<f64>> {
        let mut d = SeeingDriver::new(
            DriverProfile::from_seed(5),
            InputDevice::Joystick,
            square(),
            5,
        )
        .with_model(model);
        let touching_ahead = [0.0, 0.5, 0.5, 2.0];
        (0..200u64)
            .map(|k| {
                let touching = bump.is_some_and(|b| (b..b + 3).contains(&k));
                let seen = Perception {
                    bearings_rad: &BEARINGS,
                    clearance_m: if touching { &touching_ahead } else { &OPEN },
                    touching,
                };
                let x = 0.01 * k as f64 + if k >= 100 { jump_m } else { 0.0 };
                let pose = Isometry2::new(Vector2::new(x, 0.0), 0.0);
                d.step(k * 50_000_000, pose, 0.3, &seen).unwrap().input
            })
            .collect()
    }

    fn mean_forward(outputs: &[Vector2<f64>]) -> f64 {
        outputs.iter().map(|u| u.x).sum::<f64>() / outputs.len() as f64
    }

    #[test]
    fn after_a_bump_ahead_the_person_backs_off_then_creeps_near_it_and_not_far_from_it() {
        let calm = outputs_around_a_bump(DriverModel::Steady, None, 0.0);
        let bumped = outputs_around_a_bump(DriverModel::Steady, Some(20), 0.0);
        assert_eq!(calm[..20], bumped[..20], "nothing changes before the bump");
        // Backing off (0.5 s) shows within the reaction delay (at most 0.72 s) after the bump.
        assert!(
            bumped[20..50].iter().any(|u| u.x < -0.2),
            "no back-off: {:?}",
            &bumped[20..50]
        );
        // Then near the bump: slow (the lowest step's wish, give or take tremor) and no turn on
        // the spot, where the same person without the bump drives at their preferred input.
        let (near, before) = (mean_forward(&bumped[60..100]), mean_forward(&calm[60..100]));
        assert!(near < WARY_INPUT + 0.1, "near the bump {near:.2}");
        assert!(
            before > near + 0.2,
            "without the bump {before:.2}, with {near:.2}"
        );
        // Farther than WARY_WITHIN_M from the bump the person drives as before.
        let far = outputs_around_a_bump(DriverModel::Steady, Some(20), WARY_WITHIN_M + 0.5);
        let away = mean_forward(&far[140..200]);
        assert!(
            away > near + 0.2,
            "far from the bump {away:.2}, near {near:.2}"
        );
    }

    #[test]
    fn the_per_period_model_ignores_bumps() {
        // The named older model keeps its figures: the touch changes only the clearance seen.
        let bumped = outputs_around_a_bump(DriverModel::PerPeriod, Some(20), 0.0);
        assert!(
            bumped[20..50].iter().all(|u| u.x > -0.2),
            "{:?}",
            &bumped[20..50]
        );
    }

    #[test]
    fn reaction_delay_holds_the_start() {
        let mut d = SeeingDriver::new(
            DriverProfile::from_seed(1),
            InputDevice::Joystick,
            square(),
            1,
        );
        let seen = Perception {
            bearings_rad: &BEARINGS,
            clearance_m: &OPEN,
            touching: false,
        };
        let first = d.step(0, Isometry2::identity(), 0.0, &seen).unwrap();
        assert_eq!(first.input, Vector2::zeros());
        let short = Perception {
            bearings_rad: &BEARINGS,
            clearance_m: &OPEN[..2],
            touching: false,
        };
        assert!(d.step(1, Isometry2::identity(), 0.0, &short).is_err());
    }

    #[test]
    fn degenerate_circuit_is_an_error() {
        assert!(Circuit::new(vec![Point2::new(1.0, 1.0), Point2::new(1.0, 1.0)]).is_err());
        assert!(Circuit::new(vec![Point2::new(1.0, 1.0)]).is_err());
    }
}
