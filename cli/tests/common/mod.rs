//! What the process tests of `intellwheels spawn` share: free loopback ports, a deployment that
//! launches its roles (services, world, chairs) with their flags, and a container process whose
//! JSON events are followed and which is taken down with an asserted clean exit.
#![allow(dead_code)] // each test binary uses part of it

use std::io::{BufRead, BufReader, Read};
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

/// A bus address on loopback with its control port free too.
pub fn loopback() -> String {
    format!("127.0.0.1:{}", free_port_pair())
}

/// One deployment under test: where its services listen (the others' `--peer`), how its
/// containers are secured, the transport, and a folder for its keys and config files. Each role
/// it launches gets those flags; a test adds the rest.
pub struct Deployment {
    pub dir: tempfile::TempDir,
    services_addr: String,
    /// The control group key file, or `None` for `--insecure-dev`.
    control: Option<String>,
    transport: Option<String>,
}

impl Deployment {
    /// Secured by a fresh control group key, services on a free loopback address, over UDP.
    pub fn new() -> Deployment {
        let dir = tempfile::tempdir().unwrap();
        let control = keygen_control(dir.path());
        Deployment {
            dir,
            services_addr: loopback(),
            control: Some(control),
            transport: None,
        }
    }

    /// `--insecure-dev` over `transport`, the services at `services_addr`.
    pub fn insecure(transport: &str, services_addr: &str) -> Deployment {
        Deployment {
            dir: tempfile::tempdir().unwrap(),
            services_addr: services_addr.to_string(),
            control: None,
            transport: Some(transport.to_string()),
        }
    }

    /// The services listen at `addr` instead.
    pub fn services_at(mut self, addr: &str) -> Deployment {
        self.services_addr = addr.to_string();
        self
    }

    pub fn services_addr(&self) -> &str {
        &self.services_addr
    }

    /// The control group key file (panics on an insecure deployment).
    pub fn control_key(&self) -> &str {
        self.control.as_deref().expect("a secured deployment")
    }

    /// A fresh identity key file named `name` in the deployment's folder.
    pub fn key(&self, name: &str) -> String {
        keygen(self.dir.path(), name)
    }

    /// Writes `text` to the file `name` in the deployment's folder; its path.
    pub fn file(&self, name: &str, text: &str) -> String {
        let path = self.dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path.display().to_string()
    }

    /// A services configuration for `chair` with the FIPA HTTP MTP listening on a free loopback
    /// port: the port and the file's path.
    pub fn http_mtp_config(&self, chair: &str) -> (u16, String) {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let config = self.file(
            "services.toml",
            &format!(
                "[services]\nchairs = [\"{chair}\"]\n\n[mtp.http]\nlisten = \"127.0.0.1:{port}\"\n"
            ),
        );
        (port, config)
    }

    /// The services container at the deployment's services address.
    pub fn services(&self) -> Launch {
        self.launch("services", &["--services"], &self.services_addr)
    }

    /// The world container on a free loopback address, peering the services.
    pub fn world(&self) -> Launch {
        self.launch("world", &["--world"], &loopback())
            .peer_services(self)
    }

    /// Chair `name` on a free loopback address, peering the services.
    pub fn chair(&self, name: &str) -> Launch {
        self.launch(name, &["--chair", name], &loopback())
            .peer_services(self)
    }

    fn launch(&self, label: &str, role: &[&str], listen: &str) -> Launch {
        let mut security: Vec<String> = match &self.control {
            Some(key) => vec!["--control-key".into(), key.clone()],
            None => vec!["--insecure-dev".into()],
        };
        if let Some(transport) = &self.transport {
            security.extend(["--transport".into(), transport.clone()]);
        }
        Launch {
            label: label.to_string(),
            role: role.iter().map(|a| a.to_string()).collect(),
            listen: listen.to_string(),
            common: security,
            extra: Vec::new(),
            prefix: Vec::new(),
        }
    }
}

/// One container to start: its role, address and flags. Cloned to start the same container
/// again (a restart keeps its address, key and flags).
#[derive(Clone)]
pub struct Launch {
    label: String,
    role: Vec<String>,
    listen: String,
    common: Vec<String>,
    extra: Vec<String>,
    prefix: Vec<String>,
}

