//! Across processes (`intellwheels scenario run FILE --processes`): the same scenario file
//! played by the deployment itself. The world, the services and each chair are
//! `intellwheels spawn` processes on loopback UDP, in real time, with the scenario's map, seed,
//! chairs and restricted doors; the runner gives the goals and plays the faults, reads the
//! containers' JSON events and, at the end, the logger agent's log, and checks the same
//! assertions over the same typed [`Observation`]s as in process.
//!
//! Faults map to process faults:
//! - `link-loss`: every datagram between containers goes through an impairment [`relay`],
//!   which drops what a cut-off container sends or is sent;
//! - `kill-agent`: the container removes the agent (its admin path, `--admin-stdin`: only this
//!   process holds the pipe);
//! - `kill-container`: SIGKILL to the container process;
//! - `laser-blind`: the world container blinds the chair's laser in the frames it sends (its
//!   admin path) and gives it back at the end of `for_s`;
//! - `sensor-failure` of the `laser` or the `sonars`: the world container sends garbage for
//!   that sensor's readings (its admin path) and restores them at the end of `for_s`.
//!
//! A real or mixed chair's interface board is emulated on a pty in this process (with its
//! hardware watchdog), as the board of a real chair would be beside its computer.
//!
//! Not played across processes (refused by [`Scenario::validate_for`]): a failure of every
//! body read (`sensor-failure` with sensor `all`), jammed doors and door commands. With `visual_odometry`, a virtual chair's container renders
//! its camera from its own copy of the map at the true pose the world sends
//! (`iw_wiring::camera`).

pub mod relay;

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use iw_acl::Performative;
use iw_body::{BoardEmulator, WheelGeometry};
use iw_fleet::BodyKind;
use iw_fleet::compose::world_link::FailedSensor;
use iw_node::Event;
use iw_sim::Map;

use crate::ScenarioError;
use crate::assertions::check;
use crate::observe::{Observation, Totals};
use crate::report::{ChairSummary, Mode, Report};
use crate::schedule::{Cue, add_goal_places, schedule};
use crate::schema::{Fault, Scenario};
use relay::Relay;

/// The world container's name.
const WORLD: &str = iw_fleet::compose::world_link::WORLD;
/// How often the world reports its bodies, ms (the speed and goal checks sample at this rate).
const BODY_REPORT_MS: u64 = 100;
/// How long a board keeps its last speed without a command (its hardware watchdog).
const BOARD_WATCHDOG: Duration = Duration::from_millis(300);

/// How to play a scenario across processes.
#[derive(Debug, Clone)]
pub struct ProcessOptions {
    /// The `intellwheels` binary to run `spawn` with (the CLI passes its own).
    pub exe: PathBuf,
    /// Longest wait for the containers to start and join each other, and for each to stop.
    pub startup: Duration,
}

impl ProcessOptions {
    /// Options running `exe`, with a startup limit generous for a loaded 2-core machine.
    pub fn new(exe: impl Into<PathBuf>) -> ProcessOptions {
        ProcessOptions {
            exe: exe.into(),
            startup: Duration::from_secs(90),
        }
    }
}

/// A line of a container, or its end.
enum Line {
    Event(String, Instant, Event),
    Garbage(String, String),
    Closed(String),
}

/// A container process: killed and reaped when dropped.
struct Container {
    name: String,
    child: Child,
    stdin: Option<ChildStdin>,
    stderr: PathBuf,
    /// Its agents when it reported ready.
    agents: Vec<String>,
    /// Gone: killed, or stopped.
    gone: bool,
}

