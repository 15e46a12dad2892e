//! `intellwheels` (no subcommand) and `intellwheels demo`: the mixed-reality demo with no setup.
//!
//! The embedded sample building, the service container, three virtual chairs and one mixed chair
//! (the serial driver on a pty against the emulated interface board, virtual sonars merged in),
//! each in its own container, talking FIPA-ACL over real bus frames in simulated time. Staff send
//! the goals through the assistant; one chair is sent to the staff office behind a restricted door
//! it is not authorised through, so the door agent refuses and logs it. The missions are laid out
//! so no two chairs meet head-on in the corridor: chairs do not yet yield to each other there.
//! The dashboard runs throughout (its URL is printed); page actions go to the fleet as goals, door
//! and fault asks.
//! Runs faster than real time, or in real time and until Ctrl-C with `--serve`. Ends with a
//! summary and a JSON-lines log of every frame exchanged between containers.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use iw_dashboard::{Dashboard, DashboardConfig, PageAction};
/// Where the drive bench hands its inputs too.
pub(crate) use iw_fleet::dashboard::push_drive;
use iw_fleet::{BodyKind, ChairConfig, Fleet, FleetOptions, dashboard};
use iw_sim::Map;
use iw_wiring::view::map_view;
use nalgebra::{Isometry2, Vector2};

/// The sample care building shipped with the sources (`scenarios/maps/sample-building.map`).
pub(crate) const SAMPLE_BUILDING: &str =
    include_str!("../../../scenarios/maps/sample-building.map");

/// The restricted door: only [`AUTHORISED`] may have it opened.
const RESTRICTED_DOOR: &str = "office";
/// The chair allowed through [`RESTRICTED_DOOR`].
const AUTHORISED: &str = "chair-0";

/// Flags of `intellwheels demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Seed of the simulator's sensor and encoder noise.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Longest simulated time before the demo ends, s.
    #[arg(long, default_value = "90", value_parser = super::flags::seconds)]
    max_time_s: std::time::Duration,
    /// Simulation step, ms.
    #[arg(long, default_value_t = 50)]
    step_ms: u64,
    /// Where to write the message log (default: a fresh folder in the temporary directory).
    #[arg(long)]
    log_dir: Option<PathBuf>,
    /// Keep running in real time for the browser until Ctrl-C (or SIGTERM).
    #[arg(long)]
    serve: bool,
    /// Where the dashboard listens (any address but loopback needs --token).
    #[arg(long, default_value = "127.0.0.1:0")]
    bind: SocketAddr,
    /// The dashboard's access token (required for a non-loopback --bind).
    #[arg(long)]
    token: Option<String>,
}

/// One chair of the demo: where it starts, its body, the named place staff send it to and when.
struct Mission {
    name: &'static str,
    start: (f64, f64, f64),
    body: BodyKind,
    place: &'static str,
    /// Simulated time at which the goal is sent, s.
    at_s: f64,
}

/// Staged so that no chair waits at a door or stands refused in the corridor while another
/// needs to pass: chair-0 crosses the building first, chair-2 is refused behind it, chair-1
/// leaves its bedroom once chair-0 has turned into the dining hall.
const MISSIONS: [Mission; 4] = [
    Mission {
        name: "chair-0",
        start: (1.0, 6.0, 0.0),
        body: BodyKind::Virtual,
        place: "dining-hall",
        at_s: 0.0,
    },
    Mission {
        name: "chair-1",
        start: (7.5, 8.5, -90.0),
        body: BodyKind::Virtual,
        place: "bathroom",
        at_s: 25.0,
    },
    Mission {
        name: "chair-2",
        start: (2.5, 8.5, -90.0),
        body: BodyKind::Virtual,
        place: "office",
        at_s: 12.0,
    },
    Mission {
        name: "chair-3",
        start: (17.5, 6.0, 180.0),
        body: BodyKind::Mixed,
        place: "therapy",
        at_s: 0.0,
    },
];

