//! The matcher's covariance comes from the match (issue 19, "the covariance must be honest"),
//! and a scan taken off its wheel step is covered by the localizer's scan-time term.

use std::sync::Arc;

use iw_body::TRACK_M;
use iw_localization::{LocalizationMap, Localizer, LocalizerConfig, Status, match_scan};
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

/// Drives the room's loop with scans cast where the chair was `lag(k)` periods before; returns
/// the localizer and the largest position error.
fn drive_with_late_scans(
    config: LocalizerConfig,
    lag: impl Fn(usize) -> usize,
) -> (Localizer, f64) {
    let world = room();
    let mut truth = Pose2::new(1.5, 1.5, 0.0);
    let mut past = vec![truth];
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
        loc.predict(&step);
        let at = past[past.len() - 1 - lag(k).min(past.len() - 1)];
        loc.update_ranges(&scan(&world, &at, 0.005, k as u64), &[]);
        let e = loc.pose();
        worst = worst.max((e.x - truth.x).hypot(e.y - truth.y));
    }
    (loc, worst)
}

/// A scan 0 to 3 periods late (a world process that answers late, by a different amount each
/// time): the localizer learns the scan-time spread from the innovations along the motion and
/// keeps tracking; without the term the same drive rejects its scans and loses the pose.
#[test]
fn scans_that_trail_the_wheels_by_a_jittering_lag_keep_the_chair_tracked() {
    let lag = |k: usize| (k.wrapping_mul(0x9E37_79B9) >> 7) % 4;
    let config = || LocalizerConfig::new(Some(laser()), None, [0.01, 0.002, 0.01, 0.002]);
    let (loc, worst) = drive_with_late_scans(config(), lag);
    assert_eq!(loc.status(), Status::Tracking);
    assert_eq!(loc.searches(), 0, "the chair lost its pose");
    assert!(worst < 0.1, "worst error {worst} m");
    let sigma = loc.scan_time_sigma();
    assert!(
        (0.5..=3.0).contains(&sigma),
        "scan-time sigma {sigma} periods"
    );

    let mut without = config();
    without.scan_time.max = 0.0;
    let (loc, _) = drive_with_late_scans(without, lag);
    assert!(
        loc.searches() > 0,
        "without the scan-time term the pose was kept"
    );
}

/// Scans taken with their wheel step teach the scan-time term nothing.
#[test]
fn scans_on_time_leave_the_scan_time_term_near_zero() {
    let config = LocalizerConfig::new(Some(laser()), None, [0.01, 0.002, 0.01, 0.002]);
    let (loc, worst) = drive_with_late_scans(config, |_| 0);
    assert!(worst < 0.01, "worst error {worst} m");
    let sigma = loc.scan_time_sigma();
    assert!(sigma < 0.2, "scan-time sigma {sigma} periods");
}
