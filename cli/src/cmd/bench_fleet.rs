//! `intellwheels bench fleet --chairs N`: the deployment at scale, as processes on loopback UDP.
//!
//! Starts the services, the world and N virtual chairs (`intellwheels spawn`, visual odometry
//! off as `spawn` always runs it, control channel authenticated with a fresh group key) in a hall
//! generated for the run: one bay (a place of the map) per chair, the chair starting on it. Then:
//! - **convergence**: from the first chair's launch until every container has every other
//!   container's agents (those its `ready` event lists) in its Global Agent List, read from the
//!   `joined`/`left` events;
//! - **REQUEST/AGREE**: the services give each chair the goal of its own bay when it joins; the
//!   assistant's round trip to the chair's cognitive agent comes from the `agreed` events;
//! - **idle CPU**: once every goal is answered, user+system CPU of each process over a window,
//!   from `/proc/PID/stat`, as a share of one core.
//!
//! Every process is stopped (SIGTERM, then SIGKILL) on every exit path.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader, Write};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use serde_json::Value;

use super::bench::round1;

/// Distance between two bays, m: a chair (about 0.7 m by 1.2 m) and room to turn.
const BAY_SPACING_M: f64 = 2.5;
/// How long the goals are waited for once the fleet has converged.
const GOAL_WAIT: Duration = Duration::from_secs(30);
/// How long the processes get to stop after SIGTERM.
const STOP_GRACE: Duration = Duration::from_secs(5);
/// Events queued between the containers' readers and the bench, at most: a full queue holds the
/// readers back (and through its pipe the container's writer), it never grows (at 100 chairs an
/// unbounded one grew to 1.9 GB while the bench was not scheduled).
pub(super) const EVENT_QUEUE: usize = 65_536;
/// The events `bench fleet` reads; the rest are dropped unparsed by the readers and counted.
const FLEET_EVENTS: &[&str] = &["ready", "joined", "left", "agreed", "goal"];

/// How each fleet runs.
pub struct Settings {
    /// The idle window.
    pub idle: Duration,
    /// Longest run.
    pub timeout: Duration,
    /// container.heartbeat_ms of every container.
    pub heartbeat: Duration,
    /// container.lease_ms of every container.
    pub lease: Duration,
}

/// What one run measured (the JSON object: these keys and no others).
#[derive(Debug, serde::Serialize)]
pub struct FleetRow {
    chairs: usize,
    #[serde(rename = "heartbeat_ms", serialize_with = "iw_bus::millis::serialize")]
    heartbeat: Duration,
    #[serde(rename = "lease_ms", serialize_with = "iw_bus::millis::serialize")]
    lease: Duration,
    /// Every container: services, world and the chairs.
    containers: usize,
    /// From the first chair's launch until the last chair reported `ready`, s.
    launch_s: f64,
    /// From the first chair's launch until every container listed every agent, s.
    converged_s: f64,
    /// `left` events before convergence and during the idle window (agents dropped because a
    /// container missed its lease).
    left_events: usize,
    /// Of those, the ones the services reported (chairs' agents they dropped) and the ones the
    /// chairs reported (the other containers' agents a chair dropped).
    left_at_services: usize,
    left_at_chairs: usize,
    /// Leases that expired, from the containers' logs: the services' (a chair or the world
    /// not heard from for `lease_ms`) and the chairs' (the services or the world not heard from).
    leases_expired_at_services: usize,
    leases_expired_at_chairs: usize,
    /// Event lines the bench's readers dropped unparsed (kinds it does not read).
    events_shed: u64,
    /// The machine's 1-minute load average when the run started and when it ended.
    load_avg_start: f64,
    load_avg_end: f64,
    /// Chairs whose cognitive agent AGREEd to its goal.
    agreed: usize,
    rtt_p50_ms: f64,
    rtt_p99_ms: f64,
    rtt_max_ms: f64,
    /// Idle CPU, % of one core.
    services_cpu_pct: f64,
    world_cpu_pct: f64,
    chair_cpu_median_pct: f64,
    chair_cpu_max_pct: f64,
    /// Every container together, % of one core.
    total_cpu_pct: f64,
    /// The idle window, s.
    idle_s: f64,
}

