//! Narrow passages on a path: where a chair must stop, ask the watcher, drive through and let go.
//!
//! [`legs`] cuts a path (the chair's position, then its waypoints) into [`Leg`]s: drive to a
//! point [`WAIT_BACK_M`] before a passage, acquire it, drive until the whole chair is
//! [`CLEAR_M`] past its exit, release it, and so on. Each passage the path crosses is acquired
//! once, in the direction of crossing, and released once the chair is clear of it; a chair that
//! starts inside one acquires it before it moves (it cannot wait outside), and a path that ends
//! inside one keeps it (the next motion, which starts inside, releases it).

use std::collections::BTreeSet;

use nalgebra::{Point2, Vector2};

/// A chair waits this far (along its path) before a passage's edge, m: its front stays out
/// of the passage and out of the way of chairs leaving it.
pub const WAIT_BACK_M: f64 = 1.0;

/// A chair lets a passage go once its centre is this far past the exit, m: the rear of the
/// chair is out too.
pub const CLEAR_M: f64 = 0.8;

/// A path that leaves a passage and comes back into it within this, m, is still crossing it
/// (a bulge into a side opening): the chair keeps it rather than let go where it is in the way.
pub const REENTRY_M: f64 = 5.0;

/// Spacing at which a path is checked against passages, m.
const SAMPLE_M: f64 = 0.05;

/// The strip around an axis that chairs cross one direction at a time (a corridor, a doorway).
#[derive(Debug, Clone, PartialEq)]
pub struct NarrowPassage {
    /// The name the watcher knows it by.
    pub name: String,
    /// One end of the axis, map frame, m.
    pub a: Point2<f64>,
    /// The other end, map frame, m.
    pub b: Point2<f64>,
    /// Width of the strip, m.
    pub width_m: f64,
}

impl NarrowPassage {
    /// Position along the axis from `a` (0) to `b` (1); unclamped.
    pub fn along(&self, p: &Point2<f64>) -> f64 {
        let axis = self.b - self.a;
        (p - self.a).dot(&axis) / axis.norm_squared().max(f64::EPSILON)
    }

    /// Whether `p` is inside the strip.
    pub fn contains(&self, p: &Point2<f64>) -> bool {
        let t = self.along(p);
        let axis: Vector2<f64> = self.b - self.a;
        let off_axis = (p - (self.a + axis * t)).norm();
        (0.0..=1.0).contains(&t) && off_axis <= self.width_m / 2.0
    }

    /// `forward` when going from `from` to `to` moves from `a`'s end towards `b`'s.
    pub fn direction(&self, from: &Point2<f64>, to: &Point2<f64>) -> &'static str {
        if self.along(to) >= self.along(from) {
            "forward"
        } else {
            "backward"
        }
    }
}

/// One part of carrying out a motion.
#[derive(Debug, Clone, PartialEq)]
pub enum Leg {
    /// Drive through these waypoints (map frame, m).
    Drive(Vec<Point2<f64>>),
    /// Ask the watcher for the passage and wait for the grant.
    Acquire {
        /// The passage.
        passage: String,
        /// `forward` or `backward`.
        direction: &'static str,
    },
    /// Tell the watcher the chair is out, once it is at `at` (the chair does not stop there).
    Release {
        /// The passage.
        passage: String,
        /// Where the chair is clear of it, map frame, m.
        at: Point2<f64>,
    },
}

/// A polyline measured by arc length.
struct Polyline<'a> {
    points: &'a [Point2<f64>],
    /// Arc length at each point.
    at: Vec<f64>,
}

impl<'a> Polyline<'a> {
    fn new(points: &'a [Point2<f64>]) -> Self {
        let mut at = Vec::with_capacity(points.len());
        let mut s = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                s += (p - points[i - 1]).norm();
            }
            at.push(s);
        }
        Polyline { points, at }
    }

    fn length(&self) -> f64 {
        self.at.last().copied().unwrap_or(0.0)
    }

    fn point_at(&self, s: f64) -> Point2<f64> {
        let i = self
            .at
            .partition_point(|&a| a <= s)
            .clamp(1, self.points.len().max(2) - 1);
        let (Some(p), Some(q)) = (self.points.get(i - 1), self.points.get(i)) else {
            return self.points.first().copied().unwrap_or_else(Point2::origin);
        };
        let span = self.at[i] - self.at[i - 1];
        let t = if span > 0.0 {
            ((s - self.at[i - 1]) / span).clamp(0.0, 1.0)
        } else {
            1.0
        };
        p + (q - p) * t
    }

    /// The vertices after arc length `s0` up to and including `s1`.
    fn vertices(&self, s0: f64, s1: f64) -> Vec<Point2<f64>> {
        self.points
            .iter()
            .zip(&self.at)
            .filter(|&(_, &a)| a > s0 + 1e-9 && a <= s1 + 1e-9)
            .map(|(p, _)| *p)
            .collect()
    }

    /// The waypoints of a drive from arc length `s0` that stops at `s1`: the vertices between,
    /// then `s1`'s point.
    fn between(&self, s0: f64, s1: f64) -> Vec<Point2<f64>> {
        let mut out: Vec<Point2<f64>> = self
            .points
            .iter()
            .zip(&self.at)
            .filter(|&(_, &a)| a > s0 + 1e-9 && a < s1 - 1e-9)
            .map(|(p, _)| *p)
            .collect();
        out.push(self.point_at(s1));
        out
    }
}

