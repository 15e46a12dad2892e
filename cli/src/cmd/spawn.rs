//! `intellwheels spawn`: one container process (a chair's micro agents, or the services) over a
//! real transport, until Ctrl-C or SIGTERM. Reports one JSON event per line on stdout.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Context;
use iw_node::{BodyKind, GoalSpec, NodeError, Role, Runtime, SpawnConfig, TransportKind};

/// Flags; each overrides the configuration file's key of the same meaning.
#[derive(clap::Args)]
#[command(group = clap::ArgGroup::new("role").required(true).args(["chair", "services", "world", "keygen", "keygen_control", "keygen_roster"]))]
pub struct Args {
    /// Run chair NAME's perception, control, cognitive and interface agents.
    #[arg(long, value_name = "NAME")]
    chair: Option<String>,
    /// Run the service agents (AMS, DF, door, logger, watcher, assistant, staff console).
    #[arg(long)]
    services: bool,
    /// Run the world: the simulator owning the deployment's shared world (virtual bodies, doors).
    #[arg(long)]
    world: bool,
    /// Write a new identity key (PKCS#8, mode 0600) to FILE and exit.
    #[arg(long, value_name = "FILE")]
    keygen: Option<PathBuf>,
    /// Write a new control group key (64 hex digits, mode 0600) to FILE and exit; every
    /// container of a deployment is given the same file (--control-key).
    #[arg(long, value_name = "FILE")]
    keygen_control: Option<PathBuf>,
    /// Write the deployment's roster to FILE and exit: each --member's identity key is
    /// `NAME.pk8` beside FILE (written, mode 0600, if absent; an existing one is kept), and FILE
    /// pins each member's id to its key (security.roster). Rewrites FILE.
    #[arg(long, value_name = "FILE", requires = "members")]
    keygen_roster: Option<PathBuf>,
    /// A container of the roster --keygen-roster writes: `NAME` (its id derived as spawn
    /// derives it: services 1, world 2, a chair from its name) or `NAME=ID`; repeat.
    #[arg(long = "member", value_name = "NAME[=ID]", requires = "keygen_roster")]
    members: Vec<String>,
    /// The configuration file (keys documented in deploy/default.toml).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// The body: `virtual`, `serial:PATH` or `mixed:PATH` (body.kind, body.port).
    #[arg(long, value_name = "BODY")]
    body: Option<String>,
    /// `udp`, `tcp` or `iceoryx2` (transport.kind).
    #[arg(long, value_name = "KIND")]
    transport: Option<String>,
    /// Bus address: `host:port` or an iceoryx2 inbox name (transport.listen).
    #[arg(long, value_name = "ADDR")]
    listen: Option<String>,
    /// Address the others reach this bus at (transport.advertise).
    #[arg(long, value_name = "ADDR")]
    advertise: Option<String>,
    /// Another container's bus address to greet; repeat for several (transport.peers).
    #[arg(long = "peer", value_name = "ADDR")]
    peers: Vec<String>,
    /// The identity key file (security.identity_key).
    #[arg(long, value_name = "FILE")]
    key: Option<String>,
    /// The control group key file (security.control_key); required unless --insecure-dev.
    #[arg(long, value_name = "FILE")]
    control_key: Option<String>,
    /// The deployment's roster of container identities (security.roster): control frames then
    /// speak for an id only under its pinned key.
    #[arg(long, value_name = "FILE")]
    roster: Option<String>,
    /// Run without a control key: control traffic unauthenticated, for development only
    /// (security.insecure_dev).
    #[arg(long)]
    insecure_dev: bool,
    /// For tests: the world steps in lockstep with its virtual bodies, one fixed 50 ms step once
    /// every body has sent its wheel speeds (world.lockstep); give it to the world and the
    /// chairs alike.
    #[arg(long)]
    lockstep: bool,
    /// Start pose `X,Y,HEADING_DEG` in the map frame (body.start).
    #[arg(long, value_name = "X,Y,DEG")]
    start: Option<String>,
    /// A goal `CHAIR:PLACE` (a place of the map or `x,y` in metres) the services give when the
    /// chair joins; repeatable (services.goals).
    #[arg(long = "goal", value_name = "CHAIR:PLACE")]
    goals: Vec<String>,
    /// Take admin commands (JSON lines: a goal, a killed agent, a blinded laser, a failed
    /// sensor) on stdin from the parent process, and stop when stdin closes (the parent is
    /// gone). The scenario runner's `--processes` mode drives its containers this way.
    #[arg(long)]
    admin_stdin: bool,
}

