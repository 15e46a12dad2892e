//! Every file flag of the binary given what a hostile tester gives it: a FIFO with no writer,
//! `/dev/zero`, a folder and a 2 GB file of holes. Each must be refused within the limit with a
//! clear error naming the file and why, never a hang, an abort or memory eaten without bound.
//! Before the fix these hung (FIFO), ran out of memory (`/dev/zero`), or aborted asking for 14 GB
//! (`scenario run` on the 2 GB file).

mod common;

use std::path::Path;
use std::process::{Command, Stdio};

/// Address space each run may take: a regression reading `/dev/zero` fails here instead of
/// taking the machine's memory.
const MAX_VIRTUAL_KIB: u64 = 4 << 20;

/// Runs the binary with `args` under [`MAX_VIRTUAL_KIB`], killed at [`common::LIMIT`]:
/// (finished in time, exit code, stderr).
fn run(args: &[&str]) -> (bool, Option<i32>, String) {
    run_under(MAX_VIRTUAL_KIB, args, Stdio::null())
}

/// [`run`] under `max_virtual_kib` of address space, its stdout to `stdout`.
fn run_under(max_virtual_kib: u64, args: &[&str], stdout: Stdio) -> (bool, Option<i32>, String) {
    let child = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {max_virtual_kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_intellwheels"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (status, stderr) = common::exit_within(child);
    (status.is_some(), status.and_then(|s| s.code()), stderr)
}

/// Address space `log query` runs in below: the log queried is larger. Before the log was
/// streamed, reading it whole failed here.
const LOG_QUERY_VIRTUAL_KIB: u64 = 192 << 10;

#[test]
fn a_log_larger_than_the_address_space_it_is_queried_in_is_queried_in_full() {
    use iw_logger::{LogStore, LoggedMessage, SyncPolicy};
    const RECORDS: u64 = 800;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.iwl");
    let mut log = LogStore::open(&path, SyncPolicy::EveryN(u32::MAX)).unwrap();
    let filler = "x".repeat(300 << 10);
    for i in 0..RECORDS {
        let m = LoggedMessage {
            time_ns: i,
            sender: "cognitive@chair-a".into(),
            receivers: vec!["control@chair-a".into()],
            performative: if i % 100 == 7 { "refuse" } else { "inform" }.into(),
            conversation_id: Some(format!("c{i}")),
            acl: format!("(inform :content \"{filler}\")"),
        };
        log.append(&m.to_payload(), i).unwrap();
    }
    log.sync().unwrap();
    drop(log);
    let len = std::fs::metadata(&path).unwrap().len();
    assert!(len > LOG_QUERY_VIRTUAL_KIB << 10, "a log of {len} bytes");
    let out = dir.path().join("found.jsonl");
    let log = path.to_str().unwrap();
    let args = [
        "log",
        "query",
        "--log",
        log,
        "--performative",
        "refuse",
        "--json",
    ];
    let stdout = Stdio::from(std::fs::File::create(&out).unwrap());
    let (finished, code, stderr) = run_under(LOG_QUERY_VIRTUAL_KIB, &args, stdout);
    assert!(finished, "still running: {stderr}");
    assert_eq!(code, Some(0), "{stderr}");
    let found: Vec<u64> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str::<LoggedMessage>(line).unwrap().time_ns)
        .collect();
    let want: Vec<u64> = (0..RECORDS).filter(|i| i % 100 == 7).collect();
    assert_eq!(found, want, "every matching message, in order");
    println!(
        "log query: {} MiB log under a {} MiB address space: {} messages found",
        len >> 20,
        LOG_QUERY_VIRTUAL_KIB >> 10,
        found.len()
    );
}

/// The hostile inputs that exist on this machine: (label, path).
fn hostile_files(dir: &Path) -> Vec<(&'static str, String)> {
    let mut files = vec![
        ("/dev/zero", "/dev/zero".to_string()),
        ("a folder", dir.display().to_string()),
    ];
    let fifo = dir.join("input.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        files.push(("a FIFO", fifo.display().to_string()));
    } else {
        println!("SKIP: mkfifo is not available; the FIFO case was not tried");
    }
    files
}