/// The passages `path` enters at some point.
pub fn touched<'a>(path: &[Point2<f64>], passages: &'a [NarrowPassage]) -> BTreeSet<&'a str> {
    let line = Polyline::new(path);
    let samples = (line.length() / SAMPLE_M).ceil() as usize;
    let points: Vec<Point2<f64>> = (0..=samples)
        .map(|k| line.point_at((k as f64 * SAMPLE_M).min(line.length())))
        .collect();
    passages
        .iter()
        .filter(|q| points.iter().any(|p| q.contains(p)))
        .map(|q| q.name.as_str())
        .collect()
}

/// The legs of driving `path` (the chair's position first) past `passages`; those in `held`
/// are already granted to this chair and are only released.
pub fn legs(path: &[Point2<f64>], passages: &[NarrowPassage], held: &BTreeSet<String>) -> Vec<Leg> {
    let mut held = held.clone();
    let line = Polyline::new(path);
    let length = line.length();
    let samples = (length / SAMPLE_M).ceil() as usize;
    let s_of = |k: usize| (k as f64 * SAMPLE_M).min(length);
    let mut out = Vec::new();
    let mut driven = 0.0;
    let mut k = 0;
    while k <= samples {
        let p = line.point_at(s_of(k));
        let Some(passage) = passages.iter().find(|q| q.contains(&p)) else {
            k += 1;
            continue;
        };
        let entry = s_of(k);
        let inside = |j: usize| passage.contains(&line.point_at(s_of(j)));
        let mut exit_k = k;
        loop {
            while exit_k <= samples && inside(exit_k) {
                exit_k += 1;
            }
            let back = (exit_k..=samples)
                .take_while(|&j| s_of(j) - s_of(exit_k) <= REENTRY_M)
                .find(|&j| inside(j));
            match back {
                Some(j) => exit_k = j,
                None => break,
            }
        }
        let exit = s_of(exit_k);
        if !held.contains(&passage.name) {
            let wait = (entry - WAIT_BACK_M).max(driven);
            if wait > driven {
                out.push(Leg::Drive(line.between(driven, wait)));
                driven = wait;
            }
            let direction = passage.direction(&line.point_at(entry), &line.point_at(exit));
            out.push(Leg::Acquire {
                passage: passage.name.clone(),
                direction,
            });
        }
        let ends_inside = exit_k > samples;
        let clear = (exit + CLEAR_M).min(length);
        // Only the path's own vertices: the chair drives on past the release point.
        let through = line.vertices(driven, clear);
        if !through.is_empty() {
            out.push(Leg::Drive(through));
        }
        driven = driven.max(clear);
        if ends_inside {
            break;
        }
        held.remove(&passage.name);
        out.push(Leg::Release {
            passage: passage.name.clone(),
            at: line.point_at(clear),
        });
        // Past the clearance, so the same passage is not seen again as the chair leaves it.
        k = ((clear / SAMPLE_M).floor() as usize + 1).max(exit_k);
    }
    if length > driven || out.is_empty() {
        out.push(Leg::Drive(line.between(driven, length)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn corridor() -> NarrowPassage {
        NarrowPassage {
            name: "corridor".into(),
            a: Point2::new(2.0, 6.0),
            b: Point2::new(12.0, 6.0),
            width_m: 2.0,
        }
    }

    fn end_of(legs: &[Leg]) -> Option<Point2<f64>> {
        legs.iter().rev().find_map(|l| match l {
            Leg::Drive(w) => w.last().copied(),
            _ => None,
        })
    }

    #[test]
    fn a_crossing_waits_outside_acquires_and_releases_once_clear() {
        let path = [
            Point2::new(0.0, 6.0),
            Point2::new(14.0, 6.0),
            Point2::new(14.0, 9.0),
        ];
        let legs = legs(&path, &[corridor()], &BTreeSet::new());
        let [
            Leg::Drive(to_wait),
            Leg::Acquire { direction, .. },
            Leg::Release { at, .. },
            Leg::Drive(rest),
        ] = legs.as_slice()
        else {
            panic!("{legs:?}");
        };
        assert_eq!(*direction, "forward");
        assert!(
            (to_wait.last().unwrap().x - 1.0).abs() < 0.06,
            "waits 1 m before x = 2: {to_wait:?}"
        );
        assert!(
            (at.x - 12.8).abs() < 0.06 && at.y == 6.0,
            "released 0.8 m past x = 12: {at:?}"
        );
        assert_eq!(
            rest,
            &vec![Point2::new(14.0, 6.0), Point2::new(14.0, 9.0)],
            "no waypoint added past the wait point"
        );
    }

    #[test]
    fn crossing_back_is_backward_and_a_start_inside_acquires_first() {
        let path = [Point2::new(5.0, 6.0), Point2::new(0.0, 6.0)];
        let legs = legs(&path, &[corridor()], &BTreeSet::new());
        assert_eq!(
            legs[0],
            Leg::Acquire {
                passage: "corridor".into(),
                direction: "backward"
            }
        );
        assert!(matches!(&legs[1], Leg::Release { .. }), "{legs:?}");
    }

    #[test]
    fn a_bulge_out_of_the_passage_is_still_one_crossing() {
        // Out through the side for 2 m (into a doorway) and back in: held throughout.
        let path = [
            Point2::new(0.0, 6.0),
            Point2::new(6.0, 6.0),
            Point2::new(6.0, 7.5),
            Point2::new(6.5, 7.5),
            Point2::new(6.5, 6.0),
            Point2::new(14.0, 6.0),
        ];
        let acquires = |path: &[Point2<f64>]| {
            legs(path, &[corridor()], &BTreeSet::new())
                .iter()
                .filter(|l| matches!(l, Leg::Acquire { .. }))
                .count()
        };
        assert_eq!(acquires(&path), 1);
        // Far apart, two crossings.
        let path = [
            Point2::new(0.0, 6.0),
            Point2::new(6.0, 6.0),
            Point2::new(6.0, 12.0),
            Point2::new(7.0, 12.0),
            Point2::new(7.0, 6.0),
            Point2::new(14.0, 6.0),
        ];
        assert_eq!(acquires(&path), 2);
    }

    #[test]
    fn a_path_ending_inside_keeps_the_passage() {
        let path = [Point2::new(0.0, 6.0), Point2::new(5.0, 6.0)];
        let legs = legs(&path, &[corridor()], &BTreeSet::new());
        assert!(
            matches!(
                legs.as_slice(),
                [Leg::Drive(_), Leg::Acquire { .. }, Leg::Drive(_)]
            ),
            "{legs:?}"
        );
        assert_eq!(end_of(&legs), Some(Point2::new(5.0, 6.0)));
    }

    #[test]
    fn a_held_passage_is_only_released_and_a_path_outside_is_one_drive() {
        let held = BTreeSet::from(["corridor".to_string()]);
        let path = [Point2::new(5.0, 6.0), Point2::new(0.0, 6.0)];
        assert!(matches!(
            legs(&path, &[corridor()], &held).as_slice(),
            [Leg::Release { .. }, Leg::Drive(_)]
        ));
        let outside = [Point2::new(0.0, 0.0), Point2::new(5.0, 1.0)];
        assert_eq!(
            legs(&outside, &[corridor()], &BTreeSet::new()),
            vec![Leg::Drive(vec![Point2::new(5.0, 1.0)])]
        );
        assert!(touched(&outside, &[corridor()]).is_empty());
        assert_eq!(touched(&path, &[corridor()]), BTreeSet::from(["corridor"]));
    }

    proptest! {
        /// Whatever the path, the legs end where it ends, and every acquire is released unless
        /// the path ends inside the passage.
        #[test]
        fn legs_end_at_the_goal_and_balance(points in proptest::collection::vec((-1.0..15.0f64, 3.0..9.0f64), 2..6)) {
            let path: Vec<Point2<f64>> = points.iter().map(|&(x, y)| Point2::new(x, y)).collect();
            let legs = legs(&path, &[corridor()], &BTreeSet::new());
            let end = end_of(&legs).unwrap();
            prop_assert!((end - path[path.len() - 1]).norm() < 1e-9, "{legs:?}");
            let acquired = legs.iter().filter(|l| matches!(l, Leg::Acquire { .. })).count();
            let released = legs.iter().filter(|l| matches!(l, Leg::Release { .. })).count();
            let inside = usize::from(corridor().contains(&path[path.len() - 1]));
            prop_assert_eq!(acquired, released + inside);
        }
    }
}