fn flag_err(flag: &'static str, value: &str, reason: &str) -> NodeError {
    NodeError::Flag {
        flag,
        value: value.into(),
        reason: reason.into(),
    }
}

fn apply(args: &Args, config: &mut SpawnConfig) -> Result<(), NodeError> {
    if let Some(body) = &args.body {
        let (kind, port) = match body.split_once(':') {
            None if body == "virtual" => (BodyKind::Virtual, ""),
            Some(("serial", port)) if !port.is_empty() => (BodyKind::Real, port),
            Some(("mixed", port)) if !port.is_empty() => (BodyKind::Mixed, port),
            _ => {
                return Err(flag_err(
                    "--body",
                    body,
                    "expected `virtual`, `serial:PATH` or `mixed:PATH`",
                ));
            }
        };
        config.body.kind = kind;
        config.body.port = port.to_string();
    }
    if let Some(kind) = &args.transport {
        config.transport.kind = kind.parse::<TransportKind>()?;
    }
    if let Some(listen) = &args.listen {
        config.transport.listen = listen.clone();
    }
    if let Some(advertise) = &args.advertise {
        config.transport.advertise = advertise.clone();
    }
    if !args.peers.is_empty() {
        config.transport.peers = args.peers.clone();
    }
    if let Some(key) = &args.key {
        config.security.identity_key = key.clone();
    }
    if let Some(key) = &args.control_key {
        config.security.control_key = key.clone();
    }
    if let Some(roster) = &args.roster {
        config.security.roster = roster.clone();
    }
    if args.insecure_dev {
        config.security.insecure_dev = true;
    }
    if args.lockstep {
        config.world.lockstep = true;
    }
    if let Some(start) = &args.start {
        if args.chair.is_none() {
            return Err(flag_err(
                "--start",
                start,
                "only a chair has a start pose (give it with --chair NAME)",
            ));
        }
        let values: Vec<f64> = start
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| flag_err("--start", start, &e.to_string()))?;
        let pose = <[f64; 3]>::try_from(values)
            .map_err(|_| flag_err("--start", start, "expected three numbers X,Y,HEADING_DEG"))?;
        if !pose.iter().all(|v| v.is_finite()) {
            return Err(flag_err("--start", start, "every number must be finite"));
        }
        config.body.start = pose;
    }
    for goal in &args.goals {
        let (chair, place) = goal
            .split_once(':')
            .filter(|(c, p)| !c.is_empty() && !p.is_empty())
            .ok_or_else(|| flag_err("--goal", goal, "expected CHAIR:PLACE"))?;
        config.services.goals.push(GoalSpec {
            chair: chair.into(),
            place: place.into(),
        });
    }
    Ok(())
}

/// Reads admin commands from stdin until it closes, then asks the container to stop. A line
/// that is too long or not a command is passed on as refused (the container reports it in an
/// `admin` event); nothing on it panics.
fn read_admin(
    commands: &std::sync::mpsc::Sender<Result<iw_node::AdminCommand, String>>,
    stop: &AtomicBool,
) {
    use std::io::{BufRead, Read};
    let refuse = |line: &[u8], error: String| {
        let shown = String::from_utf8_lossy(&line[..line.len().min(80)]).into_owned();
        commands
            .send(Err(format!("`{}`: {error}", shown.trim_end())))
            .is_ok()
    };
    let mut stdin = std::io::stdin().lock();
    let mut line = Vec::new();
    loop {
        line.clear();
        // at most one byte past the cap, so an endless line cannot fill the memory
        let read = stdin
            .by_ref()
            .take(iw_node::MAX_ADMIN_LINE as u64 + 1)
            .read_until(b'\n', &mut line);
        match read {
            Ok(0) | Err(_) => break,
            Ok(_) if line.last() != Some(&b'\n') && line.len() > iw_node::MAX_ADMIN_LINE => {
                if !refuse(
                    &line,
                    format!("longer than {} bytes", iw_node::MAX_ADMIN_LINE),
                ) {
                    break;
                }
                // skip the rest of the line, a bounded piece at a time
                loop {
                    line.clear();
                    match stdin
                        .by_ref()
                        .take(iw_node::MAX_ADMIN_LINE as u64)
                        .read_until(b'\n', &mut line)
                    {
                        Ok(0) | Err(_) => return stop_on_close(stop),
                        Ok(_) if line.last() == Some(&b'\n') => break,
                        Ok(_) => {}
                    }
                }
            }
            Ok(_) => match serde_json::from_slice::<iw_node::AdminCommand>(line.trim_ascii()) {
                Ok(command) => {
                    if commands.send(Ok(command)).is_err() {
                        break;
                    }
                }
                Err(e) => {
                    if !refuse(&line, format!("not an admin command: {e}")) {
                        break;
                    }
                }
            },
        }
    }
    stop_on_close(stop);
}

