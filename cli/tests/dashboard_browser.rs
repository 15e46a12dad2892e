//! The dashboard in a real browser: `intellwheels --serve` on an ephemeral loopback port, driven
//! by Debian's headless chromium through playwright-core (cli/tests/browser/*.mjs).
//! - dashboard.mjs: the page loads, chairs move between two frames, a click on the map sends the
//!   selected chair a goal and it turns.
//! - drive.mjs: a chair's on-board view, driven with the on-screen joystick: released while
//!   moving it stops; it goes through a doorway without contact and does not cross the wall it
//!   is driven at (contacts at that wall are printed, not failed on: a known gap, see the script).
//!
//! The screenshots' paths are printed. Prints SKIP when chromium, node or playwright-core is
//! missing (`.ci/run` installs them).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

fn chromium() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("CHROMIUM") {
        return Some(PathBuf::from(path));
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
        .into_iter()
        .map(PathBuf::from)
        .find(|p| p.exists())
}

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
    let browser_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    let Some(chromium) = chromium() else {
        iw_testdata::skip(
            test,
            "no chromium (apt-get install chromium; .ci/run does it)",
        );
        return None;
    };
    if !browser_dir.join("node_modules/playwright-core").exists() {
        iw_testdata::skip(
            test,
            "playwright-core not installed (npm ci in cli/tests/browser; .ci/run does it)",
        );
        return None;
    }
    if Command::new("node").arg("--version").output().is_err() {
        iw_testdata::skip(test, "no node");
        return None;
    }
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

    let screenshot = std::env::temp_dir().join(format!(
        "intellwheels-{}-{}.png",
        script.trim_end_matches(".mjs"),
        std::process::id()
    ));
    let out = Command::new("node")
        .current_dir(&browser_dir)
        .arg(script)
        .arg(&url)
        .arg(&chromium)
        .arg(&screenshot)
        .output()
        .expect("run node");
    println!("{}", String::from_utf8_lossy(&out.stdout));
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the browser check failed");
    let png = std::fs::read(&screenshot).expect("the screenshot");
    assert!(png.starts_with(b"\x89PNG"), "the screenshot is a PNG");
    println!("screenshot (CI artifact): {}", screenshot.display());

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
