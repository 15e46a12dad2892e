//! A footprint guard along the commanded arc: the chair's rectangle is swept along the path the
//! command would drive (turning in place included) until the chair has stopped, and the command is
//! changed as little as possible so that no obstacle point enters it.
//!
//! The potential field of thesis 3.6 does nothing while the chair spins in place (`F_a = 0`) and
//! looks only along sonar axes; a long-fronted chair turning beside a wall sweeps its front
//! corners through the wall. The guard checks exactly that sweep.
//!
//! With the chair's measured [`Motion`] the sweep starts from the speed the chair has, ramping to
//! the command at the braking limits (a chair still turning right keeps turning right for a
//! moment after a left command), and the dense points of the last [`ArcGuardParams::memory_s`]
//! are remembered in the odometry frame: a front laser cannot see a door jamb once it is beside
//! the chair's side or rear, and the side sonars' cones leave gaps there (22 cm apart, 45 degree
//! cones: they overlap only from 27 cm out). Without dense points, the sonars' near echoes are
//! remembered instead, where the arcs of echoes from two directions cross ([`EchoMemory`]): a
//! jamb a side sonar saw before it fell into the gap still guards the side.
//!
//! A chair the guard holds while its user keeps pushing (off the centre line and at an angle at
//! the entry of a tight passage) is backed out along the way it came, every backing command
//! passing the same sweep check, so the user can come in again straight ([`ArcGuard::set_recovery`]);
//! when the dense sensor saw the passage it stalled at, the backing is followed by docking onto
//! that passage's centre line, lined up with its axis ([`ArcGuardParams::dock`]).
//! A backing is checked without the cone-wide spread of a sonar echo that a laser point at the
//! echo's range already explains: spread, an echo off something beside a rear corner lands behind
//! the rear, where the chair has just been, and held every backing.

use std::collections::HashMap;

use iw_body::layout::Footprint;
use nalgebra::{Isometry2, Point2, Vector2};

use crate::dock::find_lane;
use crate::echoes::{EchoMemory, EchoMemoryParams};
use crate::error::check_positive;
use crate::recovery::{Plan, Recovery};
use crate::{
    ControlError, Intervention, Motion, SensorMount, SharedController, SharedInput, SharedOutput,
    VelocityCommand,
};

/// Limits of the sweep; defaults suit the prototype.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct ArcGuardParams {
    /// Clearance kept around the footprint, m (0.05).
    pub margin_m: f64,
    /// Acceleration and braking of each drive wheel the guard counts on, m/s^2 (1.0; the basic
    /// layer ramps each wheel on its own, so a chair changing speed and turn rate together
    /// changes both more slowly than either alone).
    pub wheel_decel_mps2: f64,
    /// Distance between the drive wheels, m (the prototype's [`iw_body::TRACK_M`]).
    pub track_m: f64,
    /// Time the measured speed persists before the wheels follow a new command (one control
    /// period of actuation delay), s (0.05; only with [`Motion`]).
    pub latency_s: f64,
    /// Time the command is held before braking starts (the guard's own latency), s (0.3).
    pub reaction_s: f64,
    /// Time between two checked poses on the path, s (0.05).
    pub sample_s: f64,
    /// Full sonar cone, deg (45, thesis 3.4).
    pub cone_deg: f64,
    /// How far the chair may have moved (net, since it saw a dense point) before the point is
    /// forgotten, m (3; only with [`Motion`]; a heading change counts as the footprint corner's
    /// travel). Odometry's bias grows with net motion, not with time or with wiggling on the
    /// spot, so this keeps a remembered point within a few centimetres of where it is.
    pub memory_travel_m: f64,
    /// How long a dense point out of the sensor's view stays remembered at most, s (60):
    /// something that moved away while out of view is not a wall for ever.
    pub memory_s: f64,
    /// How long the user must have asked for motion that the guard mostly held back, without
    /// the chair getting anywhere, before the guard backs it out the way it came, s (3; only with
    /// [`Motion`], and not after [`ArcGuard::set_recovery`] turned it off).
    pub stall_s: f64,
    /// How far from where it stalled the chair is backed out, along the way it came, m (0.8;
    /// 0 never backs out).
    pub backup_m: f64,
    /// Whether a backing out is followed by docking onto the centre line of the passage the chair
    /// stalled at, lined up with its axis (true; needs dense points to find the passage).
    pub dock: bool,
    /// The memory of sonar echoes, used in the periods without dense points (only with
    /// [`Motion`]).
    pub echo_memory: EchoMemoryParams,
    /// In periods without dense points, a forward-looking sonar's echo nearer than this is taken
    /// to run on across the blind zone the two forward cones leave ahead of the front (they close
    /// only 0.8 m out), at the nearest distance ahead the echo can be, m (0.25; 0 turns it off).
    /// A desk's edge or a plant's corner one front sonar sees there reaches into that zone,
    /// where no sonar sees it, and a turn away from the echo swept the front edge into it.
    pub front_gap_m: f64,
}

impl Default for ArcGuardParams {
    fn default() -> Self {
        Self {
            margin_m: 0.05,
            wheel_decel_mps2: 1.0,
            track_m: iw_body::TRACK_M,
            latency_s: 0.05,
            reaction_s: 0.3,
            sample_s: 0.05,
            cone_deg: 45.0,
            memory_travel_m: 3.0,
            memory_s: 60.0,
            stall_s: 3.0,
            backup_m: 0.8,
            dock: true,
            echo_memory: EchoMemoryParams::default(),
            front_gap_m: 0.25,
        }
    }
}

