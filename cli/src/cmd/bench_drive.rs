//! `intellwheels bench drive`: the time from a drive panel input to the wheel command.
//!
//! In one process, as the demo runs it: the sample building with one chair (fleet stepped every
//! 50 ms of wall time, as `--serve` does) and the dashboard's websocket server. The time is read
//! again right after the fleet step in which the control agent handed the wheels the first
//! non-zero command (its `DriveStatus` is set as the body is commanded). Paths:
//! - `browser` (with `--browser-dir`): Chromium on the chair's view, driven by
//!   cli/tests/browser/latency.mjs, presses the on-screen joystick with real pointer events; the
//!   start is the time the browser stamped on the pointerdown event (`performance.timeOrigin +
//!   event.timeStamp`, wall clock, ms). In between: the page's handler, the websocket, the demo
//!   loop's action queue, the interface agent's tick, the bus, the control agent's tick with
//!   shared control.
//! - `websocket`: a websocket client sends the frame the page sends on a pointer event and notes
//!   the instant (the browser's own part left out).
//! - `device queue` (the peer): the input pushed straight into the interface agent's queue, as a
//!   device driver on the chair would.
//!
//! Across processes (with `--browser-dir`): the services (serving the dashboard), the world and
//! one chair as `intellwheels spawn` processes on loopback UDP; the same browser script on the
//! services' dashboard; the end is the chair container's `drive-applied` event (its wall-clock
//! time, read right after the agent step that commanded the wheels). In between, in addition:
//! the services' loop, the staff console's tick, the bus between containers, the chair's
//! interface agent.
//!
//! Presses alternate forward and back (the chair stays in the corridor), each held about 0.6 s at
//! a different phase of the step, then released and let stop.

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context as _, bail};
use iw_dashboard::{Dashboard, DashboardConfig, DriveInput, PageAction};
use iw_fleet::{ChairConfig, Fleet};
use iw_sim::Map;
use nalgebra::{Isometry2, Vector2};
use serde_json::Value;

use super::bench_fleet::{EVENT_QUEUE, Procs, free_port_pair, percentile};
use super::demo;

const CHAIR: &str = "chair-0";
/// The chair's launch index across processes (after the services and the world).
const CHAIR_INDEX: usize = 2;
const STEP: Duration = Duration::from_millis(50);
/// In the corridor, facing along it: room ahead and behind. x, y (m), heading (deg).
const START: [f64; 3] = [7.0, 6.0, 0.0];
/// Longest a browser run may take per press (0.6 s held, the stop, the checks).
const PER_PRESS: Duration = Duration::from_secs(20);

/// One measured path.
#[derive(Debug, serde::Serialize)]
struct Row {
    path: &'static str,
    trials: usize,
    p50_ms: f64,
    p99_ms: f64,
    max_ms: f64,
}

impl Row {
    fn new(path: &'static str, mut latencies_ms: Vec<f64>) -> Row {
        latencies_ms.sort_by(f64::total_cmp);
        Row {
            path,
            trials: latencies_ms.len(),
            p50_ms: round1(percentile(&latencies_ms, 0.5)),
            p99_ms: round1(percentile(&latencies_ms, 0.99)),
            max_ms: round1(percentile(&latencies_ms, 1.0)),
        }
    }
}