impl Drop for Container {
    fn drop(&mut self) {
        // SIGKILL is harmless for a process that has already exited (it is reaped next)
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Everything a run across processes holds; dropping it kills every child and removes its files.
struct Deployment<'a> {
    // dropped first (fields drop in order), so no child outlives its boards, relay or files
    containers: Vec<Container>,
    _boards: Vec<BoardEmulator>,
    relay: Option<Relay>,
    dir: tempfile::TempDir,
    scenario: &'a Scenario,
    options: &'a ProcessOptions,
    lines: Receiver<Line>,
    tx: Sender<Line>,
    /// Everything the containers reported, in arrival order.
    events: Vec<(String, Instant, Event)>,
    garbage: Vec<String>,
}

impl Deployment<'_> {
    fn path(&self) -> String {
        self.scenario.source.display().to_string()
    }

    fn failed(&self, container: &str, reason: impl Into<String>) -> ScenarioError {
        let last_words = self
            .containers
            .iter()
            .find(|c| c.name == container)
            .and_then(|c| std::fs::read_to_string(&c.stderr).ok())
            .map(|text| {
                let lines: Vec<&str> = text.lines().collect();
                lines[lines.len().saturating_sub(8)..].join("\n")
            })
            .unwrap_or_default();
        ScenarioError::Container {
            path: self.path(),
            container: container.into(),
            reason: reason.into(),
            last_words,
        }
    }

    fn io_err(
        &self,
        container: &str,
        what: &str,
    ) -> impl FnOnce(std::io::Error) -> ScenarioError + use<> {
        let (path, container, what) = (self.path(), container.to_string(), what.to_string());
        move |source| ScenarioError::Spawn {
            path,
            container,
            what,
            source,
        }
    }