/// The container processes; each is stopped when this is dropped.
pub(super) struct Procs {
    /// Name and child, in launch order (services, world, chairs).
    children: Vec<(String, Child)>,
    events: SyncSender<(usize, Value)>,
    /// The event kinds passed on.
    wanted: &'static [&'static str],
    /// Lines dropped by the readers: not JSON, or a kind not wanted.
    shed: Arc<AtomicU64>,
    dir: PathBuf,
}

impl Procs {
    /// No process yet; their stderr goes to files in `dir` (removed on drop), their events of
    /// the kinds in `wanted` to `events` (a bounded queue, [`EVENT_QUEUE`]), tagged with their
    /// launch index.
    pub(super) fn new(
        dir: PathBuf,
        events: SyncSender<(usize, Value)>,
        wanted: &'static [&'static str],
    ) -> Procs {
        Procs {
            children: Vec::new(),
            events,
            wanted,
            shed: Arc::default(),
            dir,
        }
    }

    /// Lines the readers dropped so far.
    pub(super) fn shed(&self) -> u64 {
        self.shed.load(Ordering::Relaxed)
    }

    pub(super) fn launch(&mut self, name: &str, args: &[String]) -> anyhow::Result<()> {
        let exe = std::env::current_exe().context("locating the intellwheels binary")?;
        let stderr = std::fs::File::create(self.dir.join(format!("{name}.stderr")))
            .context("creating a stderr file")?;
        let mut command = Command::new(exe);
        if std::env::var_os("RUST_LOG").is_none() {
            // the containers log each lease that expires at info (counted in the results)
            command.env("RUST_LOG", "warn,iw_container=info");
        }
        let mut child = command
            .arg("spawn")
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .with_context(|| format!("starting container {name}"))?;
        let stdout = child.stdout.take().context("the child's stdout")?;
        let index = self.children.len();
        let (events, wanted, shed) = (self.events.clone(), self.wanted, self.shed.clone());
        std::thread::Builder::new()
            .name(format!("events-{name}"))
            .spawn(move || read_events(BufReader::new(stdout), index, &events, wanted, &shed))
            .context("starting an event reader")?;
        self.children.push((name.to_string(), child));
        Ok(())
    }

    /// Exits so far, with the container's name and the tail of its stderr.
    pub(super) fn exited(&mut self) -> Option<String> {
        for (name, child) in &mut self.children {
            if let Ok(Some(status)) = child.try_wait() {
                let err = std::fs::read_to_string(self.dir.join(format!("{name}.stderr")))
                    .unwrap_or_default();
                let tail: String = err.lines().rev().take(5).collect::<Vec<_>>().join(" | ");
                return Some(format!("container {name} exited ({status}): {tail}"));
            }
        }
        None
    }

    /// Lines of each container's log (in launch order) that hold `text`.
    pub(super) fn log_lines(&self, text: &str) -> Vec<usize> {
        self.children
            .iter()
            .map(|(name, _)| {
                std::fs::read_to_string(self.dir.join(format!("{name}.stderr")))
                    .map_or(0, |log| log.lines().filter(|l| l.contains(text)).count())
            })
            .collect()
    }

    /// SIGTERM to all (chairs first, services last), then SIGKILL to what is left.
    fn stop(&mut self) {
        for (_, child) in self.children.iter().rev() {
            // SAFETY: kill(2) on our own child's pid; a failure only means it is gone
            unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
        }
        let deadline = Instant::now() + STOP_GRACE;
        for (_, child) in &mut self.children {
            while Instant::now() < deadline && matches!(child.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
        self.children.clear();
    }
}

/// The kind of a `spawn` event line: its first field, `{"event":"KIND",` (the tag serde writes
/// first), read without parsing the line.
fn event_kind(line: &str) -> Option<&str> {
    let rest = line.strip_prefix("{\"event\":\"")?;
    rest.split_once('"').map(|(kind, _)| kind)
}

/// Passes container `index`'s events of the `wanted` kinds to `events` until its output or
/// the receiver closes; every other line is dropped unparsed and counted in `shed`.
fn read_events(
    lines: impl BufRead,
    index: usize,
    events: &SyncSender<(usize, Value)>,
    wanted: &[&str],
    shed: &AtomicU64,
) {
    for line in lines.lines().map_while(Result::ok) {
        let value = event_kind(&line)
            .filter(|kind| wanted.contains(kind))
            .and_then(|_| serde_json::from_str::<Value>(&line).ok());
        match value {
            Some(value) => {
                if events.send((index, value)).is_err() {
                    return;
                }
            }
            None => {
                shed.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

impl Drop for Procs {
    fn drop(&mut self) {
        self.stop();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Two consecutive free UDP ports on loopback (bus and control channel), not in `taken`.
pub(super) fn free_port_pair(taken: &mut BTreeSet<u16>) -> anyhow::Result<u16> {
    for _ in 0..1000 {
        let a = UdpSocket::bind("127.0.0.1:0").context("binding a loopback port")?;
        let port = a.local_addr()?.port();
        if port < u16::MAX
            && !taken.contains(&port)
            && !taken.contains(&(port + 1))
            && UdpSocket::bind(("127.0.0.1", port + 1)).is_ok()
        {
            taken.extend([port, port + 1]);
            return Ok(port);
        }
    }
    bail!("no two consecutive free UDP ports on loopback")
}

/// The hall: a square room with one bay per chair on a grid.
fn hall(chairs: usize) -> (String, Vec<[f64; 2]>) {
    let cols = (chairs as f64).sqrt().ceil().max(1.0) as usize;
    let rows = chairs.div_ceil(cols);
    let (w, h) = (
        (cols + 1) as f64 * BAY_SPACING_M,
        (rows + 1) as f64 * BAY_SPACING_M,
    );
    let bays: Vec<[f64; 2]> = (0..chairs)
        .map(|i| {
            [
                (i % cols + 1) as f64 * BAY_SPACING_M,
                (i / cols + 1) as f64 * BAY_SPACING_M,
            ]
        })
        .collect();
    let mut map = format!(
        "# generated by intellwheels bench fleet: a hall with one bay per chair\nname bench hall\nwall closed 0 0 {w} 0 {w} {h} 0 {h}\n"
    );
    for (i, [x, y]) in bays.iter().enumerate() {
        map.push_str(&format!("place bay-{i} {x} {y}\n"));
    }
    (map, bays)
}

/// The machine's 1-minute load average (other work on the machine shows in every figure).
fn load_average() -> anyhow::Result<f64> {
    let text = std::fs::read_to_string("/proc/loadavg").context("reading /proc/loadavg")?;
    text.split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .context("/proc/loadavg without a 1-minute figure")
}

/// User plus system CPU time of `pid` so far, s.
fn cpu_seconds(pid: u32) -> anyhow::Result<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .with_context(|| format!("reading /proc/{pid}/stat"))?;
    // the command name (field 2) may hold spaces: the fields after it follow its last ')'
    let rest = stat
        .rsplit_once(')')
        .map(|(_, r)| r)
        .context("/proc/PID/stat without a command name")?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // after the name: state is field 3, utime 14, stime 15 (1-based): indices 11 and 12 here
    let ticks = |i: usize| -> anyhow::Result<f64> {
        Ok(fields
            .get(i)
            .context("/proc/PID/stat too short")?
            .parse::<u64>()? as f64)
    };
    // SAFETY: sysconf has no preconditions
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    if hz <= 0.0 {
        bail!("sysconf(_SC_CLK_TCK) failed");
    }
    Ok((ticks(11)? + ticks(12)?) / hz)
}

/// The containers' Global Agent List views, from their events.
struct Views {
    /// Each container's own agents, from its `ready` event.
    own: Vec<Option<BTreeSet<String>>>,
    /// Agents each container installed (joined and not left since).
    installed: Vec<BTreeSet<String>>,
    /// `left` events per container.
    left_at: Vec<usize>,
    left: usize,
}

impl Views {
    fn new(containers: usize) -> Views {
        Views {
            own: vec![None; containers],
            installed: vec![BTreeSet::new(); containers],
            left_at: vec![0; containers],
            left: 0,
        }
    }

    fn apply(&mut self, index: usize, event: &Value) {
        let agent = || event["agent"].as_str().unwrap_or_default().to_string();
        match event["event"].as_str() {
            Some("ready") => {
                let agents = event["agents"]
                    .as_array()
                    .map(|a| {
                        a.iter()
                            .filter_map(|v| v.as_str().map(str::to_string))
                            .collect()
                    })
                    .unwrap_or_default();
                self.own[index] = Some(agents);
            }
            Some("joined") => {
                self.installed[index].insert(agent());
            }
            Some("left") => {
                self.installed[index].remove(&agent());
                self.left_at[index] += 1;
                self.left += 1;
            }
            _ => {}
        }
    }

    fn ready(&self) -> usize {
        self.own.iter().filter(|o| o.is_some()).count()
    }

    /// Containers that list every agent of every other container (0 until all are ready).
    fn converged(&self) -> usize {
        if self.ready() < self.own.len() {
            return 0;
        }
        (0..self.own.len())
            .filter(|&i| {
                self.own.iter().enumerate().all(|(j, agents)| {
                    i == j
                        || agents
                            .iter()
                            .flatten()
                            .all(|a| self.installed[i].contains(a))
                })
            })
            .count()
    }
}

/// The percentile `q` of sorted `values` (nearest rank); 0 when empty.
pub(super) fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// A running fleet and what its events said so far.
struct Run {
    procs: Procs,
    rx: Receiver<(usize, Value)>,
    views: Views,
    /// Each chair's REQUEST/AGREE round trip, ms (from the services' `agreed` events).
    agreed: BTreeMap<String, f64>,
    /// Chairs whose goal got its final answer.
    answered: BTreeSet<String>,
    deadline: Instant,
    timeout: Duration,
}

impl Run {
    fn apply(&mut self, index: usize, event: &Value) {
        self.views.apply(index, event);
        if index != 0 {
            return;
        }
        let chair = event["chair"].as_str().unwrap_or_default().to_string();
        match event["event"].as_str() {
            Some("agreed") => {
                if let Some(ms) = event["round_trip_ms"].as_f64() {
                    self.agreed.entry(chair).or_insert(ms);
                }
            }
            Some("goal") if event["performative"] != "AGREE" => {
                self.answered.insert(chair);
            }
            _ => {}
        }
    }

    /// Takes events until `done` holds; fails when a container exits or at the deadline.
    fn until(&mut self, what: &str, mut done: impl FnMut(&Run) -> bool) -> anyhow::Result<()> {
        let mut last_check = Instant::now();
        loop {
            match self.rx.recv_timeout(Duration::from_millis(20)) {
                Ok((index, event)) => {
                    self.apply(index, &event);
                    // take what is queued before checking (the check walks every list), but no
                    // more than a queue's worth: readers refill it as fast as it drains, and
                    // the deadline must still be seen
                    for _ in 0..EVENT_QUEUE {
                        let Ok((index, event)) = self.rx.try_recv() else {
                            break;
                        };
                        self.apply(index, &event);
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => bail!("{what}: every output closed"),
            }
            if done(self) {
                return Ok(());
            }
            if last_check.elapsed() >= Duration::from_millis(200) {
                last_check = Instant::now();
                if let Some(exit) = self.procs.exited() {
                    bail!("{what}: {exit}");
                }
            }
            if Instant::now() >= self.deadline {
                bail!("{what}: not within the {:?} timeout", self.timeout);
            }
        }
    }

    /// What the containers' logs say went wrong so far: how many of them logged each kind of
    /// trouble, and how often.
    fn trouble(&self) -> String {
        [
            "lease expired",
            "world unreachable",
            "no sensor frame",
            "key agreement pending, queue full",
            "undeliverable",
        ]
        .iter()
        .map(|text| {
            let lines = self.procs.log_lines(text);
            let containers = lines.iter().filter(|n| **n > 0).count();
            let total: usize = lines.iter().sum();
            format!("`{text}` {total} times in {containers} containers")
        })
        .collect::<Vec<_>>()
        .join(", ")
    }

    /// Takes events for `window` (keeps the pipes drained while the fleet idles).
    fn drain_for(&mut self, window: Duration) -> anyhow::Result<()> {
        let end = Instant::now() + window;
        self.until("idle window", |_| Instant::now() >= end)
    }
}

/// Runs the fleet of `chairs` chairs and measures it.
pub fn measure(chairs: usize, settings: &Settings) -> anyhow::Result<FleetRow> {
    let (idle, timeout) = (settings.idle, settings.timeout);
    let dir = std::env::temp_dir().join(format!("intellwheels-bench-fleet-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let load_avg_start = load_average()?;
    let (tx, rx) = std::sync::mpsc::sync_channel(EVENT_QUEUE);
    let containers = chairs + 2;
    let mut run = Run {
        procs: Procs::new(dir.clone(), tx, FLEET_EVENTS),
        rx,
        views: Views::new(containers),
        agreed: BTreeMap::new(),
        answered: BTreeSet::new(),
        deadline: Instant::now() + timeout,
        timeout,
    };
    let control = dir.join("control.key");
    iw_stack::write_group_key(&control)?;
    let control = control.display().to_string();
    let (map, bays) = hall(chairs);
    let map_path = dir.join("hall.map");
    std::fs::write(&map_path, map).context("writing the hall map")?;
    let names: Vec<String> = (0..chairs).map(|i| format!("chair-{i}")).collect();
    let config = dir.join("fleet.toml");
    write_config(
        &config,
        &map_path,
        &dir.join("agents.log"),
        &names,
        settings,
    )?;
    let config = config.display().to_string();
    let mut taken = BTreeSet::new();
    let mut args = |peer: Option<&str>| -> anyhow::Result<(String, Vec<String>)> {
        let listen = format!("127.0.0.1:{}", free_port_pair(&mut taken)?);
        let mut args = vec![
            "--config".to_string(),
            config.clone(),
            "--listen".into(),
            listen.clone(),
            "--control-key".into(),
            control.clone(),
        ];
        if let Some(peer) = peer {
            args.extend(["--peer".into(), peer.into()]);
        }
        Ok((listen, args))
    };

    let bar = indicatif::ProgressBar::new(containers as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:<20} [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message("services, world");
    let (services, mut services_args) = args(None)?;
    services_args.push("--services".into());
    run.procs.launch("services", &services_args)?;
    let (_, mut world_args) = args(Some(&services))?;
    world_args.push("--world".into());
    run.procs.launch("world", &world_args)?;
    run.until("services and world ready", |r| r.views.ready() == 2)?;
    bar.set_position(2);

    bar.set_message("chairs ready");
    let t0 = Instant::now();
    for (name, [x, y]) in names.iter().zip(&bays) {
        let (_, mut chair_args) = args(Some(&services))?;
        chair_args.extend([
            "--chair".into(),
            name.clone(),
            "--start".into(),
            format!("{x},{y},0"),
        ]);
        run.procs.launch(name, &chair_args)?;
    }
    run.until("every chair ready", |r| {
        bar.set_position(r.views.ready() as u64);
        r.views.ready() == containers
    })?;
    let launch = t0.elapsed();

    bar.set_message("converged");
    let mut checked = Instant::now() - Duration::from_secs(1);
    run.until("convergence", |r| {
        // the check walks every list: every 20 ms at most
        if checked.elapsed() < Duration::from_millis(20) {
            return false;
        }
        checked = Instant::now();
        let n = r.views.converged();
        bar.set_position(n as u64);
        n == containers
    })
    .with_context(|| {
        format!(
            "{} of {containers} containers listed every agent; agents left {} times meanwhile; {}",
            run.views.converged(),
            run.views.left,
            run.trouble()
        )
    })?;
    let converged = t0.elapsed();

    bar.set_message("goals answered");
    bar.set_length(chairs as u64);
    // a goal lost in the churn of a fleet that barely holds is counted (`agreed`), not waited for
    let goals_by = Instant::now() + GOAL_WAIT;
    run.until("every goal answered", |r| {
        bar.set_position(r.answered.len() as u64);
        (r.answered.len() == chairs && r.agreed.len() == chairs) || Instant::now() >= goals_by
    })?;

    bar.set_message("idle");
    bar.set_length(1);
    bar.set_position(0);
    let pids: Vec<u32> = run.procs.children.iter().map(|(_, c)| c.id()).collect();
    let before: Vec<f64> = pids
        .iter()
        .map(|p| cpu_seconds(*p))
        .collect::<anyhow::Result<_>>()?;
    let left_before_idle = run.views.left;
    let started = Instant::now();
    run.deadline = run.deadline.max(started + idle + Duration::from_secs(5));
    run.drain_for(idle)?;
    let window = started.elapsed().as_secs_f64();
    let after: Vec<f64> = pids
        .iter()
        .map(|p| cpu_seconds(*p))
        .collect::<anyhow::Result<_>>()?;
    bar.finish_and_clear();
    let cpu_pct: Vec<f64> = before
        .iter()
        .zip(&after)
        .map(|(b, a)| 100.0 * (a - b) / window)
        .collect();
    let mut chair_cpu = cpu_pct[2..].to_vec();
    chair_cpu.sort_by(f64::total_cmp);
    let mut rtt: Vec<f64> = run.agreed.values().copied().collect();
    rtt.sort_by(f64::total_cmp);
    if run.views.left > left_before_idle {
        tracing::warn!(
            left = run.views.left - left_before_idle,
            "agents left while the fleet idled: containers missed their leases"
        );
    }
    let expired = run.procs.log_lines("lease expired");
    Ok(FleetRow {
        chairs,
        heartbeat: settings.heartbeat,
        lease: settings.lease,
        containers,
        launch_s: round2(launch.as_secs_f64()),
        converged_s: round2(converged.as_secs_f64()),
        left_events: run.views.left,
        left_at_services: run.views.left_at[0],
        left_at_chairs: run.views.left_at[2..].iter().sum(),
        leases_expired_at_services: expired[0],
        leases_expired_at_chairs: expired[2..].iter().sum(),
        events_shed: run.procs.shed(),
        load_avg_start,
        load_avg_end: load_average()?,
        agreed: rtt.len(),
        rtt_p50_ms: round1(percentile(&rtt, 0.5)),
        rtt_p99_ms: round1(percentile(&rtt, 0.99)),
        rtt_max_ms: round1(percentile(&rtt, 1.0)),
        services_cpu_pct: round1(cpu_pct[0]),
        world_cpu_pct: round1(cpu_pct[1]),
        chair_cpu_median_pct: round1(percentile(&chair_cpu, 0.5)),
        chair_cpu_max_pct: round1(percentile(&chair_cpu, 1.0)),
        total_cpu_pct: round1(cpu_pct.iter().sum()),
        idle_s: round2(window),
    })
}

fn round2(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

/// The configuration every container reads: the hall, and for the services each chair's goal
/// (its own bay) and the log.
fn write_config(
    path: &Path,
    map: &Path,
    log: &Path,
    chairs: &[String],
    settings: &Settings,
) -> anyhow::Result<()> {
    let goals: String = chairs
        .iter()
        .enumerate()
        .map(|(i, n)| format!("{{ chair = \"{n}\", place = \"bay-{i}\" }},"))
        .collect();
    std::fs::write(
        path,
        format!(
            "[container]\nheartbeat_ms = {}\nlease_ms = {}\n[world]\nmap = {map:?}\n[services]\ngoals = [{goals}]\nlog = {log:?}\n",
            settings.heartbeat.as_millis(),
            settings.lease.as_millis(),
            map = map.display().to_string(),
            log = log.display().to_string(),
        ),
    )
    .context("writing the fleet configuration")
}

/// `bench fleet`: one run per entry of `chairs`, each a JSON line or a table row; a run that
/// fails is reported (`error`) and the others still run; the cost curves go to `plot`.
pub fn run(
    chairs: &[usize],
    settings: &Settings,
    json: bool,
    plot: Option<&Path>,
) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    if !json {
        writeln!(
            out,
            "heartbeat {} ms, lease {} ms, idle window {:?}",
            settings.heartbeat.as_millis(),
            settings.lease.as_millis(),
            settings.idle
        )?;
        writeln!(
            out,
            "{:>6} {:>8} {:>10} {:>5} {:>7} {:>7} {:>7} {:>9} {:>7} {:>10} {:>10} {:>7} {:>6}",
            "chairs",
            "launch s",
            "converge s",
            "left",
            "agreed",
            "rtt p50",
            "rtt p99",
            "services%",
            "world%",
            "chair% p50",
            "chair% max",
            "total%",
            "idle s"
        )?;
    }
    let mut rows = Vec::new();
    let mut failed = Vec::new();
    for &n in chairs {
        match measure(n, settings) {
            Ok(row) => {
                if json {
                    serde_json::to_writer(&mut out, &row)?;
                    writeln!(out)?;
                } else {
                    writeln!(
                        out,
                        "{:>6} {:>8} {:>10} {:>5} {:>7} {:>7} {:>7} {:>9} {:>7} {:>10} {:>10} {:>7} {:>6}",
                        row.chairs,
                        row.launch_s,
                        row.converged_s,
                        row.left_events,
                        row.agreed,
                        row.rtt_p50_ms,
                        row.rtt_p99_ms,
                        row.services_cpu_pct,
                        row.world_cpu_pct,
                        row.chair_cpu_median_pct,
                        row.chair_cpu_max_pct,
                        row.total_cpu_pct,
                        row.idle_s
                    )?;
                }
                rows.push(row);
            }
            Err(e) => {
                let reason = super::describe(&e);
                if json {
                    serde_json::to_writer(
                        &mut out,
                        &serde_json::json!({ "chairs": n, "error": reason }),
                    )?;
                    writeln!(out)?;
                } else {
                    writeln!(out, "{n:>6} failed: {reason}")?;
                }
                failed.push(n);
            }
        }
        out.flush()?;
    }
    if let Some(path) = plot {
        plot_curves(path, &rows)?;
    }
    if !failed.is_empty() {
        bail!("the fleets of {failed:?} chairs failed (see above)");
    }
    Ok(())
}

/// The cost curves: convergence, idle CPU and the round trip against the number of chairs.
fn plot_curves(path: &Path, rows: &[FleetRow]) -> anyhow::Result<()> {
    use iw_plot::curves::{Curve, CurvePanel};
    let curve = |name: &str, y: fn(&FleetRow) -> f64| Curve {
        name: name.into(),
        points: rows.iter().map(|r| (r.chairs as f64, y(r))).collect(),
    };
    let panels = [
        CurvePanel {
            y_label: "time from launch (s)".into(),
            curves: vec![
                curve("every GAL complete", |r| r.converged_s),
                curve("every chair ready", |r| r.launch_s),
            ],
            level: Some(("target: 100 chairs within 5 s".into(), 5.0)),
        },
        CurvePanel {
            y_label: "idle CPU (% of one core)".into(),
            curves: vec![
                curve("services", |r| r.services_cpu_pct),
                curve("world", |r| r.world_cpu_pct),
                curve("one chair (median)", |r| r.chair_cpu_median_pct),
            ],
            level: Some(("target: services below 25 %".into(), 25.0)),
        },
        CurvePanel {
            y_label: "all containers, idle CPU (% of one core)".into(),
            curves: vec![curve("total", |r| r.total_cpu_pct)],
            level: Some(("the machine: 2 cores".into(), 200.0)),
        },
        CurvePanel {
            y_label: "REQUEST/AGREE round trip (ms)".into(),
            curves: vec![
                curve("p50", |r| r.rtt_p50_ms),
                curve("p99", |r| r.rtt_p99_ms),
            ],
            level: None,
        },
    ];
    iw_plot::curves::plot_curves(
        path,
        "intellwheels bench fleet: cost against the number of chair processes",
        "chair processes",
        &panels,
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hall_parses_with_one_free_bay_per_chair() {
        for chairs in [1, 10, 11, 100] {
            let (text, bays) = hall(chairs);
            let map = iw_sim::Map::parse(&text, "hall.map").unwrap();
            assert_eq!(bays.len(), chairs);
            let mut world = iw_sim::World::new(map, 1);
            for [x, y] in bays {
                let pose = nalgebra::Isometry2::new(nalgebra::Vector2::new(x, y), 0.0);
                let id = world.add_chair(
                    iw_sim::ChairSpec::default(),
                    pose,
                    iw_sim::ChairKind::Simulated,
                );
                assert_eq!(world.obstruction(id).unwrap(), None, "{chairs} chairs");
            }
        }
    }

    #[test]
    fn cpu_time_of_this_process_grows_as_it_works() {
        let pid = std::process::id();
        let before = cpu_seconds(pid).unwrap();
        let start = Instant::now();
        let mut x = 0u64;
        while start.elapsed() < Duration::from_millis(300) {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        assert!(cpu_seconds(pid).unwrap() > before);
    }

    #[test]
    fn readers_pass_wanted_events_and_count_what_they_drop() {
        let lines = concat!(
            "{\"event\":\"joined\",\"agent\":\"a@1\",\"container\":1}\n",
            "{\"event\":\"body\",\"chair\":\"c\"}\n",
            "not json\n",
            "{\"event\":\"left\",\"agent\":\"a@1\",\"container\":1}\n",
            "{\"event\":\"joined\",\"agent\":\n",
        );
        let (tx, rx) = std::sync::mpsc::sync_channel(8);
        let shed = AtomicU64::new(0);
        read_events(lines.as_bytes(), 3, &tx, &["joined", "left"], &shed);
        drop(tx);
        let got: Vec<(usize, String)> = rx
            .iter()
            .map(|(i, v)| (i, v["event"].as_str().unwrap().to_string()))
            .collect();
        assert_eq!(got, [(3, "joined".into()), (3, "left".into())]);
        // the body event, the line that is not JSON and the cut-off one
        assert_eq!(shed.load(Ordering::Relaxed), 3);
    }

    #[test]
    fn a_full_event_queue_holds_the_reader_back_instead_of_growing() {
        let line = "{\"event\":\"left\",\"agent\":\"a@1\",\"container\":1}\n";
        let lines = line.repeat(100);
        let (tx, rx) = std::sync::mpsc::sync_channel(4);
        let reader = std::thread::spawn(move || {
            read_events(lines.as_bytes(), 0, &tx, &["left"], &AtomicU64::new(0));
        });
        std::thread::sleep(Duration::from_millis(100));
        // nobody took any: the reader waits at the bound, with its pipe still holding the rest
        assert!(!reader.is_finished());
        assert_eq!(rx.iter().count(), 100);
        reader.join().unwrap();
    }

    #[test]
    fn an_event_kind_is_read_from_the_tag_serde_writes_first() {
        assert_eq!(
            event_kind(r#"{"event":"ready","agents":[]}"#),
            Some("ready")
        );
        assert_eq!(event_kind(r#"{"agents":[],"event":"ready"}"#), None);
        assert_eq!(event_kind("{\"event\":\"cut"), None);
    }

    #[test]
    fn convergence_needs_every_other_containers_agents() {
        let mut views = Views::new(2);
        let ev = |s: &str| serde_json::from_str::<Value>(s).unwrap();
        views.apply(0, &ev(r#"{"event":"ready","agents":["a@0"]}"#));
        assert_eq!(views.converged(), 0);
        views.apply(1, &ev(r#"{"event":"ready","agents":["b@1","c@1"]}"#));
        views.apply(0, &ev(r#"{"event":"joined","agent":"b@1"}"#));
        views.apply(1, &ev(r#"{"event":"joined","agent":"a@0"}"#));
        assert_eq!(views.converged(), 1);
        views.apply(0, &ev(r#"{"event":"joined","agent":"c@1"}"#));
        assert_eq!(views.converged(), 2);
        views.apply(0, &ev(r#"{"event":"left","agent":"c@1"}"#));
        assert_eq!((views.converged(), views.left), (1, 1));
    }
}
