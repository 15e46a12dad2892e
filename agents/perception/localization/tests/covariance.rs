//! The matcher's covariance comes from the match (issue 19, "the covariance must be honest"),
//! and a scan taken off its wheel step is covered by the localizer's scan-time term.

use std::sync::Arc;

use iw_body::TRACK_M;
use iw_localization::{
    LocalizationMap, Localizer, LocalizerConfig, ScanOutcome, Status, match_scan,
};
use iw_vo::{OdometryStep, Pose2, wrap_angle};
use nalgebra::{Matrix3, Vector3};

mod common;
use common::*;

fn map() -> Arc<LocalizationMap> {
    Arc::new(LocalizationMap::new(room(), vec![], 1.0).unwrap())
}

/// Uniform noise of standard deviation `sigma_m`, independent from beam to beam (splitmix64
/// of the salt and the beam: the shared `scan`'s noise is a Weyl sequence, whose neighbouring
/// beams cancel far better than independent noise does).
fn independent_noise(ranges: &mut [f64], sigma_m: f64, salt: u64) {
    for (k, r) in ranges.iter_mut().enumerate() {
        let mut z = salt
            .wrapping_mul(0x1000_0000_01B3)
            .wrapping_add(k as u64)
            .wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        let u = (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        *r += u * sigma_m * 12f64.sqrt();
    }
}

/// The matched pose's error against `truth`, and its NEES under the match's covariance.
fn matched(noise_m: f64, truth: &Pose2, salt: u64) -> (Vector3<f64>, f64, Matrix3<f64>) {
    let guess = Pose2::new(truth.x + 0.04, truth.y - 0.03, truth.theta + 0.02);
    let mut ranges = scan(&room(), truth, 0.0, salt);
    independent_noise(&mut ranges, noise_m, salt);
    let m = match_scan(&map(), &points(&ranges), &guess, &Default::default()).unwrap();
    let e = Vector3::new(
        m.pose.x - truth.x,
        m.pose.y - truth.y,
        wrap_angle(m.pose.theta - truth.theta),
    );
    let nees = (e.transpose() * m.covariance.try_inverse().unwrap() * e)[0];
    (e, nees, m.covariance)
}

#[test]
fn the_covariance_follows_the_noise_the_scan_shows() {
    let truth = Pose2::new(2.0, 2.0, 0.3);
    let (_, _, quiet) = matched(0.005, &truth, 7);
    let (_, _, noisy) = matched(0.02, &truth, 7);
    // four times the noise: sixteen times the variance (the points' assumed 2 cm is the same)
    let ratio = noisy.trace() / quiet.trace();
    assert!((8.0..32.0).contains(&ratio), "variance ratio {ratio}");
    // no fixed floor: a quiet scan in a room with corners pins the position to millimetres
    assert!(
        quiet[(0, 0)].sqrt() < 0.002 && quiet[(1, 1)].sqrt() < 0.002,
        "{quiet}"
    );
}

#[test]
fn match_errors_agree_with_their_covariance() {
    // 60 poses over the room's lower wing, each scan with its own noise
    let nees: Vec<f64> = (0..60u64)
        .map(|k| {
            let truth = Pose2::new(
                1.0 + 0.13 * (k % 20) as f64,
                1.0 + 0.9 * (k / 20) as f64,
                -0.6 + 0.07 * k as f64,
            );
            matched(0.01, &truth, 1000 + 97 * k).1
        })
        .collect();
    let mean = nees.iter().sum::<f64>() / nees.len() as f64;
    let inside = nees.iter().filter(|n| (0.216..=9.35).contains(*n)).count();
    // a consistent covariance: mean 3 (3 degrees of freedom), 95 % inside the interval
    assert!((1.5..=5.0).contains(&mean), "mean NEES {mean}: {nees:?}");
    assert!(
        inside >= 48,
        "{inside} of 60 inside [0.216, 9.35]: {nees:?}"
    );
}

/// Periods of the drive below, ns (the control period).
const PERIOD_NS: u64 = 50_000_000;

/// Drives the room's loop with scans cast where the chair was `lag(k)` periods before. `timed`:
/// the steps and scans carry their times (the scan fused at its own time), else each scan is
/// fused as if taken now. Returns the localizer and the largest position error.
fn drive_with_late_scans(timed: bool, lag: impl Fn(usize) -> usize) -> (Localizer, f64) {
    let world = room();
    let mut truth = Pose2::new(1.5, 1.5, 0.0);
    let mut past = vec![truth];
    let config = LocalizerConfig::new(Some(laser()), None, [0.01, 0.002, 0.01, 0.002]);
    let mut loc = Localizer::new(map(), config, Some((truth, Matrix3::identity() * 1e-4)));
    let mut worst: f64 = 0.0;
    for k in 0..400 {
        let (l, r) = if (k / 50) % 2 == 0 {
            (0.025, 0.025)
        } else {
            (0.02, 0.03)
        };
        let step = OdometryStep::from_wheels(l, r, TRACK_M);
        truth = truth.compose(&step.as_delta());
        past.push(truth);
        let now_ns = (k as u64 + 1) * PERIOD_NS;
        let late = lag(k).min(past.len() - 1);
        let ranges = scan(&world, &past[past.len() - 1 - late], 0.005, k as u64);
        if timed {
            loc.predict_at(now_ns, &step);
            loc.update_ranges_at(now_ns - late as u64 * PERIOD_NS, &ranges, &[]);
        } else {
            loc.predict(&step);
            loc.update_ranges(&ranges, &[]);
        }
        let e = loc.pose();
        worst = worst.max((e.x - truth.x).hypot(e.y - truth.y));
    }
    (loc, worst)
}

/// A scan 0 to 3 periods late (a mixed chair's ghost in a world process answers late, by a
/// different amount each time), fused at its own time: the chair stays tracked and learns no
/// wheel bias from the lag; fused as if taken now, the same drive rejects its scans and loses
/// the pose (what sank the tighter covariance in `mixed-reality` run as processes).
#[test]
fn scans_that_trail_the_wheels_are_fused_at_their_own_time() {
    let lag = |k: usize| (k.wrapping_mul(0x9E37_79B9) >> 7) % 4;
    let (loc, worst) = drive_with_late_scans(true, lag);
    assert_eq!(loc.status(), Status::Tracking);
    assert_eq!(loc.searches(), 0, "the chair lost its pose");
    assert!(worst < 0.02, "worst error {worst} m");
    let ([scale, heading], _) = loc.wheel_bias();
    assert!(
        scale.abs() < 0.005 && heading.abs() < 0.005,
        "a wheel bias learned from the lag: scale {scale}, heading {heading} rad/m"
    );

    let (loc, _) = drive_with_late_scans(false, lag);
    assert!(
        loc.searches() > 0,
        "late scans fused as if taken now kept the pose: the test does not show the lag"
    );
}

/// Scans on time are fused the same with or without their times.
#[test]
fn scans_on_time_are_fused_the_same_with_their_times() {
    let (timed, worst) = drive_with_late_scans(true, |_| 0);
    let (untimed, _) = drive_with_late_scans(false, |_| 0);
    assert!(worst < 0.01, "worst error {worst} m");
    let (a, b) = (timed.pose(), untimed.pose());
    assert!(
        (a.x - b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9 && (a.theta - b.theta).abs() < 1e-9
    );
    assert!((timed.covariance() - untimed.covariance()).abs().max() < 1e-12);
}

/// A scan fused late at its own time leaves the filter where fusing it on time would have: the
/// steps after it are done again, so the result is the same EKF.
#[test]
fn a_late_scan_gives_the_filter_it_would_have_had_on_time() {
    let world = room();
    let start = Pose2::new(1.5, 1.5, 0.0);
    let config = LocalizerConfig::new(Some(laser()), None, [0.01, 0.002, 0.01, 0.002]);
    let new = || {
        Localizer::new(
            map(),
            config.clone(),
            Some((start, Matrix3::identity() * 1e-4)),
        )
    };
    let (mut on_time, mut late) = (new(), new());
    let step = OdometryStep::from_wheels(0.03, 0.035, TRACK_M);
    let mut truth = start;
    let mut scans = Vec::new();
    for k in 1..=6u64 {
        truth = truth.compose(&step.as_delta());
        scans.push(scan(&world, &truth, 0.005, k));
    }
    // on time: each scan right after its step; late: scans 3 and 4 arrive after step 6
    for (k, ranges) in scans.iter().enumerate() {
        let t = (k as u64 + 1) * PERIOD_NS;
        on_time.predict_at(t, &step);
        assert!(matches!(
            on_time.update_ranges_at(t, ranges, &[]),
            ScanOutcome::Fused { .. }
        ));
        late.predict_at(t, &step);
        if k < 2 {
            late.update_ranges_at(t, ranges, &[]);
        }
        if k == 1 {
            late.update_visual(&step.as_delta(), &(Matrix3::identity() * 1e-4));
            on_time.update_visual(&step.as_delta(), &(Matrix3::identity() * 1e-4));
        }
    }
    for (k, ranges) in scans.iter().enumerate().skip(2) {
        let outcome = late.update_ranges_at((k as u64 + 1) * PERIOD_NS, ranges, &[]);
        assert!(matches!(outcome, ScanOutcome::Fused { .. }), "{outcome:?}");
    }
    let (a, b) = (on_time.pose(), late.pose());
    assert!(
        (a.x - b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9 && (a.theta - b.theta).abs() < 1e-9,
        "{a:?} against {b:?}"
    );
    assert!((on_time.covariance() - late.covariance()).abs().max() < 1e-12);
    // the same frame read again is not fused twice
    assert_eq!(
        late.update_ranges_at(6 * PERIOD_NS, &scans[5], &[]),
        ScanOutcome::Stale
    );
}

/// A body whose clock starts again (a board that restarted) keeps its scans fused: a time far
/// behind the last scan's is a new clock, not a stale scan.
#[test]
fn a_body_clock_that_starts_again_keeps_the_scans_fused() {
    let world = room();
    let start = Pose2::new(1.5, 1.5, 0.0);
    let config = LocalizerConfig::new(Some(laser()), None, [0.01, 0.002, 0.01, 0.002]);
    let mut loc = Localizer::new(map(), config, Some((start, Matrix3::identity() * 1e-4)));
    let step = OdometryStep::from_wheels(0.02, 0.02, TRACK_M);
    let mut truth = start;
    for (k, t) in [3_000, 3_050, 3_100, 50, 100, 150].iter().enumerate() {
        truth = truth.compose(&step.as_delta());
        let t = t * 1_000_000;
        loc.predict_at(t, &step);
        let outcome = loc.update_ranges_at(t, &scan(&world, &truth, 0.005, k as u64), &[]);
        assert!(
            matches!(outcome, ScanOutcome::Fused { .. }),
            "{k}: {outcome:?}"
        );
    }
}
