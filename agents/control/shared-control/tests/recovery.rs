//! The arc guard backing a stalled chair out of a tight passage's entry, on a deterministic rig:
//! a 0.95 m passage between a row of seats and a wall, as on the ward corridor, and a user who
//! keeps steering for the passage's centre line, or one who only pushes straight ahead. The rig
//! moves the chair as the guard commands (each wheel ramping at 1 m/s^2) and gives the guard every
//! wall point within reach (as a dense sensor's points), with the chair's motion, each 50 ms
//! period.

use iw_body::TRACK_M;
use iw_body::layout::Footprint;
use iw_shared_control::{
    ArcGuard, ArcGuardParams, Motion, SharedController, SharedInput, VelocityCommand,
};
use nalgebra::{Isometry2, Point2, Vector2};

#[path = "support/walls.rs"]
mod walls;
use walls::segment;

const PERIOD_S: f64 = 0.05;
/// Half the passage's width, m (0.95 m between the seats and the wall).
const HALF_PASSAGE_M: f64 = 0.475;

/// The passage runs along +x from x = 0 to 3 m, centred on y = 0. The wall on its right goes on
/// along the approach; the seats on its left start at x = 0, and the corridor before them is 2 m
/// wide.
fn passage() -> Vec<Point2<f64>> {
    let mut walls = segment((-4.0, -HALF_PASSAGE_M), (4.0, -HALF_PASSAGE_M));
    walls.extend(segment((0.0, HALF_PASSAGE_M), (3.0, HALF_PASSAGE_M)));
    walls.extend(segment((0.0, HALF_PASSAGE_M), (0.0, 1.525)));
    walls.extend(segment((-4.0, 1.525), (4.0, 1.525)));
    walls
}

/// Distance from `p` (chair frame) to the bare footprint (0 inside).
fn distance(fp: &Footprint, p: &Point2<f64>) -> f64 {
    let dx = (p.x - fp.front_m).max(-fp.rear_m - p.x).max(0.0);
    let dy = (p.y.abs() - fp.half_width_m).max(0.0);
    dx.hypot(dy)
}

/// A chair driven through the guard on the rig.
struct Rig {
    guard: ArcGuard,
    walls: Vec<Point2<f64>>,
    pose: Isometry2<f64>,
    /// Wheel speeds (left, right), m/s.
    wheels: (f64, f64),
    time_ns: u64,
    /// Smallest distance from the footprint to each wall point so far, m.
    nearest: Vec<f64>,
    backed: bool,
    docked: bool,
}

impl Rig {
    fn new(walls: Vec<Point2<f64>>, pose: Isometry2<f64>, recovery: bool) -> Self {
        Self::with_docking(walls, pose, recovery, true)
    }

    fn with_docking(
        walls: Vec<Point2<f64>>,
        pose: Isometry2<f64>,
        recovery: bool,
        dock: bool,
    ) -> Self {
        let fp = Footprint::PROTOTYPE;
        let params = ArcGuardParams {
            dock,
            ..ArcGuardParams::default()
        };
        let mut guard = ArcGuard::new(params, fp, Vec::new()).unwrap();
        guard.set_recovery(recovery);
        let inv = pose.inverse();
        let nearest = walls.iter().map(|p| distance(&fp, &(inv * p))).collect();
        Rig {
            guard,
            walls,
            pose,
            wheels: (0.0, 0.0),
            time_ns: 0,
            nearest,
            backed: false,
            docked: false,
        }
    }

    /// One period with the user asking for `user`.
    fn step(&mut self, user: VelocityCommand) {
        let fp = Footprint::PROTOTYPE;
        let inv = self.pose.inverse();
        let seen: Vec<Point2<f64>> = self
            .walls
            .iter()
            .map(|p| inv * p)
            .filter(|p| p.coords.norm() < 2.5)
            .collect();
        let (l, r) = self.wheels;
        let twist = VelocityCommand::new((l + r) / 2.0, (r - l) / TRACK_M);
        let out = self
            .guard
            .step(&SharedInput {
                user,
                speed_mps: twist.linear_mps.abs(),
                sonar_m: &[],
                points_chair: &seen,
                motion: Some(Motion {
                    time_ns: self.time_ns,
                    t_odom_chair: self.pose,
                    twist,
                }),
            })
            .unwrap();
        self.backed |= self.guard.is_backing();
        self.docked |= self.guard.is_docking();
        let c = out.command;
        let goal = (
            c.linear_mps - c.angular_radps * TRACK_M / 2.0,
            c.linear_mps + c.angular_radps * TRACK_M / 2.0,
        );
        let step = 1.0 * PERIOD_S;
        let toward = |v: f64, g: f64| v + (g - v).clamp(-step, step);
        let new = (toward(l, goal.0), toward(r, goal.1));
        let (l, r) = ((l + new.0) / 2.0, (r + new.1) / 2.0);
        self.wheels = new;
        let (v, w) = ((l + r) / 2.0, (r - l) / TRACK_M);
        let th = w * PERIOD_S;
        let (x, y) = if w.abs() < 1e-9 {
            (v * PERIOD_S, 0.0)
        } else {
            (v / w * th.sin(), v / w * (1.0 - th.cos()))
        };
        self.pose *= Isometry2::new(Vector2::new(x, y), th);
        self.time_ns += (PERIOD_S * 1e9) as u64;
        let inv = self.pose.inverse();
        for (p, nearest) in self.walls.iter().zip(&mut self.nearest) {
            *nearest = nearest.min(distance(&fp, &(inv * p)));
        }
    }

