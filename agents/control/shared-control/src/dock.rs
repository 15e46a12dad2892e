//! Docking after a backing out: the chair is brought onto the centre line of the passage it
//! stalled at, aligned with the passage's axis, and handed back so the user's own command drives
//! it in.
//!
//! Backing out along the way it came leaves the chair where it was before it wedged: off the
//! centre line and at an angle (on the rig of `tests/recovery.rs`, 0.77 m off and 48 degrees),
//! and a user who comes in the same way wedges again. No turn on the spot lines such a chair up:
//! it has to be driven sideways, which a wheelchair does by an S of arcs, like parking a car.
//!
//! [`find_lane`] finds the passage from the sensed free space only (the dense sensor's points,
//! current and remembered; never a map): of the straight lanes ahead of the stalled chair's front,
//! the passage's axis is the heading whose lane is widest, because a lane across two walls
//! narrows as it tilts; the widest reached from the chair's own heading, since that is the
//! passage it was pushing into. [`Docking`] then turns the chair on the spot to that axis,
//! reverses along it until there is room to take out the sideways offset (or until something
//! behind holds it), drives forwards onto the centre line at an angle that shrinks with the
//! offset, so it comes alongside the line before the entry, and follows the line until the
//! chair's front is well inside the passage.

use iw_body::layout::Footprint;
use nalgebra::{Isometry2, Point2, Vector2};

use crate::VelocityCommand;
use crate::tactical::wrap_angle;

/// Headings searched for the passage's axis, either side of the stalled chair's heading, deg.
const SEARCH_DEG: i32 = 55;
/// The stretch of each lane examined, along it from the stalled chair's front centre, m: from a
/// little beside the front (the walls it is wedged between) to well inside the passage.
const LANE_FROM_M: f64 = -0.3;
const LANE_TO_M: f64 = 1.3;
/// Points farther than this to the side of a lane's line are not its walls, m.
const LANE_SIDE_M: f64 = 1.5;
/// Lanes wider than this are open floor, not a passage to line up with, m.
const WIDEST_PASSAGE_M: f64 = 1.5;
/// Lanes this close to the widest count as equally wide, m: the axis is their middle (a doorway
/// in a thin wall gives a flat optimum).
const WIDTH_TIE_M: f64 = 0.01;
/// Fewest dense points on each side of the lane for it to be a passage.
const MIN_WALL_POINTS: usize = 3;

/// How far before the entry the front of the docked chair stops, m: room to be sure it is lined
/// up before the passage narrows round it.
const DOCK_BEFORE_M: f64 = 0.3;
/// Run-in before the dock pose, m per metre of sideways offset, and at least: a wheelchair moves
/// sideways only along an S of arcs, and a sharp S swings its long front into the walls.
const RUN_IN_PER_OFFSET: f64 = 2.5;
const RUN_IN_MIN_M: f64 = 0.4;
/// Longest reversing to make the run-in, m.
const RUN_IN_MAX_M: f64 = 2.0;
/// Distance along the line over which the sideways offset is taken out, m: the approach angle
/// is `atan(offset / MERGE_M)`.
const MERGE_M: f64 = 0.6;
/// Steepest approach to the line, rad (35 degrees).
const MERGE_MAX_RAD: f64 = 0.61;
/// Offset from the line under which the chair is on it, m.
const LINED_UP_M: f64 = 0.03;
/// Gain of the heading control, 1/s.
const K_HEADING: f64 = 1.5;
/// Docking speeds at most, m/s and rad/s (those of the backing out).
const DOCK_MPS: f64 = 0.2;
const DOCK_TURN_RADPS: f64 = 0.6;
/// Heading error under which the chair is lined up, rad (3 degrees).
const ALIGNED_RAD: f64 = 0.05;
/// How far past the entry the front is taken along the centre line before docking hands back, m.
/// Handed back before the entry, the user's own steering (a head cap's lateral wobble, a
/// misjudged jamb) turned the lined-up chair off the line again, and it wedged at the same door
/// (two rooms, held-out driver 216: docked twice onto the lower door's line, wedged twice more).
const THROUGH_M: f64 = 1.0;

/// A passage's centre line (odometry frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lane {
    /// The centre line's point level with the stalled chair's front centre (the entry).
    pub(crate) entry: Point2<f64>,
    /// The axis, pointing into the passage, rad.
    pub(crate) heading: f64,
    /// The free width across it, m.
    pub(crate) width_m: f64,
}