/// `bench drive`: `trials` presses per path; the browser paths only with `browser_dir` (the
/// folder holding latency.mjs and playwright-core).
pub fn run(trials: usize, json: bool, browser_dir: Option<&Path>) -> anyhow::Result<()> {
    anyhow::ensure!(trials >= 2, "--trials must be at least 2, got {trials}");
    let browser = browser_dir.map(Browser::find).transpose()?;
    let map = Map::parse(demo::SAMPLE_BUILDING, "sample-building.map")
        .context("embedded sample building")?;
    let view = iw_wiring::view::map_view(&map);
    let chair = ChairConfig {
        name: CHAIR.into(),
        t_world_body: Isometry2::new(Vector2::new(START[0], START[1]), START[2].to_radians()),
    };
    let mut fleet = Fleet::new(map, 7, &[chair]).context("composing the fleet")?;
    let dashboard =
        Dashboard::start(DashboardConfig::default(), &view).context("starting the dashboard")?;
    let mut loop_ = Loop {
        fleet: &mut fleet,
        dashboard: &dashboard,
        next: Instant::now(),
        published: None,
        driving: false,
    };
    let mut rows = Vec::new();
    if let Some(browser) = &browser {
        eprintln!("in process, browser: {trials} presses");
        rows.push(Row::new(
            "browser",
            browser_in_process(&mut loop_, browser, trials)?,
        ));
    }
    let ws_url = format!("ws://{}/ws", dashboard.addr());
    let (mut socket, _) = tungstenite::connect(ws_url.as_str()).context("connecting")?;
    let bar = indicatif::ProgressBar::new(2 * trials as u64);
    for path in ["websocket", "device queue"] {
        let mut latencies_ms = Vec::with_capacity(trials);
        for k in 0..trials {
            let y = if k % 2 == 0 { 1.0 } else { -1.0 };
            // spread the send over the step: k * 7 ms into it, modulo 50
            loop_.step()?;
            std::thread::sleep(Duration::from_millis((k as u64 * 7) % 50));
            let input = DriveInput::Stick { x: 0.0, y };
            let sent = unix_ms();
            if path == "websocket" {
                let frame = serde_json::to_string(&PageAction::Drive {
                    chair: CHAIR.into(),
                    input,
                })?;
                socket.send(tungstenite::Message::text(frame))?;
            } else {
                demo::push_drive(loop_.fleet, CHAIR, input)?;
            }
            let commanded = loop {
                if let Some((at, linear)) = loop_.step()?
                    && linear * y > 0.0
                {
                    break at;
                }
                anyhow::ensure!(
                    unix_ms() - sent < 5000.0,
                    "no wheel command 5 s after the input"
                );
            };
            latencies_ms.push(commanded - sent);
            demo::push_drive(loop_.fleet, CHAIR, DriveInput::Stick { x: 0.0, y: 0.0 })?;
            // let it stop (watchdog 0.5 s, ramp): 1 s
            for _ in 0..20 {
                loop_.step()?;
            }
            bar.inc(1);
        }
        rows.push(Row::new(path, latencies_ms));
    }
    bar.finish_and_clear();
    if let Some(browser) = &browser {
        eprintln!("across processes, browser: {trials} presses");
        rows.push(Row::new(
            "browser, processes",
            across_processes(browser, trials)?,
        ));
    }
    if json {
        for row in &rows {
            println!("{}", serde_json::to_string(row)?);
        }
        return Ok(());
    }
    println!(
        "drive input -> wheel command; in process the fleet is stepped every {} ms of wall time",
        STEP.as_millis()
    );
    println!(
        "{:20} {:>7} {:>8} {:>8} {:>8}",
        "path", "trials", "p50 ms", "p99 ms", "max ms"
    );
    for r in &rows {
        println!(
            "{:20} {:>7} {:>8.1} {:>8.1} {:>8.1}",
            r.path, r.trials, r.p50_ms, r.p99_ms, r.max_ms
        );
    }
    let p50 = |path: &str| rows.iter().find(|r| r.path == path).map(|r| r.p50_ms);
    if let (Some(ws), Some(queue)) = (p50("websocket"), p50("device queue")) {
        println!(
            "ratio websocket / device queue (p50): {:.2}",
            ws / queue.max(f64::MIN_POSITIVE)
        );
    }
    Ok(())
}

fn round1(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}

/// Wall-clock time, ms since the Unix epoch (the clock the browser's event times are in).
fn unix_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1e3)
}

/// The demo's real-time loop: the page's actions applied, then one fleet step, every 50 ms of
/// wall time; the page gets the state every other step, as in the demo.
struct Loop<'a> {
    fleet: &'a mut Fleet,
    dashboard: &'a Dashboard,
    next: Instant,
    published: Option<Instant>,
    /// A non-zero command was applied after the last step.
    driving: bool,
}

impl Loop<'_> {
    /// One step; when the control agent applied the first non-zero command of a drive in it,
    /// when (unix ms) and the linear speed applied.
    fn step(&mut self) -> anyhow::Result<Option<(f64, f64)>> {
        std::thread::sleep(self.next.saturating_duration_since(Instant::now()));
        self.next = self.next.max(Instant::now() - STEP) + STEP;
        while let Some(action) = self.dashboard.try_action() {
            if let PageAction::Drive { chair, input } = action {
                demo::push_drive(self.fleet, &chair, input)?;
            }
        }
        self.fleet.step(STEP);
        let at = unix_ms();
        let applied = self
            .fleet
            .drive_status(CHAIR)?
            .applied
            .filter(|v| v.linear_mps != 0.0 || v.angular_radps != 0.0);
        let onset = applied
            .filter(|_| !self.driving)
            .map(|v| (at, v.linear_mps));
        self.driving = applied.is_some();
        if self
            .published
            .is_none_or(|t| t.elapsed() >= Duration::from_millis(100))
        {
            self.published = Some(Instant::now());
            let state =
                iw_fleet::dashboard::state(self.fleet, false, &Default::default(), Vec::new());
            self.dashboard
                .publish(&state)
                .context("publishing the state")?;
        }
        Ok(onset)
    }
}