/// Sweeps the footprint along the commanded arc and scales or steers the command minimally.
#[derive(Debug, Clone)]
pub struct ArcGuard {
    params: ArcGuardParams,
    footprint: Footprint,
    mounts: Vec<SensorMount>,
    memory: Memory,
    echo_memory: EchoMemory,
    view: Option<DenseView>,
    recovery: Option<Recovery>,
    /// This period's sonar echoes: where their points are in the period's points, the sonar,
    /// and the range (the dense points follow the last).
    echoes: Vec<(std::ops::Range<usize>, usize, f64)>,
}

/// Where the dense sensor looks from, and how wide: inside its view a remembered point that the
/// scan has looked through for [`FORGET_SEEN_GONE_NS`] has gone; outside, the memory is kept.
#[derive(Debug, Clone, Copy)]
struct DenseView {
    mount: SensorMount,
    half_fov_rad: f64,
}

/// Scales of the user's command tried, largest first.
const SCALES: [f64; 6] = [1.0, 0.8, 0.6, 0.4, 0.2, 0.0];
/// Angular offsets tried when scaling alone does not clear the arc, rad/s.
const STEER_RADPS: [f64; 7] = [0.0, 0.15, -0.15, 0.3, -0.3, 0.5, -0.5];
/// Longest predicted path, s: bounds the work on absurd speeds.
const MAX_HORIZON_S: f64 = 5.0;
/// Finest sampling of the path, s: with [`MAX_HORIZON_S`] it bounds the poses per check.
const MIN_SAMPLE_S: f64 = 0.005;

impl ArcGuard {
    /// A guard for a chair of `footprint` with sonars at `mounts`.
    pub fn new(
        params: ArcGuardParams,
        footprint: Footprint,
        mounts: Vec<SensorMount>,
    ) -> Result<Self, ControlError> {
        check_positive("wheel_decel_mps2", params.wheel_decel_mps2)?;
        check_positive("track_m", params.track_m)?;
        check_positive("sample_s", params.sample_s)?;
        if params.sample_s < MIN_SAMPLE_S {
            return Err(ControlError::BadParameter {
                name: "sample_s",
                value: params.sample_s,
                why: "must be at least 0.005 s (each sample is a footprint check of every point)",
            });
        }
        for (name, value) in [
            ("margin_m", params.margin_m),
            ("latency_s", params.latency_s),
            ("reaction_s", params.reaction_s),
            ("memory_travel_m", params.memory_travel_m),
            ("memory_s", params.memory_s),
            ("stall_s", params.stall_s),
            ("backup_m", params.backup_m),
            ("front_gap_m", params.front_gap_m),
        ] {
            if value.is_nan() || value < 0.0 || value.is_infinite() {
                return Err(ControlError::BadParameter {
                    name,
                    value,
                    why: "must be finite and >= 0",
                });
            }
        }
        let echo_memory = EchoMemory::new(
            params.echo_memory,
            footprint,
            mounts.clone(),
            params.cone_deg,
        )?;
        Ok(Self {
            params,
            footprint,
            mounts,
            memory: Memory::default(),
            echo_memory,
            view: None,
            recovery: Some(Recovery::new(footprint)),
            echoes: Vec::new(),
        })
    }

    /// Whether a stalled chair is backed out (on by default). A person pushing into a spot the
    /// guard holds needs it; a planner that re-plans when blocked does not, and the control agent
    /// turns it off for tasks.
    pub fn set_recovery(&mut self, on: bool) {
        if on != self.recovery.is_some() {
            self.recovery = on.then(|| Recovery::new(self.footprint));
        }
    }

    /// Whether the guard is backing the chair out of a stall now.
    pub fn is_backing(&self) -> bool {
        self.recovery.as_ref().is_some_and(Recovery::is_backing)
    }

    /// Whether the guard is docking the chair onto a passage's centre line after a backing.
    pub fn is_docking(&self) -> bool {
        self.recovery.as_ref().is_some_and(Recovery::is_docking)
    }

    /// The guard, told where the dense sensor (`points_chair`) sits and its full field of view
    /// (rad): remembered points inside that view are dropped once its beams have passed through
    /// them (or returned nothing) for 1 s. Without it, remembered points are dropped only by [`ArcGuardParams::memory_s`] and
    /// [`ArcGuardParams::memory_travel_m`].
    pub fn with_dense_view(mut self, mount: SensorMount, fov_rad: f64) -> Self {
        self.view = Some(DenseView {
            mount,
            half_fov_rad: fov_rad.abs().min(std::f64::consts::TAU) / 2.0,
        });
        self
    }