    /// A user who keeps pushing forward at 0.3 m/s, steering by pure pursuit for the centre
    /// line 0.6 m ahead (sharply: they come in at an angle).
    fn user(&self) -> VelocityCommand {
        let here = self.pose.translation.vector;
        let heading = self.pose.rotation.angle();
        let target = Vector2::new(here.x + 0.6, 0.0) - here;
        let alpha = target.y.atan2(target.x) - heading;
        let alpha = alpha.sin().atan2(alpha.cos());
        VelocityCommand::new(0.3, (2.0 * 0.3 * alpha.sin() / 0.6).clamp(-0.8, 0.8))
    }

    /// Drives for `seconds` or until the chair's axle is 2.5 m into the passage; whether it got
    /// there.
    fn drive(&mut self, seconds: f64) -> bool {
        self.drive_with(seconds, Self::user)
    }

    /// [`Self::drive`] with the user's command from `user`.
    fn drive_with(&mut self, seconds: f64, user: impl Fn(&Self) -> VelocityCommand) -> bool {
        for _ in 0..(seconds / PERIOD_S) as usize {
            if self.pose.translation.x > 2.5 {
                return true;
            }
            let command = user(self);
            self.step(command);
        }
        false
    }

    /// How far off the passage's centre line the axle is, m, and off its axis the heading, rad.
    fn off_line(&self) -> (f64, f64) {
        (
            self.pose.translation.y.abs(),
            self.pose.rotation.angle().abs(),
        )
    }
}

/// A user who only pushes straight ahead (0.3 m/s, no turn), as a head-cap user who holds the
/// head tilted forward does: they never line the chair up themselves.
fn straight(_: &Rig) -> VelocityCommand {
    VelocityCommand::new(0.3, 0.0)
}

/// An approach aimed at the entry at 27 degrees: pushed straight, the chair wedges with its front
/// right corner at the wall and its left side at the seats' corner.
fn aimed() -> Isometry2<f64> {
    Isometry2::new(Vector2::new(-1.6, 1.0), -30f64.to_radians())
}

#[test]
fn a_straight_pushing_user_is_docked_onto_the_centre_line_and_drives_in() {
    // Backing out alone retraces the straight way in, so the same push wedges the chair again,
    // for as long as the user pushes.
    let mut undocked = Rig::with_docking(passage(), aimed(), true, false);
    assert!(
        !undocked.drive_with(120.0, straight),
        "the rig must wedge a straight-pushing user whom the guard only backs out"
    );
    assert!(undocked.backed && !undocked.docked);
    // With docking, the chair is brought onto the centre line, lined up, and the same push takes
    // it through, touching nothing.
    let mut rig = Rig::new(passage(), aimed(), true);
    let mut lined_up = None;
    let mut through = false;
    for _ in 0..(120.0 / PERIOD_S) as usize {
        if rig.pose.translation.x > 2.5 {
            through = true;
            break;
        }
        let was_docking = rig.guard.is_docking();
        rig.step(straight(&rig));
        if was_docking && !rig.guard.is_docking() && lined_up.is_none() {
            lined_up = Some(rig.off_line());
        }
    }
    assert!(rig.backed && rig.docked, "it backed out and docked");
    let (offset, angle) = lined_up.expect("docking ended");
    assert!(
        offset < 0.08 && angle < 0.06,
        "docked {offset} m off the centre line, {angle} rad off the axis"
    );
    assert!(through, "still stuck at {:?}", rig.pose);
    let closest = rig.nearest.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(closest > 0.0, "touched a wall: {closest}");
}

/// The start of an approach that wedges the chair: 1.4 m before the passage, 1 m towards the
/// seats' side of its centre line, heading along it. The user's sharp pursuit brings the chair to
/// the entry about 0.22 m off the centre line and 27 degrees off the axis, as on the ward
/// corridor.
fn approach() -> Isometry2<f64> {
    Isometry2::new(Vector2::new(-1.4, 1.0), 0.0)
}