/// Chromium and the folder of the browser scripts.
struct Browser {
    chromium: PathBuf,
    dir: PathBuf,
}

impl Browser {
    fn find(dir: &Path) -> anyhow::Result<Browser> {
        anyhow::ensure!(
            dir.join("latency.mjs").is_file() && dir.join("node_modules/playwright-core").is_dir(),
            "{} holds no latency.mjs with playwright-core installed (cli/tests/browser after \
             `npm ci`)",
            dir.display()
        );
        let chromium = std::env::var_os("CHROMIUM")
            .map(PathBuf::from)
            .or_else(|| {
                ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
                    .into_iter()
                    .map(PathBuf::from)
                    .find(|p| p.exists())
            })
            .context("no chromium (install Debian's chromium or set CHROMIUM)")?;
        Ok(Browser {
            chromium,
            dir: dir.to_path_buf(),
        })
    }

    /// Starts latency.mjs on `url`; its presses arrive on the receiver as (event time, unix ms;
    /// direction, +1 forward).
    fn start(&self, url: &str, trials: usize) -> anyhow::Result<(Script, Receiver<(f64, f64)>)> {
        let mut child = Command::new("node")
            .current_dir(&self.dir)
            .arg("latency.mjs")
            .arg(url)
            .arg(&self.chromium)
            .arg(CHAIR)
            .arg(trials.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .context("starting node latency.mjs")?;
        let stdout = child.stdout.take().context("the script's stdout")?;
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::Builder::new()
            .name("latency.mjs".into())
            .spawn(move || {
                for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                    let Ok(v) = serde_json::from_str::<Value>(&line) else {
                        eprintln!("latency.mjs: {line}");
                        continue;
                    };
                    if let (Some(at), Some(dir)) = (v["event_unix_ms"].as_f64(), v["dir"].as_f64())
                    {
                        if let Some(clock) = v["clock_ms"].as_f64()
                            && clock.abs() > 2.0
                        {
                            eprintln!("latency.mjs: the page's clocks disagree by {clock} ms");
                        }
                        if tx.send((at, dir)).is_err() {
                            return;
                        }
                    }
                }
            })
            .context("starting the script reader")?;
        Ok((
            Script {
                child,
                deadline: Instant::now() + PER_PRESS * trials as u32 + Duration::from_secs(60),
            },
            rx,
        ))
    }
}

/// The browser script running; killed if dropped before it ended.
struct Script {
    child: Child,
    deadline: Instant,
}

impl Script {
    /// Whether it ended (an error if it failed or ran out of time).
    fn ended(&mut self) -> anyhow::Result<bool> {
        if let Some(status) = self.child.try_wait()? {
            anyhow::ensure!(status.success(), "latency.mjs failed ({status})");
            return Ok(true);
        }
        if Instant::now() > self.deadline {
            bail!("latency.mjs still running at its deadline");
        }
        Ok(false)
    }
}

