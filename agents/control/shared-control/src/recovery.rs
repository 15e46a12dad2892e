//! The arc guard's way out of a spot where it holds a user who keeps pushing.
//!
//! A chair that reaches a tight passage off its centre line and at an angle cannot line up where
//! it is: turning would swing a front corner into the furniture, and going on would touch the
//! wall. The guard rightly holds it, but a user who keeps pushing forward stays stuck (on the
//! ward corridor's 0.95 m passage, 50-130 s). What frees it is to back out along the way it came
//! and come in again from farther back, with room to line up.
//!
//! [`Recovery`] keeps the chair's recent path (odometry frame). When the user has asked for motion
//! for [`crate::ArcGuardParams::stall_s`], the guard has held back most of it, and the chair has
//! not got 0.25 m from where the hold began, it drives the chair back along that path by reverse pure pursuit until it is
//! [`crate::ArcGuardParams::backup_m`] away from where it stalled. Every command it sends still
//! passes the guard's sweep check, so no point inside the margin comes closer; when backing
//! would, it stops and hands the chair back. Letting go of the input (a stop) ends it at once.
//!
//! Backed out, the chair is where it was before it wedged, and a user who comes in the same way
//! wedges again. So when the stall was at a passage the dense sensor saw (found then, from its
//! points alone: [`crate::dock::find_lane`]), the backing is followed by docking
//! ([`crate::dock::Docking`]): the chair is driven onto the passage's centre line before the
//! entry, lined up with its axis, and along the line until its front is inside the passage, then
//! handed back. Each docking command passes the same sweep check as the backing's; docking ends
//! there, when the user lets go, when it has been held for [`DOCK_HELD_S`], or after
//! [`DOCK_MAX_S`]; held that long while it reverses for room, it lines up from where it is.

use std::collections::VecDeque;

use iw_body::layout::Footprint;
use nalgebra::{Isometry2, Point2};

use crate::VelocityCommand;
use crate::dock::{Docking, Lane};

/// Spacing of the remembered path, m.
const TRAIL_STEP_M: f64 = 0.05;
/// Longest remembered path, points (3 m at [`TRAIL_STEP_M`]).
const TRAIL_POINTS: usize = 60;
/// Net motion from where the hold began that counts as progress (the stall is over), m.
const PROGRESS_M: f64 = 0.25;
/// Input under which the user is not asking for motion (linear, m/s; turn, rad/s).
const PUSH_MPS: f64 = 0.05;
/// Fraction of the periods since the hold began that must have been held to call it a stall.
const STALL_HELD_SHARE: f64 = 0.5;
/// A gap in the user's pushing longer than this ends the hold, s: they are doing something else.
const PAUSE_S: f64 = 1.5;
/// Speed of the backing out, m/s (reverse).
const BACK_MPS: f64 = 0.2;
/// Scales of [`BACK_MPS`] tried when backing at full speed is not clear.
const BACK_SCALES: [f64; 3] = [1.0, 0.6, 0.3];
/// How far back along the path the reverse pursuit aims, m.
const LOOKAHEAD_M: f64 = 0.35;
/// Distance to the path's last point at which the backing has arrived, m.
const ARRIVED_M: f64 = 0.1;
/// Longest backing, s: bounds it if the wheels slip or the path cannot be followed.
const BACK_MAX_S: f64 = 10.0;
/// Turn rate of the reverse pursuit at most, rad/s.
const BACK_TURN_RADPS: f64 = 0.6;
/// How far from where it stalled a backing must have taken the chair for docking to follow, m:
/// a backing held at once leaves no room to line up.
const DOCK_AFTER_M: f64 = 0.3;
/// Longest docking, s.
const DOCK_MAX_S: f64 = 40.0;
/// How long the sweep check may hold docking back before it gives up, s.
const DOCK_HELD_S: f64 = 1.0;

/// The hold being watched: since when, from where, and how many periods held.
#[derive(Debug, Clone, Copy)]
struct Hold {
    since_ns: u64,
    from: Isometry2<f64>,
    last_push_ns: u64,
    periods: u32,
    held: u32,
}

/// Backing out along `path` (odometry frame, nearest first, farthest last).
#[derive(Debug, Clone)]
struct Backing {
    since_ns: u64,
    path: Vec<Point2<f64>>,
    /// Index of the first path point not yet passed.
    next: usize,
    /// Where the chair stalled (odometry frame).
    stalled: Point2<f64>,
    /// The passage it stalled at, if one was seen.
    lane: Option<Lane>,
}