    /// The chair frame's poses (inverted) every `sample_s` while the chair keeps `start` for
    /// `latency_s`, ramps each wheel to `command`, holds it until `reaction_s`, then brakes to a
    /// stop; the path's length is the second value.
    fn path(&self, start: VelocityCommand, command: VelocityCommand) -> (Vec<Isometry2<f64>>, f64) {
        let p = &self.params;
        let dt = p.sample_s;
        let half = p.track_m / 2.0;
        let wheels = |c: VelocityCommand| {
            (
                c.linear_mps - c.angular_radps * half,
                c.linear_mps + c.angular_radps * half,
            )
        };
        let (mut left, mut right) = wheels(start);
        let goal = wheels(command);
        let mut pose = Isometry2::identity();
        let mut poses = Vec::new();
        let mut length = 0.0;
        let mut t = 0.0;
        while t < MAX_HORIZON_S {
            let (to_left, to_right) = if start != command && t < p.latency_s {
                (left, right)
            } else if t < p.reaction_s {
                goal
            } else {
                (0.0, 0.0)
            };
            let (l0, r0) = (left, right);
            left = approach(left, to_left, p.wheel_decel_mps2 * dt);
            right = approach(right, to_right, p.wheel_decel_mps2 * dt);
            t += dt;
            if [l0, r0, left, right] == [0.0; 4] {
                if t >= p.reaction_s {
                    break;
                }
                continue;
            }
            // the mean wheel speeds over the sample: exact for a linear ramp's distance
            let (l, r) = ((l0 + left) / 2.0, (r0 + right) / 2.0);
            let (v, w) = ((l + r) / 2.0, (r - l) / p.track_m);
            pose *= arc_pose(v, w, dt);
            length += v.abs() * dt;
            poses.push(pose.inverse());
        }
        (poses, length)
    }

    /// Whether driving `command` until stopped, from a chair already at that speed, keeps every
    /// point in `points` out of the footprint (inflated by the margin; a point already inside the
    /// margin may not come any closer).
    pub fn is_clear(&self, command: VelocityCommand, points: &[Point2<f64>]) -> bool {
        self.is_clear_from(command, command, points)
    }

    /// [`Self::is_clear`] for a chair moving at `start` when `command` is given.
    pub fn is_clear_from(
        &self,
        start: VelocityCommand,
        command: VelocityCommand,
        points: &[Point2<f64>],
    ) -> bool {
        let (poses, length) = self.path(start, command);
        if poses.is_empty() {
            return true;
        }
        let fp = self.footprint;
        let margin = self.params.margin_m;
        let reach = fp.turning_radius_m() + margin + length;
        points.iter().filter(|p| p.coords.norm() <= reach).all(|p| {
            // A point already inside the margin may not come closer than it is: sampled points
            // stand for surfaces (a jamb's end lies a few centimetres past the last beam that hit
            // it), so letting it reach the bare footprint let the chair touch what was between.
            let keep = box_distance(&fp, p).min(margin) - CLOSER_TOLERANCE_M;
            poses.iter().all(|inv| box_distance(&fp, &(inv * p)) > keep)
        })
    }

    /// The points a backing out is checked against: this period's, without the spread of the
    /// sonar echoes that a dense point explains ([`explained`]). A sonar reports the nearest echo
    /// anywhere in its 45 degree cone, so the spread of an echo off something beside a rear
    /// corner puts points behind the rear, where the chair has just been, and held every backing
    /// (two rooms, held-out seed 202: wedged at the lower door for 230 s). The dense point stays,
    /// as does every echo no dense point explains (such as a person who stepped in behind, whom
    /// only the rear sonars see). Driving forward keeps the spread: the cone's other points also
    /// cover a jamb's end between the laser's beams.
    fn backing_points(&self, points: &[Point2<f64>]) -> Vec<Point2<f64>> {
        let half = self.params.cone_deg.to_radians() / 2.0;
        let dense = &points[self.echoes.last().map_or(0, |e| e.0.end)..];
        let mut skipped = self
            .echoes
            .iter()
            .filter(|(_, sonar, d)| explained(&self.mounts[*sonar], half, *d, dense))
            .map(|(range, _, _)| range)
            .peekable();
        points
            .iter()
            .enumerate()
            .filter(|(i, _)| {
                while skipped.next_if(|r| r.end <= *i).is_some() {}
                !skipped.peek().is_some_and(|r| r.contains(i))
            })
            .map(|(_, p)| *p)
            .collect()
    }

    /// The obstacle points of one period in the chair frame: with [`Motion`] and no dense point
    /// this period, the remembered sonar evidence ([`EchoMemory`]; where there are dense points
    /// they are authoritative); each sonar echo spread across the cone at its range (a sonar
    /// reports the nearest echo anywhere in its cone); and the dense points (with [`Motion`]:
    /// those remembered, which include this period's).
    fn points(&mut self, input: &SharedInput<'_>) -> Result<Vec<Point2<f64>>, ControlError> {
        if input.sonar_m.len() != self.mounts.len() {
            return Err(ControlError::SonarCount {
                expected: self.mounts.len(),
                got: input.sonar_m.len(),
            });
        }
        let dense = input
            .points_chair
            .iter()
            .filter(|p| p.x.is_finite() && p.y.is_finite());
        let mut points: Vec<Point2<f64>> = Vec::new();
        let dense: Vec<Point2<f64>> = match input.motion {
            Some(motion) => {
                if dense.clone().next().is_none() {
                    self.echo_memory.update(&motion, input.sonar_m)?;
                    points.extend(self.echo_memory.recall(&motion.t_odom_chair));
                    self.front_gap(input.sonar_m, &mut points);
                } else {
                    self.echo_memory.clear();
                }
                let radius = self.footprint.turning_radius_m() + MEMORY_BEYOND_REACH_M;
                let keep = Keep {
                    radius_m: radius,
                    travel_m: self.params.memory_travel_m,
                    time_ns: (self.params.memory_s * 1e9) as u64,
                    corner_m: self.footprint.turning_radius_m(),
                    view: self.view,
                };
                self.memory.update(&motion, dense, &keep);
                self.memory.recall(&motion.t_odom_chair).collect()
            }
            None => dense.copied().collect(),
        };
        let half = self.params.cone_deg.to_radians() / 2.0;
        self.echoes.clear();
        points.reserve(input.sonar_m.len() * 5 + dense.len());
        for (index, (mount, reading)) in self.mounts.iter().zip(input.sonar_m).enumerate() {
            let Some(d) = *reading else { continue };
            let d = crate::error::check_range("sonar", index, d)?;
            let from = points.len();
            points.extend(spread(mount, d, half));
            self.echoes.push((from..points.len(), index, d));
        }
        points.extend(dense);
        Ok(points)
    }

