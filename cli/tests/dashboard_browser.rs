//! The dashboard in a real browser: `intellwheels --serve` on an ephemeral loopback port, driven
//! by Debian's headless chromium through playwright-core (cli/tests/browser/*.mjs).
//! - dashboard.mjs: the page loads, chairs move between two frames, a click on the map sends the
//!   selected chair a goal and it turns.
//! - drive.mjs: a chair's on-board view, driven with the on-screen joystick: released while
//!   moving it stops; it goes through a doorway and, driven straight at a wall, stops short of
//!   it, with no contact anywhere.
//!
//! The screenshots' paths are printed. Prints SKIP when chromium, node or playwright-core is
//! missing (`.ci/run` installs them).

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Kills the demo if the test fails half way.
struct Demo(Child);

impl Drop for Demo {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Runs `script` (in cli/tests/browser) against a fresh `intellwheels demo --serve`; `None`
/// (after printing SKIP for `test`) when the browser tools are missing.
fn in_browser(test: &str, script: &str) -> Option<()> {
    // One demo and one chromium at a time: two of each would starve a 2-core runner.
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let (chromium, browser_dir) = match common::browser_tools() {
        Ok(tools) => tools,
        Err(why) => {
            iw_testdata::skip(test, why);
            return None;
        }
    };
    let log_dir = tempfile::tempdir().unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
        .args(["demo", "--serve", "--bind", "127.0.0.1:0", "--log-dir"])
        .arg(log_dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start the demo");
    let mut demo = Demo(child);
    let stdout = demo.0.stdout.take().expect("stdout");
    let mut lines = BufReader::new(stdout).lines();
    let url = lines
        .by_ref()
        .map_while(Result::ok)
        .find_map(|l| l.strip_prefix("dashboard: ").map(str::to_string))
        .expect("the demo prints the dashboard URL");
    std::thread::spawn(move || lines.for_each(drop));
    println!("dashboard at {url}");

    common::run_browser_script(&browser_dir, &chromium, script, &url);

    // SIGTERM ends a serving demo cleanly, with its summary
    let pid = demo.0.id().to_string();
    assert!(
        Command::new("kill")
            .args(["-TERM", &pid])
            .status()
            .expect("kill")
            .success()
    );
    let mut waited = Duration::ZERO;
    let status = loop {
        if let Some(status) = demo.0.try_wait().expect("wait") {
            break status;
        }
        assert!(
            waited < Duration::from_secs(20),
            "the demo did not stop on SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(100));
        waited += Duration::from_millis(100);
    };
    assert!(status.success(), "demo exit status {status}");
    assert!(log_dir.path().join("summary.json").exists());
    Some(())
}

#[test]
fn the_dashboard_shows_moving_chairs_and_sends_a_goal_from_a_click() {
    in_browser(
        "the_dashboard_shows_moving_chairs_and_sends_a_goal_from_a_click",
        "dashboard.mjs",
    );
}

#[test]
fn a_person_drives_a_chair_with_the_on_screen_joystick() {
    in_browser(
        "a_person_drives_a_chair_with_the_on_screen_joystick",
        "drive.mjs",
    );
}