/// The passage ahead of a stalled chair at `stalled` (odometry frame), from the dense points
/// `dense` (chair frame): the widest straight lane through the chair's front centre, with walls
/// on both sides, that the width climbs to from the chair's heading (it must be at least the
/// chair's width plus `margin_m` each side, at most [`WIDEST_PASSAGE_M`]). `None` if there is
/// none.
pub(crate) fn find_lane(
    stalled: &Isometry2<f64>,
    dense: &[Point2<f64>],
    fp: &Footprint,
    margin_m: f64,
) -> Option<Lane> {
    let front = Point2::new(fp.front_m, 0.0);
    let narrowest = 2.0 * (fp.half_width_m + margin_m);
    // (heading, left edge, right edge) of the lane through the front centre at each heading
    // searched (index SEARCH_DEG is the chair's own heading); None without walls on both sides.
    let lanes: Vec<Option<(f64, f64, f64)>> = (-SEARCH_DEG..=SEARCH_DEG)
        .map(|deg| {
            let heading = f64::from(deg).to_radians();
            let (sin, cos) = heading.sin_cos();
            let (mut left, mut right) = (f64::INFINITY, f64::NEG_INFINITY);
            let (mut on_left, mut on_right) = (0, 0);
            for p in dense {
                let d = p - front;
                let (u, v) = (d.x * cos + d.y * sin, -d.x * sin + d.y * cos);
                if !(LANE_FROM_M..=LANE_TO_M).contains(&u) || v.abs() > LANE_SIDE_M {
                    continue;
                }
                if v >= 0.0 {
                    left = left.min(v);
                    on_left += 1;
                } else {
                    right = right.max(v);
                    on_right += 1;
                }
            }
            (on_left >= MIN_WALL_POINTS && on_right >= MIN_WALL_POINTS)
                .then_some((heading, left, right))
        })
        .collect();
    let width = |i: usize| lanes[i].map_or(f64::NEG_INFINITY, |(_, l, r)| l - r);
    // The passage the chair stalled at is the one it was heading into: the widest lane reached
    // by climbing the width from the chair's own heading, either way, not the widest anywhere.
    // Through a doorway the lanes tilted far across the room beyond are wider than the door's
    // own (two rooms, seed 116: a 1.43 m lane 49 degrees off the 0.90 m door's axis), and
    // docking onto one drove the chair away from the door into the furniture, five times.
    let climb = |step: isize| {
        let (mut peak, mut i) = (SEARCH_DEG as usize, SEARCH_DEG as usize);
        while let Some(next) = i.checked_add_signed(step).filter(|&j| j < lanes.len()) {
            if lanes[next].is_none() || width(next) < width(peak) - WIDTH_TIE_M {
                break;
            }
            if width(next) > width(peak) {
                peak = next;
            }
            i = next;
        }
        peak
    };
    let (up, down) = (climb(1), climb(-1));
    let peak = if width(down) > width(up) { down } else { up };
    let widest = width(peak);
    if !(narrowest..=WIDEST_PASSAGE_M).contains(&widest) {
        return None;
    }
    // the lanes as wide as the peak next to it (a doorway in a thin wall gives a flat optimum)
    let flat = |i: &usize| lanes[*i].is_some() && width(*i) >= widest - WIDTH_TIE_M;
    let from = (0..peak).rev().take_while(flat).last().unwrap_or(peak);
    let to = (peak + 1..lanes.len())
        .take_while(flat)
        .last()
        .unwrap_or(peak);
    let ties: Vec<(f64, f64, f64)> = lanes[from..=to].iter().flatten().copied().collect();
    let n = ties.len() as f64;
    let heading = ties.iter().map(|t| t.0).sum::<f64>() / n;
    let middle = ties.iter().map(|(_, l, r)| (l + r) / 2.0).sum::<f64>() / n;
    let normal = Vector2::new(-heading.sin(), heading.cos());
    Some(Lane {
        entry: stalled * (front + normal * middle),
        heading: wrap_angle(stalled.rotation.angle() + heading),
        width_m: widest,
    })
}

/// Driving to the dock pose of a [`Lane`] and on into the passage, in four steps: turn on the
/// spot to the passage's axis, reverse along it until there is room for the run-in, the S onto
/// the centre line, then along the line until the front is [`THROUGH_M`] past the entry.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Docking {
    /// Where the axle ends up (odometry frame).
    goal: Point2<f64>,
    /// Heading it ends up with, rad.
    heading: f64,
    step: Step,
}

/// Where docking is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    /// Turning on the spot to the axis.
    Turn,
    /// Reversing along the axis until this far before the dock pose, m.
    Back { run_in_m: f64 },
    /// Driving forwards onto the dock pose.
    In,
    /// Lined up: on along the centre line until the front is [`THROUGH_M`] past the entry.
    Through,
}

impl Docking {
    /// Docking onto `lane` for a chair of `fp`.
    pub(crate) fn new(lane: &Lane, fp: &Footprint) -> Self {
        let axis = Vector2::new(lane.heading.cos(), lane.heading.sin());
        Docking {
            goal: lane.entry - axis * (fp.front_m + DOCK_BEFORE_M),
            heading: lane.heading,
            step: Step::Turn,
        }
    }