/// The parent closed the pipe (or is gone): the container does not outlive it.
fn stop_on_close(stop: &AtomicBool) {
    stop.store(true, std::sync::atomic::Ordering::Release);
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if let Some(path) = &args.keygen {
        let public = iw_node::write_identity(path)?;
        println!(
            "{}",
            serde_json::json!({ "event": "key", "path": path.display().to_string(), "public_key": hex::encode(public) })
        );
        return Ok(ExitCode::SUCCESS);
    }
    if let Some(path) = &args.keygen_control {
        iw_stack::write_group_key(path)?;
        println!(
            "{}",
            serde_json::json!({ "event": "control-key", "path": path.display().to_string() })
        );
        return Ok(ExitCode::SUCCESS);
    }
    if let Some(path) = &args.keygen_roster {
        let mut members = Vec::new();
        for member in &args.members {
            let (name, id) = match member.split_once('=') {
                None => (member.as_str(), 0),
                Some((name, id)) => (
                    name,
                    id.parse::<u64>().ok().filter(|id| *id > 0).ok_or_else(|| {
                        flag_err(
                            "--member",
                            member,
                            "expected NAME or NAME=ID, ID a positive integer",
                        )
                    })?,
                ),
            };
            members.push((name.to_string(), id));
        }
        let dir = match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir,
            _ => std::path::Path::new("."),
        };
        let roster = iw_node::write_roster(path, dir, &members)?;
        let pinned: Vec<_> = roster
            .pins()
            .map(|(id, pin)| serde_json::json!({ "id": id.0, "name": pin.name }))
            .collect();
        println!(
            "{}",
            serde_json::json!({ "event": "roster", "path": path.display().to_string(), "containers": pinned })
        );
        return Ok(ExitCode::SUCCESS);
    }
    let role = match &args.chair {
        Some(name) if name.is_empty() || name == iw_node::SERVICES || name.contains('@') => {
            return Err(flag_err(
                "--chair",
                name,
                "a chair name is not empty, not `services` and has no `@`",
            )
            .into());
        }
        Some(name) => Role::Chair { name: name.clone() },
        None if args.world => Role::World,
        None => Role::Services,
    };
    let mut config = match &args.config {
        Some(path) => SpawnConfig::load(path)?,
        None => SpawnConfig::default(),
    };
    apply(&args, &mut config)?;

    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        signal_hook::flag::register(signal, stop.clone())
            .context("installing the signal handlers")?;
    }
    let (events, reports) = std::sync::mpsc::channel();
    let mut runtime =
        Runtime::start(&role, config, events).with_context(|| match &args.config {
            // a key the configuration got wrong is named in the error; this names its file
            Some(path) => format!(
                "starting container `{}` (configuration {})",
                role.name(),
                path.display()
            ),
            None => format!("starting container `{}`", role.name()),
        })?;
    if args.admin_stdin {
        let (commands, admin) = std::sync::mpsc::channel();
        runtime = runtime.with_admin(admin);
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("iw-admin".into())
            .spawn(move || read_admin(&commands, &stop))
            .context("starting the admin reader")?;
    }
    let worker = {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("iw-node".into())
            .spawn(move || runtime.run(&stop))
            .context("starting the container thread")?
    };
    // Reports until the runtime (and every agent holding a sender) is gone.
    let mut out = std::io::stdout().lock();
    for event in reports {
        serde_json::to_writer(&mut out, &event)?;
        writeln!(out)?;
        out.flush()?;
    }
    worker
        .join()
        .map_err(|_| anyhow::anyhow!("the container thread panicked"))??;
    Ok(ExitCode::SUCCESS)
}