impl Drop for Script {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Each press's latency to the first wheel command in its direction after it and before the next
/// press, ms.
fn pair(presses: &[(f64, f64)], onsets: &[(f64, f64)]) -> anyhow::Result<Vec<f64>> {
    presses
        .iter()
        .enumerate()
        .map(|(k, &(at, dir))| {
            let next = presses.get(k + 1).map_or(f64::INFINITY, |p| p.0);
            onsets
                .iter()
                .find(|&&(t, linear)| t >= at && t < next && linear * dir > 0.0)
                .map(|&(t, _)| t - at)
                .with_context(|| {
                    format!("press {k}: no wheel command in its direction before the next press")
                })
        })
        .collect()
}

/// The browser on the in-process dashboard; the fleet keeps stepping meanwhile.
fn browser_in_process(
    loop_: &mut Loop<'_>,
    browser: &Browser,
    trials: usize,
) -> anyhow::Result<Vec<f64>> {
    let url = format!("http://{}/", loop_.dashboard.addr());
    let (mut script, presses_rx) = browser.start(&url, trials)?;
    let (mut presses, mut onsets) = (Vec::new(), Vec::new());
    while !script.ended()? {
        if let Some(onset) = loop_.step()? {
            onsets.push(onset);
        }
        presses.extend(presses_rx.try_iter());
    }
    // the reader may still hold the last lines
    std::thread::sleep(Duration::from_millis(100));
    presses.extend(presses_rx.try_iter());
    anyhow::ensure!(
        presses.len() == trials,
        "latency.mjs reported {} of {trials} presses",
        presses.len()
    );
    pair(&presses, &onsets)
}

/// The services (serving the dashboard), the world and one chair as processes; the browser on
/// the services' dashboard; the chair's `drive-applied` events.
fn across_processes(browser: &Browser, trials: usize) -> anyhow::Result<Vec<f64>> {
    let dir = std::env::temp_dir().join(format!("intellwheels-bench-drive-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let (tx, rx) = std::sync::mpsc::sync_channel(EVENT_QUEUE);
    let mut procs = Procs::new(dir.clone(), tx, &["ready", "serving", "drive-applied"]);
    let control = dir.join("control.key");
    iw_stack::write_group_key(&control)?;
    let control = control.display().to_string();
    let mut taken = BTreeSet::new();
    let dashboard = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .context("a free loopback port for the dashboard")?;
    let config = dir.join("services.toml");
    std::fs::write(
        &config,
        format!(
            "[services]\nchairs = [\"{CHAIR}\"]\nlog = {:?}\n\n[dashboard]\nlisten = \"{dashboard}\"\n",
            dir.join("agents.log").display().to_string()
        ),
    )
    .context("writing the services' configuration")?;
    let services = format!("127.0.0.1:{}", free_port_pair(&mut taken)?);
    let common = |listen: String| {
        vec![
            "--listen".to_string(),
            listen,
            "--control-key".into(),
            control.clone(),
        ]
    };
    let mut args = common(services.clone());
    args.extend([
        "--services".into(),
        "--config".into(),
        config.display().to_string(),
    ]);
    procs.launch("services", &args)?;
    let mut args = common(format!("127.0.0.1:{}", free_port_pair(&mut taken)?));
    args.extend(["--world".into(), "--peer".into(), services.clone()]);
    procs.launch("world", &args)?;
    let mut args = common(format!("127.0.0.1:{}", free_port_pair(&mut taken)?));
    args.extend([
        "--peer".into(),
        services,
        "--chair".into(),
        CHAIR.into(),
        "--start".into(),
        format!("{},{},{}", START[0], START[1], START[2]),
    ]);
    procs.launch(CHAIR, &args)?;

    let mut seen = Seen {
        rx,
        ready: 0,
        url: None,
        onsets: Vec::new(),
    };
    let deadline = Instant::now() + Duration::from_secs(120);
    let url = loop {
        seen.take(&mut procs)?;
        if let (3, Some(url)) = (seen.ready, &seen.url) {
            break url.clone();
        }
        anyhow::ensure!(
            Instant::now() < deadline,
            "the containers were not ready within 120 s"
        );
    };
    let (mut script, presses_rx) = browser.start(&url, trials)?;
    let mut presses = Vec::new();
    while !script.ended()? {
        seen.take(&mut procs)?;
        presses.extend(presses_rx.try_iter());
    }
    std::thread::sleep(Duration::from_millis(100));
    presses.extend(presses_rx.try_iter());
    drop(procs);
    anyhow::ensure!(
        presses.len() == trials,
        "latency.mjs reported {} of {trials} presses",
        presses.len()
    );
    pair(&presses, &seen.onsets)
}

/// What the containers' events said so far.
struct Seen {
    rx: Receiver<(usize, Value)>,
    /// Containers ready.
    ready: usize,
    /// The services' dashboard.
    url: Option<String>,
    /// The chair's `drive-applied` events: unix ms, linear m/s.
    onsets: Vec<(f64, f64)>,
}

impl Seen {
    /// Takes one event (or none within 5 ms); fails when a container exited.
    fn take(&mut self, procs: &mut Procs) -> anyhow::Result<()> {
        if let Some(exit) = procs.exited() {
            bail!("{exit}");
        }
        let (index, event) = match self.rx.recv_timeout(Duration::from_millis(5)) {
            Ok(event) => event,
            Err(RecvTimeoutError::Timeout) => return Ok(()),
            Err(RecvTimeoutError::Disconnected) => bail!("every container's output closed"),
        };
        match (index, event["event"].as_str()) {
            (_, Some("ready")) => self.ready += 1,
            (0, Some("serving")) if event["service"] == "dashboard" => {
                self.url = event["url"].as_str().map(str::to_string);
            }
            (CHAIR_INDEX, Some("drive-applied")) => {
                if let (Some(at), Some(linear)) =
                    (event["unix_ms"].as_f64(), event["linear_mps"].as_f64())
                {
                    self.onsets.push((at, linear));
                }
            }
            _ => {}
        }
        Ok(())
    }
}