impl Launch {
    /// Adds `FLAG VALUE`.
    pub fn arg(mut self, flag: &str, value: &str) -> Launch {
        self.extra.extend([flag.to_string(), value.to_string()]);
        self
    }

    pub fn listen(mut self, addr: &str) -> Launch {
        self.listen = addr.to_string();
        self
    }

    pub fn goal(self, goal: &str) -> Launch {
        self.arg("--goal", goal)
    }

    /// `--start X,Y,DEG`.
    pub fn start(self, pose: &str) -> Launch {
        self.arg("--start", pose)
    }

    pub fn key(self, path: &str) -> Launch {
        self.arg("--key", path)
    }

    pub fn config(self, path: &str) -> Launch {
        self.arg("--config", path)
    }

    pub fn body(self, body: &str) -> Launch {
        self.arg("--body", body)
    }

    /// `--lockstep`: a world that steps only when its bodies have spoken, or a chair in one.
    pub fn lockstep(mut self) -> Launch {
        self.extra.push("--lockstep".to_string());
        self
    }

    /// Run through a command prefix (`ip netns exec NS`), which must exec the container.
    pub fn via(mut self, prefix: &[String]) -> Launch {
        self.prefix = prefix.to_vec();
        self
    }

    fn peer_services(self, deployment: &Deployment) -> Launch {
        self.arg("--peer", &deployment.services_addr.clone())
    }

    pub fn addr(&self) -> &str {
        &self.listen
    }

    fn args(&self) -> Vec<String> {
        let mut args = self.role.clone();
        args.extend(["--listen".to_string(), self.listen.clone()]);
        args.extend(self.extra.iter().cloned());
        args.extend(self.common.iter().cloned());
        args
    }

    pub fn spawn(&self) -> Proc {
        let prefix: Vec<&str> = self.prefix.iter().map(String::as_str).collect();
        let args = self.args();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let mut proc = Proc::spawn_via(&prefix, &args);
        proc.label = self.label.clone();
        proc
    }

    /// Starts it and waits for its `ready` event.
    pub fn ready(&self) -> Proc {
        let mut proc = self.spawn();
        proc.wait_for(&format!("{} ready", self.label), |e| e["event"] == "ready");
        proc
    }

    /// Runs it to its exit (killed after LIMIT); its success and stderr.
    pub fn run_to_exit(&self) -> (bool, String) {
        let child = Command::new(env!("CARGO_BIN_EXE_intellwheels"))
            .arg("spawn")
            .args(self.args())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        match exit_within(child) {
            (Some(status), stderr) => (status.success(), stderr),
            (None, _) => panic!("{} still running after {LIMIT:?}", self.label),
        }
    }
}

/// Waits for `child` (spawned with its stderr piped) to exit, killing it with SIGKILL at
/// [`LIMIT`] (a process blocked in an open ignores SIGTERM): its exit status if it ended in
/// time, and its stderr.
pub fn exit_within(mut child: Child) -> (Option<std::process::ExitStatus>, String) {
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    (status, reader.join().unwrap())
}

/// A running container and its stdout events.
pub struct Proc {
    /// Its role or chair name, for messages.
    pub label: String,
    pub child: Child,
    pub events: Receiver<Value>,
    pub seen: Vec<Value>,
}

impl Proc {
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
            label: "container".to_string(),
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

    /// The clean take-down: SIGTERM, a successful exit and its `stopped` event, which it
    /// returns (with the count of messages sent).
    pub fn stop(&mut self) -> Value {
        let status = self.terminate();
        assert!(status.success(), "{} exit status {status}", self.label);
        let what = format!("{} stopped", self.label);
        self.wait_for(&what, |e| e["event"] == "stopped")
    }

    /// SIGKILL: no take-down at all.
    pub fn kill(&mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    /// Takes in the events printed so far without waiting.
    pub fn drain(&mut self) {
        self.seen.extend(self.events.try_iter());
    }
}

/// Stops each container in order (see [`Proc::stop`]).
pub fn stop_all<const N: usize>(procs: [&mut Proc; N]) {
    for proc in procs {
        proc.stop();
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