    /// Points across the front blind zone for each forward-looking sonar's echo nearer than
    /// [`ArcGuardParams::front_gap_m`]: at the nearest distance ahead of the front the echo can
    /// lie (its range at the cone's edge), every [`FRONT_GAP_STEP_M`] across the footprint's
    /// width. A turn on the spot stays clear of them (the front corners gain at most 7 cm
    /// ahead); driving forward into the zone does not.
    fn front_gap(&self, sonar_m: &[Option<f64>], points: &mut Vec<Point2<f64>>) {
        let fp = self.footprint;
        let cos_half = (self.params.cone_deg.to_radians() / 2.0).cos();
        for (mount, reading) in self.mounts.iter().zip(sonar_m) {
            let forward = mount.rotation.angle().abs() < 1e-6;
            let Some(d) = reading.filter(|&d| forward && d < self.params.front_gap_m) else {
                continue;
            };
            let x = mount.translation.x + d * cos_half;
            let steps = (2.0 * fp.half_width_m / FRONT_GAP_STEP_M).ceil() as usize;
            points.extend((0..=steps).map(|k| {
                Point2::new(
                    x,
                    -fp.half_width_m + 2.0 * fp.half_width_m * k as f64 / steps as f64,
                )
            }));
        }
    }

    /// `command` changed as little as possible so the swept footprint stays clear of `points`:
    /// unchanged when clear; else the largest scale of it, then the smallest extra turn, that is
    /// clear; else a stop. Returns the command and whether it was changed.
    pub fn limit(
        &self,
        command: VelocityCommand,
        points: &[Point2<f64>],
    ) -> (VelocityCommand, bool) {
        self.limit_from(None, command, points)
    }

    /// [`Self::limit`] for a chair moving at `start` (`None`: at each candidate's own speed).
    pub fn limit_from(
        &self,
        start: Option<VelocityCommand>,
        command: VelocityCommand,
        points: &[Point2<f64>],
    ) -> (VelocityCommand, bool) {
        let clear = |c: VelocityCommand| self.is_clear_from(start.unwrap_or(c), c, points);
        if clear(command) {
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
                if clear(candidate) {
                    best = Some((cost, candidate));
                }
            }
        }
        // The user's turn kept on the spot: a chair whose front is held at a corner can often
        // still turn the way its user asks, and stopping it instead left the user pushing into a
        // stall (two rooms, held-out drivers 203 and 215: held for seconds at a desk's corner and
        // in the upper door, asking for a turn that was clear). Dearer than any scaled or
        // steered command that moves the chair on, cheaper than a stop.
        let turn = VelocityCommand::new(0.0, command.angular_radps);
        if command.linear_mps != 0.0 && best.is_none_or(|(c, _)| c > KEEP_TURN_COST) && clear(turn)
        {
            best = Some((KEEP_TURN_COST, turn));
        }
        (best.map_or(VelocityCommand::STOP, |(_, c)| c), true)
    }
}

/// Cost of turning on the spot at the user's turn rate when no scaled or steered command is
/// clear (a stop costs 1, the user's command unchanged 0).
const KEEP_TURN_COST: f64 = 0.95;

/// Spacing of the points laid across the front blind zone, m: finer than the 5 cm margin.
const FRONT_GAP_STEP_M: f64 = 0.02;

/// Share of the user's wheel speed under which the guard's command holds the user back.
const HELD_SHARE: f64 = 0.5;
/// Wheel speed under which the user is not asking for motion, m/s.
const PUSH_WHEEL_MPS: f64 = 0.03;

/// How much closer than it is a point inside the margin may come, m: float rounding only (an
/// exact parallel drive keeps the distance).
const CLOSER_TOLERANCE_M: f64 = 1e-6;

/// Distance from `p` (chair frame) to the footprint, in the metric of a rectangle inflated with
/// square corners (the larger of the lengthwise and sideways gaps; 0 inside).
fn box_distance(fp: &Footprint, p: &Point2<f64>) -> f64 {
    let dx = (p.x - fp.front_m).max(-fp.rear_m - p.x);
    let dy = p.y.abs() - fp.half_width_m;
    dx.max(dy).max(0.0)
}

