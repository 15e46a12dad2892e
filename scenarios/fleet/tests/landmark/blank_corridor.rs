//! A map with nothing to match along a long corridor (issue 19, bad input): the laser sees only
//! the two parallel walls, so the localizer learns the chair's heading and its place across the
//! corridor from them but nothing along it. The estimate degrades gracefully: its covariance
//! grows along the corridor's axis (and only there), the error stays inside it, the pose does
//! not jump, and once its variance along the axis (the worst direction, what the cognitive agent
//! decides on) passes the detour's threshold the cognitive agent detours into the alcove whose
//! wall carries a landmark, where the marker resets the error.

use iw_sim::Map;
use nalgebra::{Isometry2, Vector2};

use crate::common::{Drive, Sample, covered, detour, print, stops};

/// A 2 m wide corridor, 60 m long, with a 2.5 m wide alcove on its south side at x = 48 whose
/// back wall carries landmark 1, and the goal near the east end. From the west end the laser
/// (10 m reach) sees no wall across the corridor's axis until it nears the alcove's opening, 9-10
/// m before it (measured: the along-axis variance falls to nothing at x = 27.5 m with the opening
/// at 36.75 m, at x = 19.0 m with it at 26.75 m), so the first 37 m are blank.
const CORRIDOR: &str = "\
name blank corridor
wall_height 2.7
wall 0 5 46.75 5
wall 49.25 5 60 5
wall 0 7 60 7
wall 0 5 0 7
wall 60 5 60 7
wall 46.75 5 46.75 1 49.25 1 49.25 5
landmark 1 48.0 1.0 90
place west-end 1.0 6.0
place east-end 58.0 6.0
";

/// The detour's threshold on the worst direction's variance here, m² (standard deviation 6.3
/// cm), not the deployment's 0.01 m²: an honest covariance does not reach that in a blank
/// stretch this test can drive. Measured on this map and seed (the derived matcher with the
/// acceleration-slip motion model): the along-axis variance grew to 0.0016 m² by x = 14 m, then
/// by 0.0002-0.0004 m² a metre, 0.0039 m² at x = 25 m, 0.0069 m² at 34 m and 0.0077 m² at 38.5 m
/// where the alcove came into view, while the error at the last scan read stayed within about
/// 3 cm; this threshold was crossed at x = 25.8-25.9 m (7 runs), 11 m before that. On shorter
/// maps of the same corridor it grew faster (0.0069 m² at x = 18-27 m); why was not traced.
const THRESHOLD_M2: f64 = 0.004;

/// Longest drive, s.
const MAX_S: f64 = 115.0;

/// Largest change of the error from one period to the next while nothing but the corridor's
/// walls is matched, m: what the published pose's lag (one publication, 0.1 s, at most a few
/// centimetres at walking speed) leaves; a match sliding along the corridor would move more.
const LAG_M: f64 = 0.05;