#[test]
fn every_file_flag_refuses_a_fifo_a_device_and_a_folder_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    for (label, file) in hostile_files(dir.path()) {
        let f = file.as_str();
        let cases: [(&[&str], i32); 7] = [
            (&["spawn", "--world", "--insecure-dev", "--config", f], 2),
            (&["spawn", "--world", "--insecure-dev", "--key", f], 2),
            (&["spawn", "--world", "--control-key", f], 2),
            (&["scenario", "run", f], 2),
            (&["log", "query", "--log", f], 1),
            (&["experiment", "localization", "--out", out, "--map", f], 2),
            (&["features", "--output", out, f], 2),
        ];
        for (args, want) in cases {
            let what = format!("{} ({label})", args.join(" "));
            let (finished, code, stderr) = run(args);
            assert!(
                finished,
                "{what}: still running after {:?}: {stderr}",
                common::LIMIT
            );
            assert!(!stderr.contains("panicked"), "{what}: {stderr}");
            assert_eq!(code, Some(want), "{what}: {stderr}");
            assert!(
                stderr.contains(f) && stderr.contains("not a regular file"),
                "{what}: the error should name the file and why: {stderr}"
            );
            println!("{what}: {}", stderr.lines().last().unwrap_or(""));
        }
    }
}

#[test]
fn a_two_gigabyte_file_of_holes_is_refused_without_reading_it() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.toml");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(2 << 30)
        .unwrap();
    let big = big.to_str().unwrap();
    let out = dir.path().join("out");
    let cases: [&[&str]; 3] = [
        &["scenario", "run", big],
        &["spawn", "--world", "--insecure-dev", "--config", big],
        &[
            "experiment",
            "localization",
            "--out",
            out.to_str().unwrap(),
            "--map",
            big,
        ],
    ];
    for args in cases {
        let what = args.join(" ");
        let (finished, code, stderr) = run(args);
        assert!(finished, "{what}: still running: {stderr}");
        assert!(!stderr.contains("memory allocation"), "{what}: {stderr}");
        assert_eq!(code, Some(2), "{what}: {stderr}");
        assert!(
            stderr.contains(big) && stderr.contains("bytes accepted"),
            "{what}: {stderr}"
        );
        println!("{what}: {}", stderr.lines().last().unwrap_or(""));
    }
}

#[test]
fn experiment_numbers_that_panicked_or_ran_as_nonsense_are_refused_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    let huge = u64::MAX.to_string();
    let localization = |flag: &'static str| {
        let args = vec![
            "experiment",
            "localization",
            "--out",
            out,
            flag,
            huge.as_str(),
        ];
        (args, flag)
    };
    let odometry = |flag: &'static str, value: &'static str| {
        (
            vec!["experiment", "odometry", "--frames", "2", flag, value],
            flag,
        )
    };
    let cases = [
        // An overflow panic summing the progress bar's total.
        localization("--seeds"),
        localization("--global-runs"),
        localization("--blind-runs"),
        // Run to exit 0 with a NaN or absurd setting.
        odometry("--speed", "1e300"),
        odometry("--speed", "NaN"),
        odometry("--threshold-scale", "NaN"),
        odometry("--threshold-scale", "0"),
        odometry("--light", "NaN"),
    ];
    for (args, flag) in cases {
        let what = args.join(" ");
        let (finished, code, stderr) = run(&args);
        assert!(finished, "{what}: still running: {stderr}");
        assert!(!stderr.contains("panicked"), "{what}: {stderr}");
        assert_eq!(code, Some(2), "{what}: {stderr}");
        assert!(
            stderr.contains(flag),
            "{what}: the error should name {flag}: {stderr}"
        );
        println!("{what}: {}", stderr.lines().next().unwrap_or(""));
    }
}