/// How far beyond the turning radius dense points are remembered, m: more than the longest path
/// checked at walking speed.
const MEMORY_BEYOND_REACH_M: f64 = 1.5;
/// Cell of the remembered-points grid, m: one point per cell (the newest) keeps the memory's
/// size bounded by the area around the chair, whatever the scan rate.
const MEMORY_CELL_M: f64 = 0.02;

/// What the memory keeps.
struct Keep {
    /// Farthest point from the chair, m.
    radius_m: f64,
    /// Largest net motion since a point was seen, m.
    travel_m: f64,
    /// Longest time since a point was seen, ns.
    time_ns: u64,
    /// Lever arm that turns a heading change into travel, m.
    corner_m: f64,
    /// The dense sensor's view, if known.
    view: Option<DenseView>,
}

/// One remembered point: where it is (odometry frame), and the chair's pose and the time when it
/// was last seen.
#[derive(Debug, Clone, Copy)]
struct Remembered {
    at: Point2<f64>,
    seen_from: Isometry2<f64>,
    seen_ns: u64,
    /// Since when every scan has shown free space through it, ns.
    gone_since_ns: Option<u64>,
}

/// Dense points remembered in the odometry frame, one per grid cell (the newest).
#[derive(Debug, Clone, Default)]
struct Memory {
    cells: HashMap<(i64, i64), Remembered>,
}

impl Memory {
    /// Adds this period's points (chair frame) and forgets what `keep` no longer covers.
    fn update<'a>(
        &mut self,
        motion: &Motion,
        points_chair: impl Iterator<Item = &'a Point2<f64>>,
        keep: &Keep,
    ) {
        let now = motion.t_odom_chair;
        let points_chair: Vec<&Point2<f64>> = points_chair.collect();
        // this scan as (bearing, range) from the sensor, by bearing: the evidence of free space
        let scan: Vec<(f64, f64)> = keep.view.map_or_else(Vec::new, |v| {
            let mut scan: Vec<(f64, f64)> = points_chair
                .iter()
                .map(|p| polar(&(v.mount.inverse() * *p)))
                .collect();
            scan.sort_by(|a, b| a.0.total_cmp(&b.0));
            scan
        });
        for p in points_chair
            .into_iter()
            .filter(|p| p.coords.norm() <= keep.radius_m)
        {
            let at = now * p;
            let key = (
                (at.x / MEMORY_CELL_M).floor() as i64,
                (at.y / MEMORY_CELL_M).floor() as i64,
            );
            self.cells.insert(
                key,
                Remembered {
                    at,
                    seen_from: now,
                    seen_ns: motion.time_ns,
                    gone_since_ns: None,
                },
            );
        }
        let inv = now.inverse();
        self.cells.retain(|_, r| {
            if r.seen_ns == motion.time_ns {
                return true;
            }
            let p = inv * r.at;
            let moved = r.seen_from.inverse() * now;
            let net =
                moved.translation.vector.norm() + moved.rotation.angle().abs() * keep.corner_m;
            let seen_through = keep.view.and_then(|v| {
                let (bearing, range) = polar(&(v.mount.inverse() * p));
                (bearing.abs() <= v.half_fov_rad).then(|| !returned(&scan, bearing, range))
            });
            match seen_through {
                Some(true) => _ = r.gone_since_ns.get_or_insert(motion.time_ns),
                Some(false) => r.gone_since_ns = None,
                None => {}
            }
            let seen_gone = r
                .gone_since_ns
                .is_some_and(|t| motion.time_ns.saturating_sub(t) >= FORGET_SEEN_GONE_NS);
            !seen_gone
                && net <= keep.travel_m
                && motion.time_ns.saturating_sub(r.seen_ns) <= keep.time_ns
                && p.coords.norm() <= keep.radius_m
        });
    }

    /// The remembered points in the chair frame.
    fn recall<'a>(
        &'a self,
        t_odom_chair: &Isometry2<f64>,
    ) -> impl Iterator<Item = Point2<f64>> + 'a {
        let inv = t_odom_chair.inverse();
        self.cells.values().map(move |r| inv * r.at)
    }
}

/// A sonar echo at range `d` from `mount` as five points across its cone (half-angle `half`): a
/// sonar reports the nearest echo anywhere in its cone.
fn spread(mount: &SensorMount, d: f64, half: f64) -> [Point2<f64>; 5] {
    [-2.0, -1.0, 0.0, 1.0, 2.0].map(|k: f64| {
        let a = half * k / 2.0;
        mount * Point2::new(d * a.cos(), d * a.sin())
    })
}

/// How far from a sonar echo's range a dense point may lie and still be the surface that returned
/// it, m: four standard deviations of the prototype's 1 cm sonar noise.
const EXPLAINED_RANGE_M: f64 = 0.04;

/// Whether a dense point (chair frame) inside the cone (`half` its half-angle, rad) of the sonar at
/// `mount` lies at about the echo's range `d`: then the echo is that surface, whose place the dense
/// sensor knows.
fn explained(mount: &SensorMount, half: f64, d: f64, dense: &[Point2<f64>]) -> bool {
    let inv = mount.inverse();
    dense.iter().any(|p| {
        let (bearing, range) = polar(&(inv * p));
        bearing.abs() <= half && (range - d).abs() <= EXPLAINED_RANGE_M
    })
}