#[test]
fn a_blank_corridor_grows_the_covariance_along_its_axis_and_the_chair_detours_to_a_landmark() {
    let map = Map::parse(CORRIDOR, "blank corridor").unwrap();
    let (samples, fleet) = Drive {
        map: &map,
        seed: 3,
        start: Isometry2::new(Vector2::new(1.0, 6.0), 0.0),
        place: "east-end",
        blind: false,
        threshold_m2: Some(THRESHOLD_M2),
        max_s: MAX_S,
    }
    .run();
    print("corridor", &samples);
    let stops = stops(&fleet);
    assert_eq!(stops.len(), 1, "the alcove's landmark is a stop: {stops:?}");
    let d = detour(&samples, &stops, THRESHOLD_M2);
    println!("{d:#?}");
    let blank = &samples[..d.crossed_at];

    // the uncertainty is along the corridor: x's standard deviation several times y's
    let c = d.crossed.covariance;
    assert!(
        c[(0, 0)] > 9.0 * c[(1, 1)],
        "the covariance did not grow along the axis: {c}"
    );
    // across it the walls keep the chair within a few centimetres
    let worst_across = blank.iter().map(|s| s.error().y.abs()).fold(0.0, f64::max);
    assert!(
        worst_across < 0.05,
        "{worst_across:.3} m off across the corridor"
    );
    // honest: the error within 2 sqrt(trace) (98 % if consistent; room for the camera rate)
    let cover = covered(blank);
    assert!(
        cover >= 0.9,
        "error within 2 sigma on {:.0} % of the periods",
        cover * 100.0
    );
    // and still honest after the crossing, through the chair's swerve off the axis towards the
    // landmark, until it is there: the walls see the swerve, which tells the wheels' scale and
    // through it the place along the axis (with main's cautious covariance the worst
    // direction's variance fell from 0.01 m² to about 0.003 m² in 2 s);
    // the error must stay inside the smaller covariance. Measured against the pose the
    // published estimate is of (see `Sample::sensed`): against the truth a period on, the
    // estimate trails by 2.5-5 cm, which once the alcove's walls pin it to millimetres is most
    // of the periods
    let detour_leg = &samples[d.crossed_at..d.arrived_at];
    let cover_after = covered(detour_leg);
    // the most standard deviations off, in the swerve (the 10 s after the crossing) and in all
    // of the leg (where the alcove's walls pin the estimate to millimetres, a period's lag counts)
    let most_off = |leg: &[Sample]| {
        let worst = leg
            .iter()
            .max_by(|a, b| sd_at_read(a).total_cmp(&sd_at_read(b)))
            .copied()
            .expect("the crossing is before the arrival");
        format!(
            "{:.2} sd at {:.1} s at ({:.2}, {:.2}), {:.3} m off at the read, trace {:.5} m2",
            sd_at_read(&worst),
            worst.t_s,
            worst.truth.x,
            worst.truth.y,
            worst.error_at_read_m(),
            worst.trace_m2()
        )
    };
    let swerve = detour_leg
        .iter()
        .take_while(|s| s.t_s < d.crossed.t_s + 10.0)
        .count();
    println!(
        "from the crossing to the landmark ({} periods): error within 2 sigma {:.0} %, \
         largest error at the read {:.3} m; most off in the swerve {}; in the leg {}",
        detour_leg.len(),
        cover_after * 100.0,
        detour_leg
            .iter()
            .map(Sample::error_at_read_m)
            .fold(0.0, f64::max),
        most_off(&detour_leg[..swerve]),
        most_off(detour_leg)
    );
    assert!(
        cover_after >= 0.9,
        "error within 2 sigma on {:.0} % of the periods from the crossing to the landmark",
        cover_after * 100.0
    );
    // no jump: the error changes smoothly while only the corridor's walls are matched
    let jump = largest_jump(blank);
    println!(
        "blank stretch to x = {:.2} m: error within 2 sigma {:.0} %, largest change of the error \
         between periods {jump:.3} m, largest error across {worst_across:.3} m",
        d.crossed.truth.x,
        cover * 100.0
    );
    assert!(
        jump < LAG_M,
        "the estimate jumped by {jump:.3} m in the blank corridor"
    );
    // and a correction (the alcove's walls, the marker) moves it towards the truth, not away
    for w in samples.windows(2) {
        let (a, b) = (w[0], w[1]);
        assert!(
            b.error_m() <= a.error_m() + LAG_M,
            "the estimate moved {:.3} m away from the truth at {:.1} s",
            b.error_m() - a.error_m(),
            b.t_s
        );
    }
    // the detour: into the alcove (off the way to the east end), where the marker resets it
    assert!(
        d.arrived.truth.y < 4.0,
        "the stop is in the alcove: {:?}",
        d.arrived
    );
    assert!(
        d.after.trace_m2() < d.crossed.trace_m2() / 2.0 && d.after.error_m() < 0.05,
        "the marker did not reset the estimate: crossed {:?}, after {:?}",
        d.crossed,
        d.after
    );
}

/// The largest change of the error vector from one period to the next, m.
fn largest_jump(samples: &[Sample]) -> f64 {
    samples
        .windows(2)
        .map(|w| (w[1].error() - w[0].error()).norm())
        .fold(0.0, f64::max)
}

/// The error against the pose the agents read (the nearer of the two), in standard deviations
/// of the estimate's x-y covariance (the Mahalanobis distance).
fn sd_at_read(s: &Sample) -> f64 {
    let Some(inverse) = s.covariance.try_inverse() else {
        return f64::INFINITY;
    };
    s.sensed
        .iter()
        .map(|p| {
            let e = s.estimate - p;
            (e.transpose() * inverse * e)[(0, 0)].max(0.0).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}