    /// Ends the run back when something behind holds it, so the chair merges onto the line from
    /// where it is; whether it was running back. The run back only buys a gentler S: giving up
    /// the whole docking there left the chair where it had come in off the line, and its user
    /// came in off the line again (two rooms, seed 116: held by the trolley behind, three times
    /// before the 0.85 m door, until the lap timed out).
    pub(crate) fn no_room_behind(&mut self) -> bool {
        let running_back = matches!(self.step, Step::Back { .. });
        if running_back {
            self.step = Step::In;
        }
        running_back
    }

    /// The chair's position relative to the dock pose: along the axis (negative before it) and
    /// across it, m.
    fn offsets(&self, pose: &Isometry2<f64>) -> (f64, f64) {
        let d = Point2::from(pose.translation.vector) - self.goal;
        let (sin, cos) = self.heading.sin_cos();
        (d.x * cos + d.y * sin, -d.x * sin + d.y * cos)
    }

    /// The commands towards the dock pose from `pose`, best first (the first one the sweep check
    /// clears is sent), or `None` when the chair is through the entry.
    pub(crate) fn commands(&mut self, pose: &Isometry2<f64>) -> Option<[VelocityCommand; 3]> {
        let theta = pose.rotation.angle();
        let error = wrap_angle(self.heading - theta);
        let hold = |gain: f64| (gain * error).clamp(-DOCK_TURN_RADPS, DOCK_TURN_RADPS);
        let scaled = |c: VelocityCommand| {
            [1.0, 0.6, 0.3].map(|s| VelocityCommand::new(c.linear_mps * s, c.angular_radps * s))
        };
        if self.step == Step::Turn {
            if error.abs() > ALIGNED_RAD {
                // A front corner that would swing into something on the spot may clear it while
                // the chair reverses, or once it has reversed.
                let turn = hold(K_HEADING);
                return Some([
                    VelocityCommand::new(0.0, turn),
                    VelocityCommand::new(-DOCK_MPS / 2.0, turn),
                    VelocityCommand::new(-DOCK_MPS / 2.0, 0.0),
                ]);
            }
            let (_, across) = self.offsets(pose);
            self.step = Step::Back {
                run_in_m: (RUN_IN_MIN_M + RUN_IN_PER_OFFSET * across.abs()).min(RUN_IN_MAX_M),
            };
        }
        if let Step::Back { run_in_m } = self.step {
            let (along, _) = self.offsets(pose);
            if along > -run_in_m {
                return Some(scaled(VelocityCommand::new(-DOCK_MPS, hold(K_HEADING))));
            }
            self.step = Step::In;
        }
        // Onto the line: heading for it at an angle that shrinks with the offset (at most
        // MERGE_MAX_RAD), so the chair comes alongside the line instead of swinging its front
        // through the walls beside it.
        let (along, across) = self.offsets(pose);
        if along >= 0.0 || (across.abs() < LINED_UP_M && error.abs() <= ALIGNED_RAD) {
            self.step = Step::Through;
        }
        if self.step == Step::Through && along >= DOCK_BEFORE_M + THROUGH_M {
            return None;
        }
        let wanted = self.heading
            - (across / MERGE_M)
                .atan()
                .clamp(-MERGE_MAX_RAD, MERGE_MAX_RAD);
        let w = (K_HEADING * wrap_angle(wanted - theta)).clamp(-DOCK_TURN_RADPS, DOCK_TURN_RADPS);
        Some(scaled(VelocityCommand::new(DOCK_MPS, w)))
    }
}

/// The wall sampler the recovery rig test uses too.
#[cfg(test)]
#[path = "../tests/support/walls.rs"]
mod walls;

#[cfg(test)]
mod tests {
    use super::walls::segment;
    use super::*;

