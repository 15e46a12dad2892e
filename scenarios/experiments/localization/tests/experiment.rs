//! A short drive and two global runs in the sample building: the summary has the contract keys
//! and the map-based estimate beats dead reckoning.

use iw_localization_experiment::{Config, Summary, run, sample_building, write_outputs};

#[test]
fn a_short_drive_stays_localized_and_writes_the_summary() {
    let map = sample_building().unwrap();
    let config = Config {
        minutes: 0.75,
        seeds: 1,
        global_runs: 2,
        global_drive_m: 6.0,
        blind_runs: 1,
        vo_every: 0,
        ..Config::default()
    };
    let report = run(&map, &config, &|_| {}).unwrap();
    let out = tempfile::tempdir().unwrap();
    let summary = write_outputs(&report, &map, out.path()).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap())
            .unwrap();
    for key in [
        "wheel",
        "vo",
        "fused",
        "localized",
        "global",
        "nees_pass_rate",
        "blind",
    ] {
        assert!(json.get(key).is_some(), "summary.json lacks `{key}`");
    }
    for key in ["runs", "converged", "median_distance_m"] {
        assert!(json["global"].get(key).is_some(), "global lacks `{key}`");
    }
    assert!(out.path().join("paths.png").exists() && out.path().join("error.png").exists());
    eprintln!(
        "wheel {:.3} m, localized {:.3} m (max {:.3}), NEES pass {:.2}, global {}/{}",
        summary.wheel.rmse_m,
        summary.localized.rmse_m,
        summary.localized.max_m,
        summary.nees_pass_rate,
        summary.global.converged,
        summary.global.runs
    );
    assert!(
        summary.distance_m[0] > 10.0,
        "drove {:?} m",
        summary.distance_m
    );
    assert!(summary.localized.rmse_m < 0.05 && summary.localized.rmse_m < summary.wheel.rmse_m);
    assert_eq!(summary.global.falsely_confident, 0);
}

/// The localizer's covariance is honest over a long drive (issue 19's consistency test): on a
/// 30-minute drive round the sample building (about 600 m, the movers on; visual odometry off to
/// keep it short, which changes the figures by 0.001 on seed 1), the NEES of x, y and heading,
/// once a simulated second, lies inside its two-sided 95 % chi-square interval about 95 % of the
/// time, its mean is near 3, and no more seconds lie above the interval (overconfident) than a
/// consistent filter's 2.5 % and some slack.
/// Measured on seeds 1 and 2 (docs/results/localization.md, the `nees3` section): pass rate
/// 0.956 and 0.949, mean 2.43 and 2.48, above 1.7 % and 1.4 %. The filter before the derived
/// matcher fails the first two bounds: on seed 1 of this drive, pass rate 0.896, mean 1.61.
#[test]
fn the_covariance_is_consistent_over_a_long_drive() {
    let map = sample_building().unwrap();
    for seed in [1, 2] {
        let config = Config {
            minutes: 30.0,
            seeds: 1,
            global_runs: 0,
            blind_runs: 0,
            vo_every: 0,
            seed,
            ..Config::default()
        };
        let summary = Summary::of(&run(&map, &config, &|_| {}).unwrap());
        let (pass, mean, above) = (
            summary.nees_pass_rate,
            summary.nees_mean,
            summary.nees_above_rate,
        );
        eprintln!(
            "seed {seed}: {:.0} m, NEES pass rate {pass:.3}, mean {mean:.2}, above {above:.3}, components {:?}",
            summary.distance_m[0], summary.nees_components
        );
        assert!(summary.distance_m[0] > 500.0, "{:?}", summary.distance_m);
        assert!(pass >= 0.93, "seed {seed}: NEES pass rate {pass:.3}");
        assert!(
            (2.2..=3.8).contains(&mean),
            "seed {seed}: mean NEES {mean:.2}"
        );
        assert!(
            above <= 0.04,
            "seed {seed}: {above:.3} of the seconds overconfident"
        );
    }
}

#[test]
fn a_map_without_a_closed_route_is_refused() {
    let map = iw_sim::Map::parse("wall 0 0 5 0 5 5\nroute r 1 1 2 2\n", "m").unwrap();
    let err = run(&map, &Config::default(), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("closed route"), "{err}");
}

#[test]
fn a_kidnapped_chair_notices_and_finds_itself_again() {
    let map = sample_building().unwrap();
    let lmap = std::sync::Arc::new(iw_sim::localization::localization_map(&map).unwrap());
    let config = Config {
        vo_every: 0,
        ..Config::default()
    };
    let mut recovered = 0;
    for seed in 1..=4 {
        let run = iw_localization_experiment::kidnap_run(&map, &lmap, &config, seed).unwrap();
        eprintln!("{run:?}");
        assert!(run.carried_m > 3.0, "{run:?}");
        // it gives up the old pose instead of tracking on where it no longer is
        assert!(run.noticed_m.is_some(), "{run:?}");
        // once it has found itself again it is never confident while far off
        assert!(run.max_error_after_fix_m <= 0.30, "{run:?}");
        recovered += usize::from(run.recovered_m.is_some());
    }
    eprintln!(
        "recovered within {} m: {recovered}/4",
        config.global_drive_m
    );
}
