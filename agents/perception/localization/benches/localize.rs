//! Cost of the localizer per 50 ms control period in a synthetic 10 x 8 m L-shaped room:
//! tracking (wheel step, 271 laser beams and 16 sonars matched to the map, EKF update) beside
//! its peer, the odometry EKF's wheel step alone; and a period of a chair that searches for
//! its pose (the search's bounded share of the period). `cargo bench -p iw-localization
//! --bench localize`.

use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use iw_body::TRACK_M;
use iw_localization::{LocalizationMap, Localizer, LocalizerConfig, SonarGeometry, Status};
use iw_vo::{OdometryFusion, OdometryStep, Pose2};
use nalgebra::Matrix3;

#[path = "../tests/common/mod.rs"]
mod common;

fn bench(c: &mut Criterion) {
    let map = Arc::new(LocalizationMap::new(common::room(), vec![], 1.0).expect("room"));
    let truth = Pose2::new(2.0, 2.0, 0.3);
    let ranges = common::scan(&common::room(), &truth, 0.01, 1);
    let sonar = SonarGeometry {
        t_base_sonar: (0..16)
            .map(|k| Pose2::new(0.3, 0.0, std::f64::consts::TAU * k as f64 / 16.0))
            .collect(),
        max_range_m: 3.0,
        sigma_m: 0.15,
    };
    let sonar_m: Vec<Option<f64>> = (0..16).map(|k| Some(1.0 + 0.1 * k as f64)).collect();
    let config = LocalizerConfig::new(
        Some(common::laser()),
        Some(sonar),
        [0.01, 0.002, 0.01, 0.002],
    );
    let step = OdometryStep::from_wheels(0.0, 0.0, TRACK_M);
    let mut group = c.benchmark_group("localize");
    group
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(3));
    group.bench_function("odometry EKF wheel step (peer)", |b| {
        let mut f = OdometryFusion::new(truth, Matrix3::identity() * 1e-4, config.alpha);
        b.iter(|| f.predict(&step))
    });
    group.bench_function("tracking period (wheel step + laser + sonar)", |b| {
        let mut l = Localizer::new(
            map.clone(),
            config.clone(),
            Some((truth, Matrix3::identity() * 1e-4)),
        );
        b.iter(|| {
            l.predict(&step);
            l.update_ranges(&ranges, &sonar_m)
        })
    });
    // A chair with no pose: every period is a wheel step and a range update, and the search
    // does at most its work budget in it. One iteration is one control period; the search is
    // restarted whenever it finds the pose, so every sample is a searching period (the grid
    // search, choosing hypotheses, updating them).
    // The same room driven in a loop; the scans are cast before timing.
    let moving = OdometryStep::from_wheels(0.025, 0.026, TRACK_M);
    let mut truth = Pose2::new(1.5, 1.5, 0.3);
    let drive: Vec<Vec<f64>> = (0..400u64)
        .map(|k| {
            truth = truth.compose(&moving.as_delta());
            if truth.x > 8.5 || truth.y > 3.5 {
                truth = Pose2::new(1.5, 1.5, 0.3);
            }
            common::scan(&common::room(), &truth, 0.01, k)
        })
        .collect();
    // A chair with no pose: a wheel step and a range update per period, the search doing at
    // most its work budget in it. The localizer starts a new search whenever it has found the
    // pose, so every sample is a searching period (grid search, choosing the hypotheses,
    // updating them).
    group.bench_function("searching period (wheel step + bounded search step)", |b| {
        let mut l = Localizer::new(map.clone(), config.clone(), None);
        let mut k = 0;
        b.iter(|| {
            if l.status() == Status::Tracking {
                l = Localizer::new(map.clone(), config.clone(), None);
            }
            k = (k + 1) % drive.len();
            l.predict(&moving);
            l.update_ranges(&drive[k], &sonar_m)
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
