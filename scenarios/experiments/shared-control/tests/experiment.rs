//! The experiment end to end on the embedded office circuit.

use iw_shared_control_experiment::{Config, Mode, office_circuit, run, run_trial, write_outputs};

#[test]
fn small_run_writes_the_contract_summary_and_plots() {
    let map = office_circuit().unwrap();
    let config = Config {
        drivers: 2,
        laps: 1,
        ..Config::default()
    };
    let done = std::sync::atomic::AtomicUsize::new(0);
    let report = run(&map, &config, |_| {
        done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    })
    .unwrap();
    assert_eq!(done.into_inner(), 2 * Mode::ALL.len());
    let dir = tempfile::tempdir().unwrap();
    write_outputs(&report, &map, dir.path()).unwrap();
    let text = std::fs::read_to_string(dir.path().join("summary.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    for mode in ["manual", "shared", "vfh", "guarded"] {
        assert!(json[mode]["collisions"].is_u64(), "{mode}: {text}");
        assert!(json[mode]["intervention_rate"].is_f64());
        assert!(json[mode]["collisions_per_lap"].is_f64());
        assert_eq!(json[mode]["laps_attempted"].as_u64(), Some(2));
        assert!(json[mode]["laps_completed"].as_u64().unwrap() <= 2);
        assert!(dir.path().join(format!("paths-{mode}.png")).exists());
    }
    assert!(json["wilcoxon_t"].is_f64() && json["wilcoxon_p_normal"].is_f64());
    let p = json["wilcoxon_p"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&p));
    // Manual driving never changes the user's command.
    assert_eq!(json["manual"]["intervention_rate"].as_f64(), Some(0.0));
    println!("{text}");
}

#[test]
fn a_trial_is_deterministic() {
    let map = office_circuit().unwrap();
    let config = Config {
        drivers: 1,
        laps: 1,
        lap_timeout_s: 30.0,
        ..Config::default()
    };
    let a = run_trial(&map, &config, 0, Mode::Shared).unwrap();
    let b = run_trial(&map, &config, 0, Mode::Shared).unwrap();
    assert_eq!(a, b);
}

#[test]
fn a_drivers_trial_depends_on_their_seed_not_on_the_set_they_are_in() {
    // `--drivers 16 --seed 101` runs seeds 101-116: driver 3 of that set is the same person, and
    // drives the same trial, as the only driver of `--drivers 1 --seed 104`. So a larger set's
    // figures extend a smaller one's, driver by driver.
    let map = office_circuit().unwrap();
    let config = |drivers, seed| Config {
        drivers,
        seed,
        lap_timeout_s: 20.0,
        ..Config::default()
    };
    let in_set = run_trial(&map, &config(16, 101), 3, Mode::Guarded).unwrap();
    let alone = run_trial(&map, &config(1, 104), 0, Mode::Guarded).unwrap();
    assert_eq!(in_set.driver, 3);
    assert_eq!(without_index(in_set), without_index(alone));
    let other = run_trial(&map, &config(1, 105), 0, Mode::Guarded).unwrap();
    assert_ne!(
        without_index(other),
        without_index(run_trial(&map, &config(1, 104), 0, Mode::Guarded).unwrap()),
        "another seed is another person"
    );
}

/// A trial with its index in the set cleared.
fn without_index(
    trial: iw_shared_control_experiment::Trial,
) -> iw_shared_control_experiment::Trial {
    iw_shared_control_experiment::Trial { driver: 0, ..trial }
}

#[test]
fn unknown_route_is_a_clear_error() {
    let map = office_circuit().unwrap();
    let config = Config {
        route: "nope".into(),
        ..Config::default()
    };
    let err = run_trial(&map, &config, 0, Mode::Manual)
        .unwrap_err()
        .to_string();
    assert!(err.contains("nope") && err.contains("lap"), "{err}");
}

#[test]
fn an_open_route_is_a_clear_error() {
    let map = iw_sim::Map::parse(
        "wall closed 0 0 10 0 10 10 0 10\nroute lap 1 1 5 1 5 5\n",
        "open.map",
    )
    .unwrap();
    let err = run_trial(&map, &Config::default(), 0, Mode::Manual)
        .unwrap_err()
        .to_string();
    assert!(err.contains("not closed"), "{err}");
}

#[test]
fn every_map_in_scenarios_maps_with_a_lap_loads_as_a_circuit() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../maps");
    for name in ["office-circuit.map", "two-rooms.map", "ward-corridor.map"] {
        let map = iw_sim::Map::load(dir.join(name)).unwrap();
        let route = map.route("lap").unwrap();
        assert!(route.closed, "{name}");
        assert!(map.start("lap").is_some(), "{name}");
    }
}