/// Docking under way: since when, and since when the sweep check has held it back.
#[derive(Debug, Clone, Copy)]
struct Dock {
    since_ns: u64,
    held_since_ns: Option<u64>,
    to: Docking,
}

/// Watches for a stall and backs the chair out of it.
#[derive(Debug, Clone)]
pub(crate) struct Recovery {
    /// Recent positions, oldest first, [`TRAIL_STEP_M`] apart.
    trail: VecDeque<Point2<f64>>,
    hold: Option<Hold>,
    backing: Option<Backing>,
    docking: Option<Dock>,
    /// The chair's footprint, for the dock pose.
    footprint: Footprint,
}

/// What the recovery wants this period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Plan {
    /// Nothing: the guard limits the user's command as usual.
    Pass,
    /// Back out: try these commands, best first; the first one clear is sent, and if none is,
    /// the backing ends and the chair stops.
    Back([VelocityCommand; BACK_SCALES.len()]),
    /// Dock: try these commands, best first; the first one clear is sent, and if none is for
    /// [`DOCK_HELD_S`], docking ends (reversing for room, it goes on forwards from there).
    Dock([VelocityCommand; 3]),
}

impl Recovery {
    /// Watching a chair of `footprint`.
    pub(crate) fn new(footprint: Footprint) -> Self {
        Recovery {
            trail: VecDeque::new(),
            hold: None,
            backing: None,
            docking: None,
            footprint,
        }
    }

    /// Records the pose at `time_ns` and says what to do with the `user`'s command.
    pub(crate) fn plan(
        &mut self,
        time_ns: u64,
        pose: &Isometry2<f64>,
        user: VelocityCommand,
    ) -> Plan {
        self.remember(pose);
        // Letting go of the input is a stop, and the user's stop always wins.
        let released = user.linear_mps.abs() < PUSH_MPS && user.angular_radps.abs() < PUSH_MPS;
        if let Some(dock) = &mut self.docking {
            let timed_out = time_ns.saturating_sub(dock.since_ns) as f64 * 1e-9 > DOCK_MAX_S;
            match dock.to.commands(pose) {
                Some(commands) if !released && !timed_out => return Plan::Dock(commands),
                _ => {
                    self.docking = None;
                    return Plan::Pass;
                }
            }
        }
        let Some(backing) = &mut self.backing else {
            return Plan::Pass;
        };
        let here = Point2::from(pose.translation.vector);
        let timed_out = time_ns.saturating_sub(backing.since_ns) as f64 * 1e-9 > BACK_MAX_S;
        let last = backing.path.last().copied();
        let arrived = last.is_none_or(|p| (p - here).norm() <= ARRIVED_M);
        if released || timed_out || arrived {
            self.end(time_ns, pose, !released);
            return Plan::Pass;
        }
        while backing.next + 1 < backing.path.len()
            && (backing.path[backing.next] - here).norm() < LOOKAHEAD_M
        {
            backing.next += 1;
        }
        let target = pose.inverse() * backing.path[backing.next];
        // Pure pursuit backwards: the arc through the chair, tangent to its axis, that passes the
        // target has curvature 2y/d^2 whichever way it is driven.
        let d2 = target.coords.norm_squared().max(1e-6);
        let curvature = 2.0 * target.y / d2;
        let pursue = (BACK_MPS * curvature).clamp(-BACK_TURN_RADPS, BACK_TURN_RADPS);
        // The way it came, slower if faster would bring something closer.
        Plan::Back(BACK_SCALES.map(|s| VelocityCommand::new(-BACK_MPS * s, -pursue * s)))
    }