    /// Starts `intellwheels spawn ARGS --admin-stdin` as container `name`.
    fn spawn(&mut self, name: &str, args: &[String]) -> Result<(), ScenarioError> {
        let stderr = self.dir.path().join(format!("{name}.stderr"));
        let file = std::fs::File::create(&stderr).map_err(self.io_err(name, "stderr file"))?;
        let mut child = Command::new(&self.options.exe)
            .arg("spawn")
            .args(args)
            .arg("--admin-stdin")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::from(file))
            .spawn()
            .map_err(self.io_err(name, "starting `intellwheels spawn`"))?;
        let stdout = child.stdout.take();
        let stdin = child.stdin.take();
        self.containers.push(Container {
            name: name.to_string(),
            child,
            stdin,
            stderr,
            agents: Vec::new(),
            gone: false,
        });
        let Some(stdout) = stdout else {
            return Err(self.failed(name, "no stdout"));
        };
        let tx = self.tx.clone();
        let container = name.to_string();
        std::thread::Builder::new()
            .name(format!("events-{name}"))
            .spawn(move || {
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    let sent = match serde_json::from_str::<Event>(&line) {
                        Ok(event) => tx.send(Line::Event(container.clone(), Instant::now(), event)),
                        Err(e) => tx.send(Line::Garbage(container.clone(), format!("{line}: {e}"))),
                    };
                    if sent.is_err() {
                        return;
                    }
                }
                let _ = tx.send(Line::Closed(container));
            })
            .map_err(self.io_err(name, "starting its event reader"))?;
        Ok(())
    }

    /// Takes the lines that arrived within `wait`; fails if a container that is not gone
    /// closed its stdout.
    fn pump(&mut self, wait: Duration) -> Result<(), ScenarioError> {
        let deadline = Instant::now() + wait;
        loop {
            let line = match self
                .lines
                .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            {
                Ok(line) => line,
                Err(RecvTimeoutError::Timeout) => return Ok(()),
                Err(RecvTimeoutError::Disconnected) => return Ok(()), // never: we hold a sender
            };
            match line {
                Line::Event(container, at, event) => self.events.push((container, at, event)),
                Line::Garbage(container, text) => {
                    self.garbage.push(format!("{container}: {text}"));
                }
                Line::Closed(container) => {
                    let gone = self
                        .containers
                        .iter()
                        .any(|c| c.name == container && c.gone);
                    if !gone {
                        return Err(self.failed(&container, "exited during the run"));
                    }
                }
            }
            if Instant::now() >= deadline {
                return Ok(());
            }
        }
    }

    /// Waits (up to the startup limit) until `done` holds over the events so far.
    fn wait_until(
        &mut self,
        container: &str,
        what: &str,
        done: impl Fn(&[(String, Instant, Event)]) -> bool,
    ) -> Result<(), ScenarioError> {
        let deadline = Instant::now() + self.options.startup;
        while !done(&self.events) {
            if Instant::now() >= deadline {
                return Err(self.failed(
                    container,
                    format!("no {what} within {:?}", self.options.startup),
                ));
            }
            self.pump(Duration::from_millis(50))?;
        }
        Ok(())
    }

    fn container(&mut self, name: &str) -> Option<&mut Container> {
        self.containers.iter_mut().find(|c| c.name == name)
    }

    /// Writes admin command `json` to container `name`.
    fn admin(&mut self, name: &str, json: &serde_json::Value) -> Result<(), ScenarioError> {
        let err = self.io_err(name, "writing an admin command");
        let Some(stdin) = self.container(name).and_then(|c| c.stdin.as_mut()) else {
            return Err(self.failed(name, "is not running"));
        };
        writeln!(stdin, "{json}")
            .and_then(|()| stdin.flush())
            .map_err(err)
    }

    /// Blinds chair `chair`'s laser in the world (or gives it back).
    fn blind_laser(&mut self, chair: &str, blind: bool) -> Result<(), ScenarioError> {
        self.admin(
            WORLD,
            &serde_json::json!({ "admin": "laser-blind", "chair": chair, "blind": blind }),
        )
    }

    /// Fails chair `chair`'s `sensor` in the world (or restores it).
    fn fail_sensor(
        &mut self,
        chair: &str,
        sensor: FailedSensor,
        failed: bool,
    ) -> Result<(), ScenarioError> {
        self.admin(
            WORLD,
            &serde_json::json!({
                "admin": "sensor-failure", "chair": chair, "sensor": sensor, "failed": failed
            }),
        )
    }

    /// SIGKILL to container `name`.
    fn kill(&mut self, name: &str) -> Result<(), ScenarioError> {
        let err = self.io_err(name, "SIGKILL");
        let Some(c) = self.container(name) else {
            return Err(self.failed(name, "is not running"));
        };
        c.gone = true;
        c.child
            .kill()
            .and_then(|()| c.child.wait().map(|_| ()))
            .map_err(err)
    }

    /// SIGTERM to container `name` (its clean shutdown), then waits for its `stopped` event;
    /// returns the messages its agents sent.
    fn stop(&mut self, name: &str) -> Result<Option<u64>, ScenarioError> {
        let Some(c) = self.container(name) else {
            return Ok(None);
        };
        if c.gone {
            return Ok(None);
        }
        c.gone = true;
        let pid = c.child.id().to_string();
        let err = self.io_err(name, "SIGTERM");
        let status = Command::new("kill")
            .args(["-TERM", &pid])
            .stderr(Stdio::null())
            .status()
            .map_err(err)?;
        if !status.success() {
            return Err(self.failed(name, "could not be sent SIGTERM"));
        }
        let stopped = |events: &[(String, Instant, Event)]| {
            events.iter().find_map(|(c, _, e)| match e {
                Event::Stopped { messages_sent, .. } if c == name => Some(*messages_sent),
                _ => None,
            })
        };
        self.wait_until(name, "clean stop", |events| stopped(events).is_some())?;
        Ok(stopped(&self.events))
    }
}

/// Two consecutive free loopback UDP ports (a bus and its control channel).
fn free_port_pair() -> std::io::Result<u16> {
    for _ in 0..64 {
        let a = UdpSocket::bind("127.0.0.1:0")?;
        let port = a.local_addr()?.port();
        if port < u16::MAX && UdpSocket::bind(("127.0.0.1", port + 1)).is_ok() {
            return Ok(port);
        }
    }
    Err(std::io::Error::other("no two consecutive free UDP ports"))
}

