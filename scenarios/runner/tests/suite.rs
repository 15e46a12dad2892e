//! Runs every `scenarios/*.toml`; checks a deliberately false assertion fails and that the same
//! seed gives the same report and message trace.

use std::path::PathBuf;

fn scenarios_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn every_scenario_file_passes() {
    let mut files: Vec<PathBuf> = std::fs::read_dir(scenarios_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 5, "{files:?}");
    let mut failed = Vec::new();
    for file in files {
        let report = iw_scenario::run(&iw_scenario::Scenario::load(&file).unwrap()).unwrap();
        let collisions: u64 = report.chairs.iter().map(|c| c.collisions).sum();
        let goals = report
            .outcomes
            .iter()
            .filter(|o| o.assertion.contains("goal-reached") && o.passed)
            .count();
        println!(
            "{}: {} ({goals} goal-reached assertions held, {collisions} collisions)",
            report.name,
            if report.passed { "PASS" } else { "FAIL" }
        );
        if !report.passed {
            failed.push(format!("{}:\n{}", file.display(), report.render()));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

#[test]
fn a_false_assertion_fails_and_runs_are_deterministic() {
    let path = scenarios_dir().join("sensor-failure.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    // the chair cannot reach a point 10 m away in 15 s with its sensors failed at 5 s
    let false_text =
        format!("{text}\n[[assert]]\nkind = \"goal-reached\"\nchair = \"chair1\"\nby_s = 15\n");
    let scenario = iw_scenario::Scenario::parse(&false_text, &path).unwrap();
    let first = iw_scenario::run(&scenario).unwrap();
    assert!(!first.passed, "{}", first.render());
    assert_eq!(
        first.outcomes.iter().filter(|o| !o.passed).count(),
        1,
        "{}",
        first.render()
    );
    let second = iw_scenario::run(&scenario).unwrap();
    assert_eq!(first, second, "same seed, same report and trace");
}

#[test]
fn runs_with_real_bodies_on_a_pty_are_deterministic() {
    let scenario = iw_scenario::Scenario::load(scenarios_dir().join("mixed-reality.toml")).unwrap();
    let first = iw_scenario::run(&scenario).unwrap();
    let second = iw_scenario::run(&scenario).unwrap();
    assert_eq!(
        first, second,
        "same seed, same report and trace, whatever the board emulator's thread timing"
    );
}

#[test]
fn bad_files_are_errors_naming_the_entry() {
    let path = scenarios_dir().join("bad.toml");
    let text = "name = \"x\"\nmap = \"maps/sample-building.map\"\nduration_s = 5\n[[chair]]\nname = \"c\"\nstart = \"nowhere\"\n";
    let err = iw_scenario::run(&iw_scenario::Scenario::parse(text, &path).unwrap()).unwrap_err();
    assert!(
        err.to_string().contains("chair[0]") && err.to_string().contains("nowhere"),
        "{err}"
    );
    assert!(iw_scenario::Scenario::parse("name = 3", &path).is_err());
}

#[test]
fn what_a_mode_cannot_play_is_refused_naming_the_entry() {
    let path = scenarios_dir().join("killed.toml");
    let text = "name = \"x\"\nmap = \"maps/sample-building.map\"\nduration_s = 5\n[[chair]]\nname = \"c\"\nstart = \"entrance\"\n[[fault]]\nkind = \"kill-container\"\nat_s = 1.0\ncontainer = \"c\"\n";
    let scenario = iw_scenario::Scenario::parse(text, &path).unwrap();
    let err = iw_scenario::run(&scenario).unwrap_err().to_string();
    assert!(
        err.contains("fault[0]") && err.contains("--processes"),
        "{err}"
    );
    let map = scenario.load_map().unwrap();
    scenario
        .validate_for(&map, iw_scenario::Mode::Processes)
        .unwrap();
    // an unknown container is refused in either mode
    let unknown = text.replace("container = \"c\"", "container = \"nobody\"");
    let err = iw_scenario::Scenario::parse(&unknown, &path)
        .unwrap()
        .validate(&map)
        .unwrap_err()
        .to_string();
    assert!(err.contains("fault[0]") && err.contains("nobody"), "{err}");

    let sensors = iw_scenario::Scenario::load(scenarios_dir().join("sensor-failure.toml")).unwrap();
    let map = sensors.load_map().unwrap();
    let err = sensors
        .validate_for(&map, iw_scenario::Mode::Processes)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("fault[0]") && err.contains("without --processes") && err.contains("`all`"),
        "{err}"
    );
    // the laser's or the sonars' garbage is played by the world container, in either mode
    for sensor in ["laser", "sonars"] {
        let text = std::fs::read_to_string(scenarios_dir().join("sensor-failure.toml"))
            .unwrap()
            .replace(
                "kind = \"sensor-failure\"",
                &format!("kind = \"sensor-failure\"\nsensor = \"{sensor}\""),
            );
        let one = iw_scenario::Scenario::parse(&text, &path).unwrap();
        one.validate_for(&map, iw_scenario::Mode::Processes)
            .unwrap();
        one.validate_for(&map, iw_scenario::Mode::InProcess)
            .unwrap();
    }
    let camera = std::fs::read_to_string(scenarios_dir().join("sensor-failure.toml"))
        .unwrap()
        .replace(
            "kind = \"sensor-failure\"",
            "kind = \"sensor-failure\"\nsensor = \"camera\"",
        );
    let err = iw_scenario::Scenario::parse(&camera, &path)
        .unwrap_err()
        .to_string();
    assert!(err.contains("camera"), "{err}");
}

#[test]
fn a_blinded_laser_and_a_landmark_visit_are_checked_naming_the_entry() {
    let path = scenarios_dir().join("blind.toml");
    let text = "name = \"x\"\nmap = \"maps/sample-building.map\"\nduration_s = 20\n[[chair]]\nname = \"c\"\nstart = \"entrance\"\n[[goal]]\nat_s = 0.5\nchair = \"c\"\nplace = \"office\"\n[[fault]]\nkind = \"laser-blind\"\nat_s = 1.0\nchair = \"c\"\nfor_s = 5.0\n[[assert]]\nkind = \"landmark-visited\"\nchair = \"c\"\nby_s = 20\n";
    let scenario = iw_scenario::Scenario::parse(text, &path).unwrap();
    let map = scenario.load_map().unwrap();
    scenario.validate(&map).unwrap();
    let refused = |text: String, entry: &str, says: &str| {
        let err = iw_scenario::Scenario::parse(&text, &path)
            .unwrap()
            .validate(&map)
            .unwrap_err()
            .to_string();
        assert!(err.contains(entry) && err.contains(says), "{err}");
    };
    refused(
        text.replace("chair = \"c\"\nfor_s", "chair = \"nobody\"\nfor_s"),
        "fault[0]",
        "nobody",
    );
    refused(
        text.replace("for_s = 5.0", "for_s = -1.0"),
        "fault[0]",
        "-1",
    );
    refused(text.replace("at_s = 1.0", "at_s = 99.0"), "fault[0]", "99");
    refused(text.replace("by_s = 20", "by_s = 21"), "assert[0]", "21");
    refused(
        text.replace("by_s = 20", "from_s = 15.0\nby_s = 10"),
        "assert[0]",
        "after by_s",
    );
    refused(
        text.replace("by_s = 20", "by_s = 20\nwithin_m = 0.0"),
        "assert[0]",
        "within_m",
    );
    // a map without a landmark cannot be visited
    let bare = std::env::temp_dir().join(format!("iw-bare-{}.map", std::process::id()));
    let map_text: String =
        std::fs::read_to_string(scenarios_dir().join("maps/sample-building.map"))
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with("landmark"))
            .map(|l| format!("{l}\n"))
            .collect();
    std::fs::write(&bare, map_text).unwrap();
    let bare_scenario = iw_scenario::Scenario::parse(
        &text.replace("maps/sample-building.map", &bare.display().to_string()),
        &path,
    )
    .unwrap();
    let err = bare_scenario
        .validate(&bare_scenario.load_map().unwrap())
        .unwrap_err()
        .to_string();
    std::fs::remove_file(&bare).unwrap();
    assert!(
        err.contains("assert[0]") && err.contains("no landmark"),
        "{err}"
    );
    // across processes too: the world container blinds the laser (its admin path)
    scenario
        .validate_for(&map, iw_scenario::Mode::Processes)
        .unwrap();
}
