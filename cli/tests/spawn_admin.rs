//! `intellwheels spawn --admin-stdin`: the parent's admin path. Lines that are not commands, or
//! too long, are refused with an `admin` event and the container runs on, as is a command for
//! another role (a blinded laser or a failed sensor outside the world); a command is carried
//! out; closing stdin
//! (the parent gone) stops the container cleanly.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc::RecvTimeoutError;
use std::time::Instant;

use common::{LIMIT, free_port_pair};
use serde_json::Value;

#[test]
fn bad_admin_lines_are_refused_and_a_closed_stdin_stops_the_container() {
    let listen = format!("127.0.0.1:{}", free_port_pair());
    let mut child = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
        .args(["spawn", "--services", "--insecure-dev", "--admin-stdin"])
        .args(["--listen", &listen])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, events) = std::sync::mpsc::channel::<Value>();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(serde_json::from_str(&line).unwrap()).is_err() {
                return;
            }
        }
    });
    let deadline = Instant::now() + LIMIT;
    let next = |what: &str, want: &dyn Fn(&Value) -> bool| loop {
        match events.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            Ok(v) if want(&v) => return v,
            Ok(_) => {}
            Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => {
                panic!("no {what}")
            }
        }
    };
    next("ready", &|e| e["event"] == "ready");
    let mut stdin = child.stdin.take().unwrap();
    writeln!(stdin, "{{\"admin\": \"reboot\"}}").unwrap();
    writeln!(stdin, "{}", "x".repeat(10_000)).unwrap();
    writeln!(
        stdin,
        "{{\"admin\": \"laser-blind\", \"chair\": \"chair1\", \"blind\": true}}"
    )
    .unwrap();
    let failure = |sensor: &str| {
        format!(
            "{{\"admin\": \"sensor-failure\", \"chair\": \"chair1\", \"sensor\": \"{sensor}\", \"failed\": true}}"
        )
    };
    writeln!(stdin, "{}", failure("sonars")).unwrap();
    writeln!(stdin, "{}", failure("camera")).unwrap();
    writeln!(
        stdin,
        "{{\"admin\": \"kill-agent\", \"agent\": \"watcher\"}}"
    )
    .unwrap();
    writeln!(
        stdin,
        "{{\"admin\": \"kill-agent\", \"agent\": \"watcher\"}}"
    )
    .unwrap();
    stdin.flush().unwrap();
    let admin = |e: &Value| e["event"] == "admin";
    let unknown = next("refusal of an unknown command", &admin);
    assert!(
        unknown["error"]
            .as_str()
            .unwrap()
            .contains("not an admin command"),
        "{unknown}"
    );
    let long = next("refusal of a long line", &admin);
    assert!(
        long["error"].as_str().unwrap().contains("longer than"),
        "{long}"
    );
    let laser = next("a laser-blind refused outside the world", &admin);
    assert_eq!(laser["done"], "laser-blind chair1 true", "{laser}");
    assert!(
        laser["error"]
            .as_str()
            .unwrap()
            .contains("only the world container"),
        "{laser}"
    );
    let sonars = next("a sensor-failure refused outside the world", &admin);
    assert_eq!(
        sonars["done"], "sensor-failure chair1 sonars true",
        "{sonars}"
    );
    assert_eq!(
        sonars["error"], "only the world container fails a sensor",
        "{sonars}"
    );
    let camera = next("an unknown sensor refused", &admin);
    let why = camera["error"].as_str().unwrap();
    assert!(
        why.contains("not an admin command") && why.contains("camera"),
        "{camera}"
    );
    let killed = next("the watcher killed", &admin);
    assert_eq!(killed["done"], "kill-agent watcher@services", "{killed}");
    assert!(killed["error"].is_null(), "{killed}");
    let again = next("a second kill refused", &admin);
    assert!(
        again["error"].as_str().unwrap().contains("no agent"),
        "{again}"
    );
    drop(stdin);
    next("stopped after stdin closed", &|e| e["event"] == "stopped");
    assert!(child.wait().unwrap().success());
}