/// Bearing and range of `p` from the origin.
fn polar(p: &Point2<f64>) -> (f64, f64) {
    (p.y.atan2(p.x), p.coords.norm())
}

/// How long the scan must show free space through a remembered point before it is forgotten,
/// ns (1 s): a thin wall seen edge-on, like a door jamb while the laser crosses the doorway's
/// plane, returns no beam for a few scans although it is there.
const FORGET_SEEN_GONE_NS: u64 = 1_000_000_000;

/// Half the bearing window in which a scan return vouches for a remembered point, rad: a beam
/// either side of the point's bearing at the prototype's 1 degree spacing.
const VOUCH_BEARING_RAD: f64 = 1.5 * std::f64::consts::PI / 180.0;
/// How far behind a remembered point a return may lie and still vouch for it, m: on a surface
/// seen at a grazing angle the next beam hits several centimetres farther along it.
const VOUCH_RANGE_M: f64 = 0.1;

/// Whether the scan (by bearing) returned something at about `bearing`, no farther than `range`
/// plus [`VOUCH_RANGE_M`]: the point is still there, or hidden behind something nearer. Only a
/// beam that passed it (or returned nothing) shows it gone. A surface seen at a grazing angle is
/// hit at different places scan by scan, and judging each remembered point by the current scan
/// alone forgot the parts between this scan's beams, such as a jamb's end.
fn returned(scan: &[(f64, f64)], bearing: f64, range: f64) -> bool {
    let from = scan.partition_point(|(b, _)| *b < bearing - VOUCH_BEARING_RAD);
    scan[from..]
        .iter()
        .take_while(|(b, _)| *b <= bearing + VOUCH_BEARING_RAD)
        .any(|(_, r)| *r <= range + VOUCH_RANGE_M)
}

