//! What the process tests of `intellwheels spawn` share: free loopback ports and a container
//! process whose JSON events are followed.
#![allow(dead_code)] // each test binary uses part of it

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use serde_json::Value;

/// Upper bound of every wait: generous for a loaded 2-core machine, never the expected time.
pub const LIMIT: Duration = Duration::from_secs(120);

/// Two consecutive free UDP ports on loopback (bus and control channel).
pub fn free_port_pair() -> u16 {
    loop {
        let a = UdpSocket::bind("127.0.0.1:0").unwrap();
        let port = a.local_addr().unwrap().port();
        if port < u16::MAX && UdpSocket::bind(("127.0.0.1", port + 1)).is_ok() {
            return port;
        }
    }
}

/// A running container and its stdout events.
pub struct Proc {
    pub child: Child,
    pub events: Receiver<Value>,
    pub seen: Vec<Value>,
}

impl Proc {
    pub fn spawn(args: &[&str]) -> Proc {
        Proc::spawn_via(&[], args)
    }

    /// The services container with `config`, on a free loopback port pair, under the group
    /// key `control`; returns it and its bus address for the other containers' `--peer`.
    pub fn services(config: &Path, control: &str) -> (Proc, String) {
        let addr = format!("127.0.0.1:{}", free_port_pair());
        let services = Proc::spawn(&[
            "--services",
            "--config",
            config.to_str().unwrap(),
            "--listen",
            &addr,
            "--control-key",
            control,
        ]);
        (services, addr)
    }

    /// `intellwheels spawn ARGS` run through a command prefix (`ip netns exec NS`), which must
    /// exec it so that the child is the container.
    pub fn spawn_via(prefix: &[&str], args: &[&str]) -> Proc {
        let exe = env!("CARGO_BIN_EXE_intellwheels");
        let mut command = match prefix.split_first() {
            Some((program, rest)) => {
                let mut c = Command::new(program);
                c.args(rest).arg(exe);
                c
            }
            None => Command::new(exe),
        };
        let mut child = command
            .arg("spawn")
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start intellwheels spawn");
        let stdout = child.stdout.take().unwrap();
        let (tx, events) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let value: Value = serde_json::from_str(&line)
                    .unwrap_or_else(|e| panic!("not a JSON event: {line}: {e}"));
                if tx.send(value).is_err() {
                    return;
                }
            }
        });
        Proc {
            child,
            events,
            seen: Vec::new(),
        }
    }

    /// Waits for an event matching `want` (also among those already seen); panics after LIMIT.
    pub fn wait_for(&mut self, what: &str, want: impl Fn(&Value) -> bool) -> Value {
        if let Some(v) = self.seen.iter().find(|v| want(v)) {
            return v.clone();
        }
        self.wait_new(what, want)
    }

    /// Waits for a new event matching `want`; panics after LIMIT.
    pub fn wait_new(&mut self, what: &str, want: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + LIMIT;
        loop {
            match self
                .events
                .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            {
                Ok(v) => {
                    self.seen.push(v.clone());
                    if want(&v) {
                        return v;
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    panic!("no {what} within {LIMIT:?}; saw {:#?}", self.seen)
                }
                Err(RecvTimeoutError::Disconnected) => {
                    panic!("stdout closed before {what}; saw {:#?}", self.seen)
                }
            }
        }
    }

    /// Sends SIGTERM and waits for the exit status.
    pub fn terminate(&mut self) -> std::process::ExitStatus {
        let status = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success(), "kill -TERM");
        self.child.wait().unwrap()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn is(event: &Value, kind: &str, field: &str, value: &str) -> bool {
    event["event"] == kind && event[field] == value
}

/// Writes a key file with `spawn FLAG PATH`, which must succeed once and then refuse to
/// overwrite it.
pub fn write_key_with(flag: &str, path: &Path) -> String {
    for (attempt, ok) in [(1, true), (2, false)] {
        let out = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
            .args(["spawn", flag])
            .arg(path)
            .output()
            .unwrap();
        assert_eq!(
            out.status.success(),
            ok,
            "{flag} attempt {attempt} (the second must refuse to overwrite): {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    path.display().to_string()
}

pub fn keygen(dir: &Path, name: &str) -> String {
    write_key_with("--keygen", &dir.join(format!("{name}.pk8")))
}

/// The deployment's control group key.
pub fn keygen_control(dir: &Path) -> String {
    write_key_with("--keygen-control", &dir.join("control.key"))
}

/// Debian's headless chromium (or `$CHROMIUM`).
pub fn chromium() -> Option<std::path::PathBuf> {
    if let Some(path) = std::env::var_os("CHROMIUM") {
        return Some(std::path::PathBuf::from(path));
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
        .into_iter()
        .map(std::path::PathBuf::from)
        .find(|p| p.exists())
}

/// The browser tools: chromium and the script folder (cli/tests/browser) with playwright-core
/// installed and node; `Err` says which is missing.
pub fn browser_tools() -> Result<(std::path::PathBuf, std::path::PathBuf), &'static str> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    let chromium = chromium().ok_or("no chromium (apt-get install chromium; .ci/run does it)")?;
    if !dir.join("node_modules/playwright-core").exists() {
        return Err("playwright-core not installed (npm ci in cli/tests/browser; .ci/run does it)");
    }
    if Command::new("node").arg("--version").output().is_err() {
        return Err("no node");
    }
    Ok((chromium, dir))
}

/// Runs `script` of `dir` with node against `url` in `chromium`; asserts it passed and saved
/// its screenshot, whose path it returns.
pub fn run_browser_script(
    dir: &Path,
    chromium: &Path,
    script: &str,
    url: &str,
) -> std::path::PathBuf {
    let screenshot = std::env::temp_dir().join(format!(
        "intellwheels-{}-{}.png",
        script.trim_end_matches(".mjs"),
        std::process::id()
    ));
    let out = Command::new("node")
        .current_dir(dir)
        .arg(script)
        .arg(url)
        .arg(chromium)
        .arg(&screenshot)
        .output()
        .expect("run node");
    println!("{}", String::from_utf8_lossy(&out.stdout));
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the browser check {script} failed");
    let png = std::fs::read(&screenshot).expect("the screenshot");
    assert!(png.starts_with(b"\x89PNG"), "the screenshot is a PNG");
    println!("screenshot (CI artifact): {}", screenshot.display());
    screenshot
}
