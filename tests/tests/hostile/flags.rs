//! Extreme flags and hostile inputs on the real binary: each is refused by the argument parser
//! or with a clear error, never a panic, an abort or a hang.

use std::time::Duration;

const LIMIT: Duration = Duration::from_secs(20);

#[test]
fn numbers_too_big_for_their_use_are_refused_by_the_argument_parser() {
    let Some(bin) = crate::intellwheels() else {
        return;
    };
    let huge = u64::MAX.to_string();
    let cases: [(&[&str], &str); 6] = [
        (
            &["log", "replay", "--log", "x.iwl", "--speed", "1e-300"],
            "--speed",
        ),
        (&["bench", "bus", "--seconds", "1e300"], "--seconds"),
        (
            &[
                "acl",
                "send",
                "--to",
                "a@b",
                "--address",
                "http://127.0.0.1:9/acc",
                "--performative",
                "inform",
                "--timeout",
                "1e300",
            ],
            "--timeout",
        ),
        (
            &["vo", "--loader-threads", "100000", "-o", "t.txt", "seq"],
            "--loader-threads",
        ),
        // Counts that overflowed arithmetic or never ended.
        (
            &["experiment", "shared-control", "--drivers", huge.as_str()],
            "--drivers",
        ),
        (&["bench", "bus", "--window", huge.as_str()], "--window"),
    ];
    for (args, flag) in cases {
        let result = crate::run(&bin, args, b"", LIMIT);
        crate::assert_refused(&args.join(" "), &result, 2, flag);
    }
}

/// Makes a FIFO at `path`; false (SKIP printed) when `mkfifo` is missing.
fn mkfifo(path: &std::path::Path) -> bool {
    let made = std::process::Command::new("mkfifo").arg(path).status();
    let ok = made.is_ok_and(|s| s.success());
    if !ok {
        println!("SKIP: mkfifo is not available");
    }
    ok
}

#[test]
fn a_fifo_in_a_sequence_is_refused_not_waited_on() {
    let Some(bin) = crate::intellwheels() else {
        return;
    };
    // As a list file, then as an image a list names.
    for fifo in ["rgb.txt", "rgb/1.png"] {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("rgb")).unwrap();
        std::fs::create_dir(dir.path().join("depth")).unwrap();
        if fifo != "rgb.txt" {
            std::fs::write(dir.path().join("rgb.txt"), "1.0 rgb/1.png\n").unwrap();
        }
        std::fs::write(dir.path().join("depth.txt"), "1.0 depth/1.png\n").unwrap();
        std::fs::write(dir.path().join("depth/1.png"), b"").unwrap();
        if !mkfifo(&dir.path().join(fifo)) {
            return;
        }
        let out = dir.path().join("trajectory.txt");
        let args = [
            "vo",
            dir.path().to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        let result = crate::run(&bin, &args, b"", LIMIT);
        crate::assert_refused(
            &format!("vo ({fifo} is a FIFO)"),
            &result,
            2,
            "not a regular file",
        );
    }
}

#[test]
fn a_report_period_that_floods_and_a_start_pose_that_is_no_pose_are_refused_naming_the_flag() {
    let Some(bin) = crate::intellwheels() else {
        return;
    };
    let huge = u64::MAX.to_string();
    let impair = |period| {
        vec![
            "impair",
            "--a",
            "127.0.0.1:9",
            "--b",
            "127.0.0.1:10",
            "--duration-ms",
            "1",
            "--report-ms",
            period,
        ]
    };
    let spawn = |role: &'static [&'static str], start: &'static str| {
        let mut args = role.to_vec();
        args.extend(["--insecure-dev", "--start", start]);
        args
    };
    let cases = [
        // Printed its counters in a tight loop, or never.
        (impair("0"), "--report-ms"),
        (impair("99"), "--report-ms"),
        (impair(huge.as_str()), "--report-ms"),
        // Accepted, then ignored (the world has no body) or driven as NaN.
        (spawn(&["spawn", "--world"], "NaN,NaN,NaN"), "--start"),
        (spawn(&["spawn", "--world"], "1,6,0"), "--start"),
        (spawn(&["spawn", "--chair", "c1"], "NaN,6,0"), "--start"),
        (spawn(&["spawn", "--chair", "c1"], "1,inf,0"), "--start"),
        (spawn(&["spawn", "--chair", "c1"], "1,6,-inf"), "--start"),
    ];
    for (args, flag) in cases {
        let result = crate::run(&bin, &args, b"", LIMIT);
        crate::assert_refused(&args.join(" "), &result, 2, flag);
    }
}

#[test]
fn a_start_inside_the_maps_box_but_not_in_its_free_space_is_refused_before_anything_binds() {
    let Some(bin) = crate::intellwheels() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // An L-shaped building: (8, 8) is inside its outer box but outside its walls.
    let map = dir.path().join("l.map");
    std::fs::write(
        &map,
        "wall closed 0 0 10 0 10 4 4 4 4 10 0 10\nplace inside 1 1\n",
    )
    .unwrap();
    let config = dir.path().join("chair.toml");
    std::fs::write(
        &config,
        format!("[world]\nmap = {:?}\n", map.display().to_string()),
    )
    .unwrap();
    let config = config.display().to_string();
    let chair = |extra: &[&str], start: &str| {
        let mut args = vec!["spawn", "--chair", "c1", "--insecure-dev"];
        args.extend_from_slice(extra);
        args.extend(["--start", start]);
        args.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let cases = [
        // wholly inside the sample building's therapy bed: the footprint crosses no outline
        (chair(&[], "14,2.5,0"), "furniture"),
        (
            chair(&["--config", &config], "8,8,0"),
            "outside the building",
        ),
    ];
    for (args, why) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let result = crate::run(&bin, &args, b"", LIMIT);
        crate::assert_refused(&args.join(" "), &result, 2, "--start");
        let stderr = String::from_utf8_lossy(&result.0.stderr);
        assert!(
            stderr.contains("body.start") && stderr.contains(why),
            "{}: {stderr}",
            args.join(" ")
        );
    }
}
