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
        assert!(dir.path().join(format!("paths-{mode}.png")).exists());
    }
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