fn loopback(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// The map file the containers load: the scenario's, plus a `place` line for each goal given
/// as a point (as [`add_goal_places`] adds it in process).
fn write_map(scenario: &Scenario, map: &Map, dir: &Path) -> Result<PathBuf, ScenarioError> {
    let base = scenario.source.parent().unwrap_or(Path::new("."));
    let original = base.join(&scenario.map);
    let io = |what: &str, path: &Path| {
        let what = format!("{what} {}", path.display());
        move |source| ScenarioError::Spawn {
            path: scenario.source.display().to_string(),
            container: "-".into(),
            what,
            source,
        }
    };
    let mut text = std::fs::read_to_string(&original).map_err(io("reading", &original))?;
    let known = scenario.load_map()?.places.len();
    text.push('\n');
    for p in &map.places[known..] {
        text.push_str(&format!(
            "place {} {} {}\n",
            p.name, p.position.x, p.position.y
        ));
    }
    let path = dir.join("scenario.map");
    std::fs::write(&path, text).map_err(io("writing", &path))?;
    Ok(path)
}

/// The place of `map` a goal at `point` resolves to (within 0.5 m, the nearest).
fn place_at(map: &Map, point: nalgebra::Point2<f64>) -> Option<String> {
    map.places
        .iter()
        .filter(|p| (p.position - point).norm() <= 0.5)
        .min_by(|a, b| {
            (a.position - point)
                .norm()
                .total_cmp(&(b.position - point).norm())
        })
        .map(|p| p.name.clone())
}

/// TOML string literal.
fn quoted(text: &str) -> String {
    toml::Value::String(text.to_string()).to_string()
}

/// Plays `scenario` across processes (see the module docs).
pub fn run_processes(
    scenario: &Scenario,
    options: &ProcessOptions,
    mut progress: impl FnMut(u64, u64),
) -> Result<Report, ScenarioError> {
    let mut map = scenario.load_map()?;
    scenario.validate_for(&map, Mode::Processes)?;
    add_goal_places(scenario, &mut map);
    let schedule = schedule(scenario, &map)?;
    let io = |what: &str| {
        let what = what.to_string();
        move |source| ScenarioError::Spawn {
            path: scenario.source.display().to_string(),
            container: "-".into(),
            what,
            source,
        }
    };
    let dir = tempfile::Builder::new()
        .prefix("iw-scenario-")
        .tempdir()
        .map_err(io("temporary directory"))?;
    let (tx, lines) = std::sync::mpsc::channel();
    let mut d = Deployment {
        scenario,
        options,
        dir,
        containers: Vec::new(),
        _boards: Vec::new(),
        relay: None,
        lines,
        tx,
        events: Vec::new(),
        garbage: Vec::new(),
    };
    let map_file = write_map(scenario, &map, d.dir.path())?;
    let log = d.dir.path().join("agents.log");
    let control_key = d.dir.path().join("control.key");
    let keygen = Command::new(&options.exe)
        .args(["spawn", "--keygen-control"])
        .arg(&control_key)
        .output()
        .map_err(io("running `intellwheels spawn --keygen-control`"))?;
    if !keygen.status.success() {
        return Err(d.failed(
            "-",
            format!(
                "`spawn --keygen-control` failed: {}",
                String::from_utf8_lossy(&keygen.stderr)
            ),
        ));
    }
    let config = d.dir.path().join("deployment.toml");
    let restricted: Vec<String> = scenario
        .restricted
        .iter()
        .map(|r| {
            let chairs: Vec<String> = r.authorised.iter().map(|c| quoted(c)).collect();
            format!("{} = [{}]", quoted(&r.door), chairs.join(", "))
        })
        .collect();
    let chairs: Vec<String> = scenario.chairs.iter().map(|c| quoted(&c.name)).collect();
    std::fs::write(
        &config,
        format!(
            "[world]\nmap = {}\nseed = {}\n\n[body]\nvisual_odometry = {}\n\n[services]\nchairs = [{}]\nrestricted = {{ {} }}\nlog = {}\npose_report_ms = {BODY_REPORT_MS}\n",
            quoted(&map_file.display().to_string()),
            scenario.seed,
            scenario.visual_odometry,
            chairs.join(", "),
            restricted.join(", "),
            quoted(&log.display().to_string()),
        ),
    )
    .map_err(io("writing the deployment configuration"))?;

    // addresses: each container's own, and, with a relay, the fronts and pairs in between
    let port = |d: &Deployment| free_port_pair().map_err(d.io_err("-", "finding free ports"));
    let mut names: Vec<String> = vec![iw_fleet::SERVICES.to_string(), WORLD.to_string()];
    names.extend(scenario.chairs.iter().map(|c| c.name.clone()));
    let mut listen: BTreeMap<String, u16> = BTreeMap::new();
    for name in &names {
        listen.insert(name.clone(), port(&d)?);
    }
    let services_port = listen[iw_fleet::SERVICES];
    let relayed = scenario
        .faults
        .iter()
        .any(|f| matches!(f, Fault::LinkLoss { .. }));
    // advertised bus address, and the bus address whose next port is the services' control
    let mut advertise: BTreeMap<String, String> = BTreeMap::new();
    let mut peer: BTreeMap<String, String> = BTreeMap::new();
    if relayed {
        let mut relay = Relay::new();
        for name in &names {
            let bus = loopback(listen[name]);
            let front = relay
                .front(name, bus)
                .map_err(d.io_err(name, "relay front"))?;
            advertise.insert(name.clone(), front.to_string());
            if name != iw_fleet::SERVICES {
                let pair = port(&d)?;
                relay
                    .pair(
                        (name, loopback(listen[name] + 1)),
                        (iw_fleet::SERVICES, loopback(services_port + 1)),
                        loopback(pair + 1),
                    )
                    .map_err(d.io_err(name, "relay pair"))?;
                peer.insert(name.clone(), loopback(pair).to_string());
            }
        }
        d.relay = Some(relay);
    }
    let common = |name: &str| -> Vec<String> {
        let mut args = vec![
            "--config".into(),
            config.display().to_string(),
            "--listen".into(),
            loopback(listen[name]).to_string(),
            "--control-key".into(),
            control_key.display().to_string(),
        ];
        if let Some(a) = advertise.get(name) {
            args.extend(["--advertise".into(), a.clone()]);
        }
        if name != iw_fleet::SERVICES {
            let p = peer
                .get(name)
                .cloned()
                .unwrap_or_else(|| loopback(services_port).to_string());
            args.extend(["--peer".into(), p]);
        }
        args
    };
    let ready = |name: &str| {
        let name = name.to_string();
        move |events: &[(String, Instant, Event)]| {
            events
                .iter()
                .any(|(c, _, e)| c == &name && matches!(e, Event::Ready { .. }))
        }
    };
    let mut services_args = vec!["--services".to_string()];
    services_args.extend(common(iw_fleet::SERVICES));
    d.spawn(iw_fleet::SERVICES, &services_args)?;
    d.wait_until(iw_fleet::SERVICES, "ready event", ready(iw_fleet::SERVICES))?;
    let mut world_args = vec!["--world".to_string()];
    world_args.extend(common(WORLD));
    d.spawn(WORLD, &world_args)?;
    d.wait_until(WORLD, "ready event", ready(WORLD))?;
    for c in &scenario.chairs {
        let start = scenario
            .start_of(c, &map)
            .map_err(|reason| scenario.invalid(c.name.clone(), reason))?;
        let mut args = vec![
            "--chair".to_string(),
            c.name.clone(),
            "--start".into(),
            format!(
                "{},{},{}",
                start.translation.x,
                start.translation.y,
                start.rotation.angle().to_degrees()
            ),
        ];
        if c.body != BodyKind::Virtual {
            let board = BoardEmulator::spawn_real_time(
                WheelGeometry::default(),
                iw_fleet::compose::CONTROL_PERIOD,
                Some(BOARD_WATCHDOG),
            )
            .map_err(|source| ScenarioError::Board {
                path: d.path(),
                container: c.name.clone(),
                source,
            })?;
            let kind = if c.body == BodyKind::Mixed {
                "mixed"
            } else {
                "serial"
            };
            args.extend(["--body".into(), format!("{kind}:{}", board.port_name())]);
            d._boards.push(board);
        }
        args.extend(common(&c.name));
        d.spawn(&c.name, &args)?;
    }
    for name in names.clone() {
        d.wait_until(&name, "ready event", ready(&name))?;
        let agents = d.events.iter().find_map(|(c, _, e)| match e {
            Event::Ready { agents, .. } if c == &name => Some(agents.clone()),
            _ => None,
        });
        if let (Some(agents), Some(c)) = (agents, d.container(&name)) {
            c.agents = agents;
        }
    }
    // every container's agents are in the services' list, and each chair publishes its pose
    // and has its body in the world
    let expected: BTreeSet<String> = d
        .containers
        .iter()
        .filter(|c| c.name != iw_fleet::SERVICES)
        .flat_map(|c| c.agents.clone())
        .collect();
    let chair_names: Vec<String> = scenario.chairs.iter().map(|c| c.name.clone()).collect();
    d.wait_until(iw_fleet::SERVICES, "join of every container", |events| {
        let joined: BTreeSet<&String> = events
            .iter()
            .filter_map(|(c, _, e)| match e {
                Event::Joined { agent, .. } if c == iw_fleet::SERVICES => Some(agent),
                _ => None,
            })
            .collect();
        expected.iter().all(|a| joined.contains(a))
            && chair_names.iter().all(|chair| {
                events.iter().any(|(c, _, e)| {
                    matches!(e, Event::Pose { chair: p, .. } if p == chair)
                        && c == iw_fleet::SERVICES
                }) && events.iter().any(|(c, _, e)| {
                    matches!(e, Event::Body { chair: b, .. } if b == chair) && c == WORLD
                })
            })
    })?;

    // the run, in real time from here
    let t0 = Instant::now();
    let since = |at: Instant| at.saturating_duration_since(t0).as_secs_f64();
    let mut timeline = Vec::new();
    let mut seen = Vec::new();
    let first_event = d.events.len();
    let duration = Duration::from_secs_f64(scenario.duration_s);
    let steps = (scenario.duration_s * 1000.0 / scenario.step.as_millis() as f64).ceil() as u64;
    let mut next = 0;
    loop {
        let now_s = t0.elapsed().as_secs_f64();
        while let Some((at_s, action)) = schedule.get(next) {
            if *at_s > now_s {
                break;
            }
            next += 1;
            let line = match action {
                Cue::Goal(g, point) => {
                    seen.push(Observation::GoalGiven {
                        time_s: now_s,
                        chair: g.chair.clone(),
                        target: [point.x, point.y],
                    });
                    let place = g.place.clone().or_else(|| place_at(&map, *point));
                    let Some(place) = place else {
                        return Err(scenario.invalid(g.chair.clone(), "goal is not a place"));
                    };
                    d.admin(
                        iw_fleet::SERVICES,
                        &serde_json::json!({ "admin": "goal", "chair": g.chair, "place": place }),
                    )?;
                    format!(
                        "goal {} -> {place} ({:.2}, {:.2})",
                        g.chair, point.x, point.y
                    )
                }
                Cue::Fault(f) => {
                    match f {
                        Fault::LinkLoss { container, .. } => {
                            if let Some(relay) = &d.relay {
                                relay.set_link(container, false);
                            }
                        }
                        Fault::KillAgent {
                            container, agent, ..
                        } => d.admin(
                            container,
                            &serde_json::json!({ "admin": "kill-agent", "agent": agent }),
                        )?,
                        Fault::KillContainer { container, .. } => d.kill(container)?,
                        Fault::LaserBlind { chair, .. } => d.blind_laser(chair, true)?,
                        Fault::SensorFailure { chair, sensor, .. }
                            if *sensor != FailedSensor::All =>
                        {
                            d.fail_sensor(chair, *sensor, true)?
                        }
                        Fault::SensorFailure { .. } | Fault::JammedDoor { .. } => {
                            return Err(
                                scenario.invalid("fault", "cannot be played across processes")
                            );
                        }
                    }
                    format!("fault {}", serde_json::to_string(f).unwrap_or_default())
                }
                Cue::LinkUp(container) => {
                    if let Some(relay) = &d.relay {
                        relay.set_link(container, true);
                    }
                    format!("link {container} restored")
                }
                Cue::LaserBack(chair) => {
                    d.blind_laser(chair, false)?;
                    format!("laser of {chair} back")
                }
                Cue::SensorsBack(chair, sensor) => {
                    d.fail_sensor(chair, *sensor, false)?;
                    format!("sensor {sensor} of {chair} restored")
                }
                Cue::Door(_) => {
                    return Err(scenario.invalid("door", "cannot be played across processes"));
                }
            };
            timeline.push(format!("{now_s:7.2} s: {line}"));
        }
        let elapsed = t0.elapsed();
        progress(
            (elapsed.as_millis() / scenario.step.as_millis().max(1)) as u64,
            steps,
        );
        if elapsed >= duration {
            break;
        }
        let until_action = schedule
            .get(next)
            .map(|(at_s, _)| Duration::from_secs_f64(at_s.max(0.0)).saturating_sub(elapsed));
        let wait = until_action
            .unwrap_or(Duration::MAX)
            .min(duration - elapsed)
            .min(Duration::from_millis(50));
        d.pump(wait)?;
    }
    let simulated_s = t0.elapsed().as_secs_f64();
    progress(steps, steps);

    // the chairs stop first, then the world, then the services (whose logger takes the others'
    // last messages)
    let mut sent = 0;
    for name in chair_names
        .iter()
        .map(String::as_str)
        .chain([WORLD, iw_fleet::SERVICES])
    {
        sent += d.stop(name)?.unwrap_or(0);
    }
    let records =
        iw_logger::read_records(&log, iw_logger::DEFAULT_MAX_RECORD_LEN).map_err(|source| {
            ScenarioError::Log {
                path: d.path(),
                source,
            }
        })?;
    let logged: Vec<iw_logger::LoggedMessage> = records
        .iter()
        .filter_map(|r| iw_logger::LoggedMessage::from_record(r).ok())
        .collect();

    // the containers' events, typed, in run time
    let mut last_body: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    for (container, at, event) in &d.events[first_event..] {
        let time_s = since(*at);
        match event {
            Event::Body {
                chair,
                x_m,
                y_m,
                theta_rad,
                distance_m,
                collisions,
                ..
            } => {
                let speed_mps = match last_body.get(chair) {
                    Some((t, dist)) if time_s > *t => (distance_m - dist).abs() / (time_s - t),
                    _ => 0.0,
                };
                last_body.insert(chair.clone(), (time_s, *distance_m));
                seen.push(Observation::Body {
                    time_s,
                    chair: chair.clone(),
                    pose: [*x_m, *y_m, *theta_rad],
                    speed_mps,
                    distance_m: *distance_m,
                    collisions: *collisions,
                });
            }
            Event::Goal {
                chair,
                conversation,
                performative,
                reason,
                ..
            } => {
                timeline.push(format!(
                    "{time_s:7.2} s: {performative} about {chair}'s goal [{conversation}]{}",
                    reason
                        .as_ref()
                        .map(|r| format!(": {r}"))
                        .unwrap_or_default()
                ));
                if let Ok(performative) = performative.parse::<Performative>() {
                    seen.push(Observation::Answer {
                        time_s,
                        chair: chair.clone(),
                        performative,
                    });
                }
            }
            Event::Admin { done, error, .. } => timeline.push(format!(
                "{time_s:7.2} s: {container}: {done}{}",
                error
                    .as_ref()
                    .map(|e| format!(" refused: {e}"))
                    .unwrap_or_default()
            )),
            Event::Left { agent, .. } if container == iw_fleet::SERVICES => {
                timeline.push(format!("{time_s:7.2} s: {agent} left"));
            }
            _ => {}
        }
    }
    // the goal answers and body reports arrive from different processes: order them in time
    // (a stable sort keeps each process's order)
    seen.sort_by(|a, b| time_of(a).total_cmp(&time_of(b)));
    // by time only (stable: a command before its acknowledgement)
    let time_in = |line: &String| {
        line.split(" s:")
            .next()
            .and_then(|t| t.trim().parse::<f64>().ok())
            .unwrap_or(f64::INFINITY)
    };
    timeline.sort_by(|a, b| time_in(a).total_cmp(&time_in(b)));
    timeline.extend(d.garbage.iter().map(|g| format!("unreadable event: {g}")));

    let container_of = |agent: &str| agent.rsplit_once('@').map(|(_, c)| c.to_string());
    let between = logged
        .iter()
        .filter(|m| {
            m.receivers
                .iter()
                .any(|r| container_of(r) != container_of(&m.sender))
        })
        .count() as u64;
    let dropped = d.relay.as_ref().map_or(0, |r| r.counts().bus_dropped);
    let totals = Totals {
        messages: between + dropped,
        dropped,
        sent,
        logged: logged.len() as u64,
    };
    let trace: Vec<String> = logged
        .iter()
        .map(|m| format!("{} -> {}: {}", m.sender, m.receivers.join(" "), m.acl))
        .collect();
    seen.extend(
        logged
            .iter()
            .filter_map(|m| iw_acl::codec::parse(&m.acl).ok())
            .map(|m| Observation::Message(Box::new(m))),
    );
    let chairs: Vec<ChairSummary> = scenario
        .chairs
        .iter()
        .map(|c| {
            let last = seen.iter().rev().find_map(|o| match o {
                Observation::Body {
                    chair,
                    pose,
                    distance_m,
                    collisions,
                    ..
                } if chair == &c.name => Some((*pose, *distance_m, *collisions)),
                _ => None,
            });
            let (pose, distance_m, collisions) = last.unwrap_or_default();
            let killed: BTreeSet<String> = d
                .events
                .iter()
                .filter_map(|(container, _, e)| match e {
                    Event::Admin {
                        done, error: None, ..
                    } if container == &c.name => done.strip_prefix("kill-agent ").map(String::from),
                    _ => None,
                })
                .collect();
            let killed_outright = scenario.faults.iter().any(
                |f| matches!(f, Fault::KillContainer { container, .. } if container == &c.name),
            );
            let agents = d
                .containers
                .iter()
                .find(|k| k.name == c.name)
                .map(|k| {
                    k.agents
                        .iter()
                        .filter(|a| !killed.contains(*a) && !killed_outright)
                        .cloned()
                        .collect()
                })
                .unwrap_or_default();
            ChairSummary {
                name: c.name.clone(),
                pose,
                distance_m,
                collisions,
                agents,
            }
        })
        .collect();
    let outcomes = check(scenario, &seen, &totals, &chairs);
    Ok(Report {
        name: scenario.name.clone(),
        mode: Mode::Processes,
        seed: scenario.seed,
        simulated_s,
        passed: outcomes.iter().all(|o| o.passed),
        outcomes,
        chairs,
        timeline,
        messages: totals.messages,
        dropped,
        sent,
        logged: totals.logged,
        trace,
    })
}

fn time_of(o: &Observation) -> f64 {
    match o {
        Observation::Body { time_s, .. }
        | Observation::GoalGiven { time_s, .. }
        | Observation::NoPath { time_s, .. }
        | Observation::Answer { time_s, .. } => *time_s,
        Observation::Message(_) => f64::INFINITY,
    }
}