#[test]
fn a_chair_wedged_at_a_passage_entry_backs_out_and_gets_through() {
    // Without the way out, the guard holds the chair at the entry for as long as the user pushes.
    let mut held = Rig::new(passage(), approach(), false);
    assert!(
        !held.drive(120.0),
        "the rig must wedge a chair without recovery"
    );
    let stuck = held.pose;
    assert!(
        stuck.translation.x < 0.0 && stuck.rotation.angle() < -0.3,
        "wedged at the entry at an angle, not inside: {stuck:?}"
    );
    // With it, the same user gets through, and nothing came nearer than the margin's rule allows:
    // no contact anywhere.
    let mut rig = Rig::new(passage(), approach(), true);
    assert!(rig.drive(120.0), "still stuck at {:?}", rig.pose);
    assert!(rig.backed, "it got through by backing out");
    let closest = rig.nearest.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(closest > 0.0, "touched a wall: {closest}");
}

#[test]
fn a_chair_that_would_back_into_something_stays_where_it_is() {
    // The same wedge, with a post put in just behind the chair once it is wedged, where the way
    // back runs: backing out would bring the post closer, so the guard does not back.
    let mut probe = Rig::new(passage(), approach(), false);
    probe.drive(60.0);
    let wedged = probe.pose;
    let mut rig = Rig::new(passage(), approach(), true);
    // Until it backs, the guard with recovery drives exactly as without.
    let at_wedge = |pose: &Isometry2<f64>| {
        (pose.translation.vector - wedged.translation.vector).norm() < 0.01
            && (pose.rotation.angle() - wedged.rotation.angle()).abs() < 0.01
    };
    for _ in 0..1200 {
        if at_wedge(&rig.pose) {
            break;
        }
        let user = rig.user();
        rig.step(user);
    }
    assert!(at_wedge(&rig.pose) && !rig.backed, "{:?}", rig.pose);
    let fp = Footprint::PROTOTYPE;
    // A post 3 cm behind the rear, across the chair's whole width.
    let post: Vec<Point2<f64>> = (-4..=4)
        .map(|k| rig.pose * Point2::new(-fp.rear_m - 0.03, k as f64 * 0.08))
        .collect();
    let inv = rig.pose.inverse();
    let before: Vec<f64> = post.iter().map(|p| distance(&fp, &(inv * p))).collect();
    rig.walls.extend(&post);
    rig.nearest.extend(&before);
    rig.drive(60.0);
    let after = &rig.nearest[rig.nearest.len() - post.len()..];
    for (now, then) in after.iter().zip(&before) {
        assert!(
            *now + 1e-6 >= *then,
            "came closer to the post: {then} -> {now}"
        );
    }
    let closest = rig.nearest.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(closest > 0.0, "touched something: {closest}");
    assert!(rig.pose.translation.x < 0.5, "it cannot have got through");
}

#[test]
fn a_docking_with_no_room_behind_to_run_back_lines_up_from_where_it_is() {
    // The straight-pushing user's docking, with a post put in 0.6 m behind the rear, across the
    // chair's whole width, once docking has turned the chair to the axis and starts reversing
    // along it for its run-in (1.85 m for this chair, 0.58 m off the line): the post holds the
    // run back short, as the trolley behind the chair did before the two rooms' upper door
    // (seed 116). Giving up the docking there left the chair off the line where it had come in,
    // and the same push wedged it again.
    let mut rig = Rig::new(passage(), aimed(), true);
    let mut post_at = None;
    for _ in 0..(60.0 / PERIOD_S) as usize {
        let (l, r) = rig.wheels;
        if rig.guard.is_docking() && l < -0.15 && r < -0.15 {
            post_at = Some(rig.pose);
            break;
        }
        rig.step(straight(&rig));
    }
    let at = post_at.expect("docking runs back along the axis");
    let fp = Footprint::PROTOTYPE;
    let post: Vec<Point2<f64>> = (-4..=4)
        .map(|k| at * Point2::new(-fp.rear_m - 0.6, k as f64 * 0.08))
        .collect();
    let inv = rig.pose.inverse();
    let before: Vec<f64> = post.iter().map(|p| distance(&fp, &(inv * p))).collect();
    rig.walls.extend(&post);
    rig.nearest.extend(&before);
    assert!(
        rig.drive_with(120.0, straight),
        "still stuck at {:?}",
        rig.pose
    );
    let closest = rig.nearest.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(closest > 0.0, "touched something: {closest}");
}