    #[test]
    fn the_lane_is_the_passages_centre_line_and_axis_seen_from_a_chair_at_an_angle() {
        // A 0.95 m passage along +x from x = 0, centred on y = 0.3; the chair's front centre at
        // its entry 0.2 m right of the centre line, heading 27 degrees left of the axis.
        let mut walls = segment((-2.0, -0.175), (3.0, -0.175));
        walls.extend(segment((0.0, 0.775), (3.0, 0.775)));
        walls.extend(segment((0.0, 0.775), (0.0, 1.8)));
        let fp = Footprint::PROTOTYPE;
        let heading = 27f64.to_radians();
        let front = Point2::new(0.0, 0.1);
        let stalled = Isometry2::new(
            front.coords - Vector2::new(heading.cos(), heading.sin()) * fp.front_m,
            heading,
        );
        let inv = stalled.inverse();
        let dense: Vec<Point2<f64>> = walls.iter().map(|p| inv * p).collect();
        let lane = find_lane(&stalled, &dense, &fp, 0.05).expect("a passage");
        assert!(lane.heading.abs() < 2f64.to_radians(), "{lane:?}");
        assert!((lane.entry.y - 0.3).abs() < 0.03, "{lane:?}");
        assert!((lane.width_m - 0.95).abs() < 0.03, "{lane:?}");
        // one wall alone is not a passage, nor open floor
        let one: Vec<Point2<f64>> = segment((-2.0, -0.175), (3.0, -0.175))
            .iter()
            .map(|p| inv * p)
            .collect();
        assert_eq!(find_lane(&stalled, &one, &fp, 0.05), None);
        let open: Vec<Point2<f64>> = [
            segment((-2.0, -1.5), (3.0, -1.5)),
            segment((-2.0, 2.0), (3.0, 2.0)),
        ]
        .concat()
        .iter()
        .map(|p| inv * p)
        .collect();
        assert_eq!(find_lane(&stalled, &open, &fp, 0.05), None);
    }

    #[test]
    fn a_chair_stalled_in_a_doorway_docks_onto_the_door_not_a_wider_lane_across_the_room_beyond() {
        // The two rooms' lower door (0.90 m, in the wall x = 5) with the right room's south wall,
        // table and chair beyond, and the chair stalled with its front in the door, 9 cm right of
        // the door's centre line and 1 degree off its axis (seed 116). A lane tilted 47 degrees
        // to the right runs across the open room beyond and is 1.45 m wide (the widest anywhere,
        // which docking took before); the door's own is 0.90 m.
        let boxed = |x0: f64, y0: f64, x1: f64, y1: f64| {
            [
                segment((x0, y0), (x1, y0)),
                segment((x1, y0), (x1, y1)),
                segment((x1, y1), (x0, y1)),
                segment((x0, y1), (x0, y0)),
            ]
            .concat()
        };
        let walls = [
            segment((5.0, 0.0), (5.0, 1.05)),
            segment((5.0, 1.95), (5.0, 3.075)),
            segment((0.0, 0.0), (11.0, 0.0)),
            boxed(7.4, 0.2, 8.6, 1.0),
            boxed(6.05, 2.05, 6.55, 2.55),
            boxed(2.5, 0.325, 3.9, 0.925),
        ]
        .concat();
        let fp = Footprint::PROTOTYPE;
        let stalled = Isometry2::new(Vector2::new(4.29, 1.41), -1f64.to_radians());
        let inv = stalled.inverse();
        let dense: Vec<Point2<f64>> = walls.iter().map(|p| inv * p).collect();
        let lane = find_lane(&stalled, &dense, &fp, 0.05).expect("the door");
        assert!(lane.heading.abs() < 3f64.to_radians(), "{lane:?}");
        assert!((lane.entry.y - 1.5).abs() < 0.03, "{lane:?}");
        assert!((lane.width_m - 0.9).abs() < 0.03, "{lane:?}");
    }

    #[test]
    fn docking_brings_a_unicycle_onto_the_line_and_along_it_into_the_passage() {
        // Free space, a start 0.77 m off the centre line and 48 degrees off its axis, either
        // facing towards the dock pose or away from it.
        let fp = Footprint::PROTOTYPE;
        let lane = Lane {
            entry: Point2::new(0.0, 0.0),
            heading: 0.0,
            width_m: 0.95,
        };
        for start in [
            Isometry2::new(Vector2::new(-1.6, 0.77), -48f64.to_radians()),
            Isometry2::new(Vector2::new(-0.6, 0.77), -48f64.to_radians()),
            Isometry2::new(Vector2::new(-1.6, -0.5), 160f64.to_radians()),
        ] {
            let mut dock = Docking::new(&lane, &fp);
            let mut pose = start;
            let mut done = false;
            for _ in 0..2000 {
                let Some([c, ..]) = dock.commands(&pose) else {
                    done = true;
                    break;
                };
                let (v, w, dt) = (c.linear_mps, c.angular_radps, 0.05);
                pose = Isometry2::new(
                    pose.translation.vector
                        + Vector2::new(pose.rotation.angle().cos(), pose.rotation.angle().sin())
                            * v
                            * dt,
                    pose.rotation.angle() + w * dt,
                );
            }
            assert!(done, "{start:?} -> {pose:?}");
            assert!(pose.translation.y.abs() < 0.08, "{start:?} -> {pose:?}");
            assert!(pose.rotation.angle().abs() <= ALIGNED_RAD, "{pose:?}");
            // handed back with the front inside the passage, not before its entry
            assert!(
                pose.translation.x + fp.front_m >= THROUGH_M - 0.05,
                "{pose:?}"
            );
        }
    }
}