/// What became of one chair's goal.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
enum Outcome {
    /// The goal was sent; no final answer yet.
    Pending,
    /// The control agent informed it was done.
    Reached { time_s: f64 },
    /// The chair's agents (or the platform) answered failure or refuse, and why.
    Failed {
        performative: String,
        reason: Option<String>,
    },
    /// It could not be sent: the way is shut (the door refused to open).
    Refused { reason: String },
}

#[derive(serde::Serialize)]
struct ChairReport {
    name: String,
    goal: String,
    outcome: Outcome,
    collisions: u64,
    distance_m: f64,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        args.step_ms > 0 && args.step_ms <= 1000,
        "--step-ms must be in 1..=1000, got {}",
        args.step_ms
    );
    let map =
        Map::parse(SAMPLE_BUILDING, "sample-building.map").context("embedded sample building")?;
    let map_view = map_view(&map);
    let chairs: Vec<ChairConfig> = MISSIONS
        .iter()
        .map(|m| ChairConfig {
            name: m.name.to_string(),
            t_world_body: Isometry2::new(
                Vector2::new(m.start.0, m.start.1),
                m.start.2.to_radians(),
            ),
        })
        .collect();
    let log_dir = match args.log_dir {
        Some(dir) => dir,
        None => std::env::temp_dir().join(format!("intellwheels-demo-{}", std::process::id())),
    };
    std::fs::create_dir_all(&log_dir).with_context(|| format!("creating {}", log_dir.display()))?;
    let options = FleetOptions {
        bodies: MISSIONS
            .iter()
            .filter(|m| m.body != BodyKind::Virtual)
            .map(|m| (m.name.to_string(), m.body))
            .collect(),
        restricted: BTreeMap::from([(
            RESTRICTED_DOOR.to_string(),
            BTreeSet::from([AUTHORISED.to_string()]),
        )]),
        log_path: Some(log_dir.join("agents.log")),
        visual_odometry: true,
        ..FleetOptions::default()
    };
    let mut fleet =
        Fleet::with_options(map, args.seed, &chairs, options).context("composing the fleet")?;
    let dashboard = Dashboard::start(
        DashboardConfig {
            bind: args.bind,
            token: args.token.clone(),
        },
        &map_view,
    )
    .context("starting the dashboard")?;
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, stop.clone())
            .context("installing the signal handler")?;
    }

    let virtual_count = MISSIONS
        .iter()
        .filter(|m| m.body == BodyKind::Virtual)
        .count();
    println!(
        "IntellWheels demo: sample care building, {virtual_count} virtual chairs + {} mixed, services container; door `{RESTRICTED_DOOR}` restricted to {AUTHORISED}",
        MISSIONS.len() - virtual_count
    );
    println!("dashboard: {}", dashboard.url());
    let mut outcomes = vec![Outcome::Pending; MISSIONS.len()];
    let mut conversations: Vec<Option<String>> = vec![None; MISSIONS.len()];
    let mut sent = [false; MISSIONS.len()];
    let mut goal_places: BTreeMap<String, String> = BTreeMap::new();

    let step = Duration::from_millis(args.step_ms);
    let total_steps = (args.max_time_s.as_secs_f64() * 1000.0 / args.step_ms as f64).ceil() as u64;
    let bar = ProgressBar::new(total_steps);
    bar.set_style(
        ProgressStyle::with_template("{spinner} sim {msg} [{bar:30}] {percent}% ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    if args.serve {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let mut notices = VecDeque::new();
    let mut paused = false;
    let mut steps = 0u64;
    let mut last_publish: Option<Instant> = None;
    let started = Instant::now();
    while !stop.load(Ordering::Acquire) {
        let mut single_step = false;
        while let Some(action) = dashboard.try_action() {
            match dashboard::apply(&mut fleet, &action, &mut goal_places) {
                Ok(Some(text)) => push_notice(&mut notices, text),
                Ok(None) => {}
                Err(err) => push_notice(&mut notices, format!("{action:?}: {err}")),
            }
            match action {
                PageAction::Pause { paused: p } => paused = p,
                PageAction::Step => single_step = true,
                _ => {}
            }
        }
        let mission_over =
            steps >= total_steps || outcomes.iter().all(|o| !matches!(o, Outcome::Pending));
        if mission_over && !args.serve {
            break;
        }
        for (k, mission) in MISSIONS.iter().enumerate() {
            if sent[k] || fleet.time_s() < mission.at_s {
                continue;
            }
            sent[k] = true;
            let line = match fleet.goal_place(mission.name, mission.place) {
                Ok(conversation) => {
                    goal_places.insert(mission.name.to_string(), mission.place.to_string());
                    let line = format!(
                        "{} ({}) -> {}: request {conversation} via the assistant",
                        mission.name,
                        dashboard::body_kind_name(mission.body),
                        mission.place
                    );
                    conversations[k] = Some(conversation);
                    line
                }
                Err(err) => {
                    outcomes[k] = Outcome::Refused {
                        reason: err.to_string(),
                    };
                    format!("{} -> {}: refused ({err})", mission.name, mission.place)
                }
            };
            bar.suspend(|| println!("  {:5.1} s  {line}", fleet.time_s()));
        }
        if !paused || single_step {
            fleet.step(step);
            steps += 1;
            bar.inc(1);
            settle_outcomes(&fleet, &conversations, &mut outcomes);
            let done = outcomes
                .iter()
                .filter(|o| !matches!(o, Outcome::Pending))
                .count();
            bar.set_message(format!(
                "{:5.1} s, {done}/{} goals settled",
                fleet.time_s(),
                outcomes.len()
            ));
        }
        if last_publish.is_none_or(|t| t.elapsed() >= Duration::from_millis(100)) {
            let refusals: Vec<String> = fleet
                .door_refusals()
                .iter()
                .map(|r| format!("door {} refused {}: {}", r.door, r.requester, r.reason))
                .collect();
            let mut shown: Vec<String> = refusals;
            shown.extend(notices.iter().cloned());
            dashboard
                .publish(&dashboard::state(&fleet, paused, &goal_places, shown))
                .context("publishing the dashboard state")?;
            last_publish = Some(Instant::now());
        }
        if args.serve {
            // real time: step k is due at k * step of wall time
            let due = started + step * u32::try_from(steps).unwrap_or(u32::MAX);
            std::thread::sleep(
                due.saturating_duration_since(Instant::now())
                    .max(Duration::from_millis(1)),
            );
        }
    }
    bar.finish_and_clear();
    fleet.quiesce(50);

    let exchanges = fleet.exchanges();
    let traffic_path = log_dir.join("traffic.jsonl");
    write_log(&traffic_path, &exchanges)?;
    let snapshot = fleet.snapshot();
    let reports: Vec<ChairReport> = MISSIONS
        .iter()
        .zip(&outcomes)
        .map(|(m, o)| {
            let chair = snapshot.chairs.iter().find(|c| c.name == m.name);
            ChairReport {
                name: m.name.to_string(),
                goal: m.place.to_string(),
                outcome: o.clone(),
                collisions: chair.map_or(0, |c| c.collisions),
                distance_m: chair.map_or(0.0, |c| c.distance_m),
            }
        })
        .collect();
    let refusals = fleet.door_refusals();
    let sent = fleet.messages_sent();
    let logged = fleet
        .messages_logged()
        .context("reading the logger agent's log")?;
    let summary_path = log_dir.join("summary.json");
    let summary = serde_json::json!({
        "time_s": snapshot.time_s,
        "chairs": reports,
        "messages": exchanges.len(),
        "dropped": exchanges.iter().filter(|e| e.dropped).count(),
        "messages_sent": sent,
        "messages_logged": logged,
        "door_refusals": refusals.iter().map(|r| serde_json::json!({"door": r.door, "requester": r.requester, "reason": r.reason})).collect::<Vec<_>>(),
        "doors": snapshot.doors,
    });
    write_synced(
        &summary_path,
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;

    let reached = reports
        .iter()
        .filter(|r| matches!(r.outcome, Outcome::Reached { .. }))
        .count();
    let collisions: u64 = reports.iter().map(|r| r.collisions).sum();
    println!(
        "Summary after {:.1} s simulated ({:.1} s wall):",
        snapshot.time_s,
        started.elapsed().as_secs_f64()
    );
    for r in &reports {
        let outcome = match &r.outcome {
            Outcome::Pending => "not reached in time".to_string(),
            Outcome::Reached { time_s } => format!("reached at {time_s:.1} s"),
            Outcome::Failed {
                performative,
                reason,
            } => match reason {
                Some(reason) => format!("{performative}: {reason}"),
                None => format!("{performative} (no reason given)"),
            },
            Outcome::Refused { reason } => format!("refused: {reason}"),
        };
        println!(
            "  {:8} {:12} {outcome}; {:.1} m driven, {} collisions",
            r.name, r.goal, r.distance_m, r.collisions
        );
    }
    for r in &refusals {
        println!("  door {} refused {}: {}", r.door, r.requester, r.reason);
    }
    println!("  goals reached: {reached}/{}", reports.len());
    println!("  collisions:    {collisions}");
    println!(
        "  messages:      {sent} sent, {logged} logged by the logger agent; {} frames between containers ({} dropped)",
        exchanges.len(),
        summary["dropped"]
    );
    println!(
        "  agents' log:   {} (the logger agent's store: `intellwheels log query` / `log replay` read it)",
        fleet.log_path().display()
    );
    println!(
        "  traffic:       {} (frames between containers as JSON lines, a capture for tools)",
        traffic_path.display()
    );
    println!("  summary:       {}", summary_path.display());
    Ok(ExitCode::SUCCESS)
}

fn push_notice(notices: &mut VecDeque<String>, text: String) {
    notices.push_back(text);
    while notices.len() > 20 {
        notices.pop_front();
    }
}

/// Records the final answer (done, failure, refuse) of each pending goal.
fn settle_outcomes(fleet: &Fleet, conversations: &[Option<String>], outcomes: &mut [Outcome]) {
    let events = fleet.goal_events();
    for (conversation, outcome) in conversations.iter().zip(outcomes.iter_mut()) {
        let (Some(conversation), Outcome::Pending) = (conversation, &*outcome) else {
            continue;
        };
        for event in events.iter().filter(|e| &e.conversation == conversation) {
            let p = event.performative.to_ascii_lowercase();
            if p == "inform" {
                *outcome = Outcome::Reached {
                    time_s: event.time_s,
                };
            } else if p == "failure" || p == "refuse" || p == "not-understood" {
                *outcome = Outcome::Failed {
                    performative: p,
                    reason: event.reason.clone(),
                };
            }
        }
    }
}

fn write_log(path: &std::path::Path, exchanges: &[iw_fleet::Exchange]) -> anyhow::Result<()> {
    let mut text = Vec::new();
    for exchange in exchanges {
        serde_json::to_writer(&mut text, exchange)?;
        text.push(b'\n');
    }
    write_synced(path, &text)
}

/// Writes `bytes` to `path` and fsyncs it, so the log outlives a crash right after the demo.
fn write_synced(path: &std::path::Path, bytes: &[u8]) -> anyhow::Result<()> {
    let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut writer = BufWriter::new(file);
    writer
        .write_all(bytes)
        .with_context(|| format!("writing {}", path.display()))?;
    let file = writer
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", path.display()))?;
    file.sync_all()
        .with_context(|| format!("syncing {}", path.display()))?;
    Ok(())
}