    /// Notes the period's outcome: whether the user asked for motion (`pushing`) and whether the
    /// guard `held` most of it back (while backing, whether it sent nothing at all; while docking,
    /// whether it held the docking command back). Starts backing out when the hold has lasted
    /// `stall_s` and a path `backup_m` long is known; `lane` then gives the passage stalled at,
    /// from the chair's pose then.
    pub(crate) fn observe(
        &mut self,
        time_ns: u64,
        pose: &Isometry2<f64>,
        (pushing, held): (bool, bool),
        (stall_s, backup_m): (f64, f64),
        lane: impl FnOnce(&Isometry2<f64>) -> Option<Lane>,
    ) {
        if let Some(dock) = &mut self.docking {
            let since = match (held, dock.held_since_ns) {
                (false, _) => None,
                (true, since) => Some(since.unwrap_or(time_ns)),
            };
            dock.held_since_ns = since;
            if since.is_some_and(|t| time_ns.saturating_sub(t) as f64 * 1e-9 >= DOCK_HELD_S) {
                if dock.to.no_room_behind() {
                    dock.held_since_ns = None;
                } else {
                    self.docking = None;
                }
            }
            return;
        }
        if self.backing.is_some() {
            if held {
                // Backing would bring something closer: stop, and dock from here if there is room.
                self.end(time_ns, pose, true);
            }
            return;
        }
        let held = pushing && held;
        let hold = match &mut self.hold {
            Some(h)
                if (Point2::from(pose.translation.vector)
                    - Point2::from(h.from.translation.vector))
                .norm()
                    <= PROGRESS_M
                    && (pushing
                        || time_ns.saturating_sub(h.last_push_ns) as f64 * 1e-9 <= PAUSE_S) =>
            {
                h
            }
            _ => {
                self.hold = held.then_some(Hold {
                    since_ns: time_ns,
                    from: *pose,
                    last_push_ns: time_ns,
                    periods: 0,
                    held: 0,
                });
                match &mut self.hold {
                    Some(h) => h,
                    None => return,
                }
            }
        };
        hold.periods += 1;
        hold.held += u32::from(held);
        if pushing {
            hold.last_push_ns = time_ns;
        }
        let lasted = time_ns.saturating_sub(hold.since_ns) as f64 * 1e-9;
        if lasted < stall_s || f64::from(hold.held) < STALL_HELD_SHARE * f64::from(hold.periods) {
            return;
        }
        let from = Point2::from(hold.from.translation.vector);
        if let Some(path) = self.path_back(&from, backup_m) {
            self.backing = Some(Backing {
                since_ns: time_ns,
                path,
                next: 0,
                stalled: Point2::from(pose.translation.vector),
                lane: lane(pose),
            });
        }
        self.hold = None;
    }

    /// Whether the chair is being backed out.
    pub(crate) fn is_backing(&self) -> bool {
        self.backing.is_some()
    }

    /// Whether the chair is being docked onto a passage's centre line.
    pub(crate) fn is_docking(&self) -> bool {
        self.docking.is_some()
    }

    /// The remembered path back from the newest pose to the first one `backup_m` from `from`,
    /// nearest first; `None` if the path known does not reach that far.
    fn path_back(&self, from: &Point2<f64>, backup_m: f64) -> Option<Vec<Point2<f64>>> {
        let mut path = Vec::new();
        for &p in self.trail.iter().rev() {
            path.push(p);
            if (p - from).norm() >= backup_m {
                return Some(path);
            }
        }
        None
    }

    /// Ends a backing: the path from where it ended on stays, the part backed over goes. With
    /// `dock`, docking follows if a passage was seen and the backing made room.
    fn end(&mut self, time_ns: u64, pose: &Isometry2<f64>, dock: bool) {
        if let Some(b) = self.backing.take() {
            let keep = self.trail.len().saturating_sub(b.next + 1);
            self.trail.truncate(keep);
            let here = Point2::from(pose.translation.vector);
            self.trail.push_back(here);
            let room = (here - b.stalled).norm() >= DOCK_AFTER_M;
            self.docking = b.lane.filter(|_| dock && room).map(|lane| Dock {
                since_ns: time_ns,
                held_since_ns: None,
                to: Docking::new(&lane, &self.footprint),
            });
        }
        self.hold = None;
    }

    /// Adds `pose` to the trail when it is [`TRAIL_STEP_M`] from the newest (not while backing:
    /// the way back is the way it came).
    fn remember(&mut self, pose: &Isometry2<f64>) {
        if self.backing.is_some() {
            return;
        }
        let here = Point2::from(pose.translation.vector);
        if self
            .trail
            .back()
            .is_none_or(|last| (here - last).norm() >= TRAIL_STEP_M)
        {
            self.trail.push_back(here);
            if self.trail.len() > TRAIL_POINTS {
                self.trail.pop_front();
            }
        }
    }
}