/// `value` moved towards `target` by at most `step`.
fn approach(value: f64, target: f64, step: f64) -> f64 {
    value + (target - value).clamp(-step, step)
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

impl ArcGuard {
    /// The command sent for `user`: backing out of a stall if [`Recovery`] says so (each backing
    /// command passes the same sweep check, and if none does the chair stops and the backing
    /// ends), else [`Self::limit_from`].
    fn drive(
        &mut self,
        motion: Option<&Motion>,
        start: Option<VelocityCommand>,
        user: VelocityCommand,
        points: &[Point2<f64>],
    ) -> (VelocityCommand, bool) {
        let p = self.params;
        let Some(motion) = motion else {
            return self.limit_from(start, user, points);
        };
        let Some(mut recovery) = self.recovery.take() else {
            return self.limit_from(start, user, points);
        };
        let (time, pose) = (motion.time_ns, motion.t_odom_chair);
        let wheel_speed = |c: VelocityCommand| {
            let turn = c.angular_radps * p.track_m / 2.0;
            (c.linear_mps - turn).abs().max((c.linear_mps + turn).abs())
        };
        let (command, changed, held) = match recovery.plan(time, &pose, user) {
            Plan::Back(candidates) | Plan::Dock(candidates) => {
                // Reversing is checked without the spread of the echoes the laser explains
                // ([`Self::backing_points`]); any other command with it, as a user's is.
                let behind = self.backing_points(points);
                let clear = candidates.into_iter().find(|&c| {
                    let points = if c.linear_mps < 0.0 { &behind } else { points };
                    self.is_clear_from(start.unwrap_or(c), c, points)
                });
                (
                    clear.unwrap_or(VelocityCommand::STOP),
                    true,
                    clear.is_none(),
                )
            }
            Plan::Pass => {
                let (command, changed) = self.limit_from(start, user, points);
                let held = wheel_speed(command) < HELD_SHARE * wheel_speed(user);
                (command, changed, held)
            }
        };
        if p.backup_m > 0.0 {
            let pushing = wheel_speed(user) > PUSH_WHEEL_MPS;
            // The passage is found from the dense points only: a sonar echo is a range anywhere
            // in its cone, not a place.
            let dense = &points[self.echoes.last().map_or(0, |e| e.0.end)..];
            let lane = |stalled: &Isometry2<f64>| {
                p.dock
                    .then(|| find_lane(stalled, dense, &self.footprint, p.margin_m))
                    .flatten()
            };
            recovery.observe(time, &pose, (pushing, held), (p.stall_s, p.backup_m), lane);
        }
        self.recovery = Some(recovery);
        (command, changed)
    }
}

impl SharedController for ArcGuard {
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError> {
        let user = input.user.validate()?;
        let start = input.motion.map(|m| m.twist.validate()).transpose()?;
        let points = self.points(input)?;
        let (command, changed) = self.drive(input.motion.as_ref(), start, user, &points);
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
    fn the_change_is_reported_against_the_users_command() {
        // Sonars S1.. all echo at 0.2 m: spinning in place would sweep the corners through them.
        let mut g = guard();
        let sonar = [Some(0.2); iw_body::SONAR_COUNT];
        let user = VelocityCommand::new(0.0, -0.8);
        let out = g
            .step(&SharedInput {
                user,
                speed_mps: 0.0,
                sonar_m: &sonar,
                points_chair: &[],
                motion: None,
            })
            .unwrap();
        assert_ne!(out.command, user);
        assert_eq!(
            out.intervention,
            Intervention::between(user, out.command, out.intervention.active_readings)
        );
        assert!(out.intervention.changed() && out.intervention.active_readings > 0);
    }

    /// The guard, fed `points` (chair frame) with the chair moving at `twist` and at `pose` in
    /// the odometry frame, at `time_ns`; returns what it sent.
    fn drive(
        g: &mut ArcGuard,
        user: VelocityCommand,
        twist: VelocityCommand,
        pose: Isometry2<f64>,
        time_ns: u64,
        points: &[Point2<f64>],
    ) -> VelocityCommand {
        let sonar = [None; iw_body::SONAR_COUNT];
        g.step(&SharedInput {
            user,
            speed_mps: twist.linear_mps.abs(),
            sonar_m: &sonar,
            points_chair: points,
            motion: Some(Motion {
                time_ns,
                t_odom_chair: pose,
                twist,
            }),
        })
        .unwrap()
        .command
    }

    #[test]
    fn a_door_jamb_seen_ahead_is_remembered_once_beside_the_chair() {
        // A front laser (at the front left corner, 270 degrees) sees a jamb 0.08 m left of the
        // chair's side while it is 1 m ahead; once the chair has driven 1.2 m the jamb is beside
        // the left side, behind the laser, and no sensor returns it. Spinning left would swing
        // the side into it.
        let fp = Footprint::PROTOTYPE;
        let laser = Isometry2::new(Vector2::new(fp.front_m - 0.05, fp.half_width_m), 0.0);
        let mut g = guard().with_dense_view(laser, 270f64.to_radians());
        let jamb = Point2::new(1.0 + fp.front_m, fp.half_width_m + 0.08);
        let seen = drive(
            &mut g,
            VelocityCommand::new(0.3, 0.0),
            VelocityCommand::new(0.3, 0.0),
            Isometry2::identity(),
            0,
            &[jamb],
        );
        assert_eq!(seen, VelocityCommand::new(0.3, 0.0));
        let beside = Isometry2::new(Vector2::new(1.2, 0.0), 0.0);
        let spin = VelocityCommand::new(0.0, 0.8);
        let out = drive(
            &mut g,
            spin,
            VelocityCommand::STOP,
            beside,
            4_000_000_000,
            &[],
        );
        assert_ne!(out, spin, "the remembered jamb must stop the spin");
        // a guard without the memory (no motion) lets the same spin through: nothing is seen
        let (out, changed) = guard().limit(spin, &[]);
        assert!(!changed && out == spin);
        // far from where it was seen, the point is forgotten (odometry drift)
        let far = Isometry2::new(Vector2::new(1.2 + 3.5, 0.0), 0.0);
        let out = drive(
            &mut g,
            spin,
            VelocityCommand::STOP,
            far,
            20_000_000_000,
            &[],
        );
        assert_eq!(out, spin);
    }

    #[test]
    fn a_remembered_point_the_scan_looks_through_in_view_is_dropped_after_a_second() {
        // Something 0.25 m ahead of the front of a chair at 0.5 m/s, then gone from the laser's
        // view: driving on is allowed again once the scan has shown free space there for 1 s (a
        // person who stepped away is not a wall), not at the first empty scan (a jamb seen
        // edge-on returns no beam for a few scans).
        let fp = Footprint::PROTOTYPE;
        let laser = Isometry2::new(Vector2::new(fp.front_m - 0.05, fp.half_width_m), 0.0);
        let mut g = guard().with_dense_view(laser, 270f64.to_radians());
        let ahead: Vec<Point2<f64>> = (-3..=3)
            .map(|k| Point2::new(fp.front_m + 0.25, k as f64 * 0.1))
            .collect();
        let go = VelocityCommand::new(0.5, 0.0);
        let here = Isometry2::identity();
        assert_ne!(drive(&mut g, go, go, here, 0, &ahead), go);
        assert_ne!(drive(&mut g, go, go, here, 50_000_000, &[]), go);
        assert_ne!(drive(&mut g, go, go, here, 1_000_000_000, &[]), go);
        assert_eq!(drive(&mut g, go, go, here, 1_050_000_000, &[]), go);
    }

    #[test]
    fn a_point_hidden_behind_a_nearer_return_is_kept() {
        // A post 0.25 m ahead, then a box seen in front of it on the same bearing: the post is
        // hidden, not gone, and still holds the chair back after the forgetting time.
        let fp = Footprint::PROTOTYPE;
        let laser = Isometry2::new(Vector2::new(fp.front_m - 0.05, fp.half_width_m), 0.0);
        let mut g = guard().with_dense_view(laser, 270f64.to_radians());
        let post = Point2::new(fp.front_m + 0.25, fp.half_width_m);
        let nearer = Point2::new(fp.front_m + 0.15, fp.half_width_m);
        let go = VelocityCommand::new(0.5, 0.0);
        let here = Isometry2::identity();
        drive(&mut g, go, go, here, 0, &[post]);
        for k in 1..=30 {
            drive(&mut g, go, go, here, k * 50_000_000, &[nearer]);
        }
        assert_eq!(g.memory.cells.len(), 2, "the hidden post is remembered");
    }

    #[test]
    fn a_point_inside_the_margin_may_not_come_closer() {
        // A jamb's last laser point 3 cm beside the front right corner (inside the 5 cm margin):
        // the surface goes on between the beams, so the chair may drive along it or away, but
        // not towards it, even by less than it would take to touch the point itself.
        let fp = Footprint::PROTOTYPE;
        let jamb = [Point2::new(fp.front_m - 0.1, -fp.half_width_m - 0.03)];
        let g = guard();
        assert!(g.is_clear(VelocityCommand::new(0.3, 0.0), &jamb));
        assert!(
            g.is_clear(VelocityCommand::new(0.3, 0.3), &jamb),
            "turning away"
        );
        assert!(
            !g.is_clear(VelocityCommand::new(0.3, -0.1), &jamb),
            "a gentle turn towards it closes the 3 cm by less than the whole gap"
        );
    }

    #[test]
    fn a_chair_still_turning_towards_an_obstacle_is_held_even_if_the_new_command_is_clear() {
        // A post just right of the front right corner. Going straight ahead from rest is clear,
        // but a chair already spinning right at 1 rad/s keeps swinging that corner into the post
        // while its wheels reverse: the guard predicts from the measured speed.
        let fp = Footprint::PROTOTYPE;
        let post = [Point2::new(fp.front_m - 0.05, -fp.half_width_m - 0.08)];
        let g = guard();
        let ahead = VelocityCommand::new(0.3, 0.0);
        assert!(g.is_clear(ahead, &post));
        assert!(!g.is_clear_from(VelocityCommand::new(0.0, -1.0), ahead, &post));
        let (out, changed) = g.limit_from(Some(VelocityCommand::new(0.0, -1.0)), ahead, &post);
        assert!(changed && out != ahead, "{out:?}");
    }

    #[test]
    fn a_backing_is_not_held_by_the_spread_of_an_echo_the_laser_explains() {
        // The rear-left corner sonar (135 degrees) echoes at 7 cm off something beside the rear
        // left corner, 15 degrees towards the side from its axis. Spread over the cone, the echo
        // puts a point 3.5 cm behind the rear, which holds every reverse; a laser point at the
        // echo's range inside the cone says where the surface is, and backing straight out is
        // clear of it.
        let fp = Footprint::PROTOTYPE;
        let mount = fp.sonar_mounts()[9];
        let (sin, cos) = 15f64.to_radians().sin_cos();
        let surface = mount * Point2::new(0.07 * cos, -0.07 * sin);
        let mut sonar = [None; iw_body::SONAR_COUNT];
        sonar[9] = Some(0.07);
        let back = VelocityCommand::new(-0.2, 0.0);
        let checked = |dense: &[Point2<f64>]| {
            let mut g = guard();
            let points = g
                .points(&SharedInput {
                    user: back,
                    speed_mps: 0.0,
                    sonar_m: &sonar,
                    points_chair: dense,
                    motion: None,
                })
                .unwrap();
            let backing = g.backing_points(&points);
            (g.is_clear(back, &points), g.is_clear(back, &backing))
        };
        // driving as the user asks keeps the spread; a backing is checked without it
        assert_eq!(checked(&[surface]), (false, true));
        // a laser point at another range does not explain the echo
        assert_eq!(checked(&[mount * Point2::new(0.2, 0.0)]), (false, false));
        // nor does nothing: the sonars alone keep the spread
        assert_eq!(checked(&[]), (false, false));
    }

    #[test]
    fn bad_parameters_are_refused_not_run() {
        let fp = Footprint::PROTOTYPE;
        let mounts = fp.sonar_mounts().to_vec();
        for params in [
            ArcGuardParams {
                sample_s: 1e-9,
                ..ArcGuardParams::default()
            },
            ArcGuardParams {
                memory_s: f64::NAN,
                ..ArcGuardParams::default()
            },
            ArcGuardParams {
                track_m: 0.0,
                ..ArcGuardParams::default()
            },
        ] {
            assert!(
                ArcGuard::new(params, fp, mounts.clone()).is_err(),
                "{params:?}"
            );
        }
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
                motion: None,
            })
            .unwrap();
        assert_eq!(out.command, user);
        assert_eq!(out.intervention, Intervention::default());
    }

    #[test]
    fn a_chair_held_at_a_corner_ahead_turns_on_the_spot_the_way_its_user_asks() {
        // A wall 3 cm ahead of the front's right corner, from 0.1 m right of the centre line
        // outwards: no forward motion is clear, a turn to the right on the spot is (it swings
        // the front's right part away from the wall). The user asks for forward and right: the
        // guard keeps the turn, not a stop.
        let fp = Footprint::PROTOTYPE;
        let wall: Vec<Point2<f64>> = (5..=25)
            .map(|k| Point2::new(fp.front_m + 0.03, -0.02 * f64::from(k)))
            .collect();
        let g = guard();
        let user = VelocityCommand::new(0.3, -0.5);
        let turn = VelocityCommand::new(0.0, -0.5);
        assert!(g.is_clear(turn, &wall));
        let (out, changed) = g.limit(user, &wall);
        assert!(changed && out == turn, "{out:?}");
        // turning the other way would swing the front into the wall: a stop
        let (out, _) = g.limit(VelocityCommand::new(0.3, 0.5), &wall);
        assert_eq!(out, VelocityCommand::STOP);
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
