//! `intellwheels` (no subcommand) and `intellwheels demo`: the mixed-reality demo with no setup.
//!
//! The embedded sample building, the service container and a few virtual chairs, each in its own
//! container, talking FIPA-ACL over real bus frames in simulated time. Chairs get goals; one is
//! sent to the bathroom behind a door that stays closed (jammed), so its door request is refused
//! and the goal cannot be planned. Ends with a summary and a JSON-lines log of every frame
//! exchanged between containers.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use iw_fleet::{ChairConfig, Fleet};
use iw_sim::Map;
use nalgebra::{Isometry2, Point2, Vector2};

/// The sample care building shipped with the sources (`scenarios/maps/sample-building.map`).
const SAMPLE_BUILDING: &str = include_str!("../../../scenarios/maps/sample-building.map");

/// The door the demo keeps closed.
const JAMMED_DOOR: &str = "bathroom";

/// Flags of `intellwheels demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Seed of the simulator's sensor and encoder noise.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Longest simulated time before the demo ends, s.
    #[arg(long, default_value_t = 90.0)]
    max_time_s: f64,
    /// Simulation step, ms.
    #[arg(long, default_value_t = 50)]
    step_ms: u64,
    /// Where to write the message log (default: a fresh folder in the temporary directory).
    #[arg(long)]
    log_dir: Option<PathBuf>,
}

/// One chair of the demo: where it starts and the named place it is sent to.
struct Mission {
    name: &'static str,
    start: (f64, f64, f64),
    place: &'static str,
}

const MISSIONS: [Mission; 3] = [
    Mission { name: "chair-0", start: (1.0, 6.0, 0.0), place: "dining-hall" },
    Mission { name: "chair-1", start: (15.0, 8.2, 180.0), place: "bedroom2" },
    Mission { name: "chair-2", start: (4.5, 2.5, 90.0), place: "bathroom" },
];

/// What became of one chair's goal.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
enum Outcome {
    /// The goal was sent; no final answer yet.
    Pending,
    /// The control agent informed it was done.
    Reached { time_s: f64 },
    /// The control agent (or the platform) answered failure or refuse.
    Failed { performative: String },
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
    anyhow::ensure!(args.max_time_s > 0.0 && args.max_time_s.is_finite(), "--max-time-s must be positive, got {}", args.max_time_s);
    anyhow::ensure!(args.step_ms > 0 && args.step_ms <= 1000, "--step-ms must be in 1..=1000, got {}", args.step_ms);
    let map = Map::parse(SAMPLE_BUILDING, "sample-building.map").context("embedded sample building")?;
    let places: Vec<Point2<f64>> = MISSIONS
        .iter()
        .map(|m| map.place(m.place).with_context(|| format!("the sample building has no place `{}`", m.place)))
        .collect::<anyhow::Result<_>>()?;
    let chairs: Vec<ChairConfig> = MISSIONS
        .iter()
        .map(|m| ChairConfig {
            name: m.name.to_string(),
            t_world_body: Isometry2::new(Vector2::new(m.start.0, m.start.1), m.start.2.to_radians()),
        })
        .collect();
    let mut fleet = Fleet::new(map, args.seed, &chairs).context("composing the fleet")?;
    fleet.jam_door(JAMMED_DOOR).context("jamming the demo door")?;

    let log_dir = match args.log_dir {
        Some(dir) => dir,
        None => std::env::temp_dir().join(format!("intellwheels-demo-{}", std::process::id())),
    };
    std::fs::create_dir_all(&log_dir).with_context(|| format!("creating {}", log_dir.display()))?;

    println!("IntellWheels demo: sample care building, {} chairs, services container", MISSIONS.len());
    let mut outcomes = Vec::new();
    let mut conversations = Vec::new();
    for (mission, target) in MISSIONS.iter().zip(&places) {
        if mission.place == JAMMED_DOOR {
            // the chair asks for the door first; a jammed door stays shut whatever it is asked
            fleet.set_door(JAMMED_DOOR, true)?;
        }
        match fleet.goal(mission.name, *target) {
            Ok(conversation) => {
                println!("  {} -> {} ({:.1}, {:.1}): request {conversation}", mission.name, mission.place, target.x, target.y);
                outcomes.push(Outcome::Pending);
                conversations.push(Some(conversation));
            }
            Err(err) => {
                let door_open = fleet.snapshot().doors.iter().any(|(d, open)| d == JAMMED_DOOR && *open);
                let reason = if door_open { err.to_string() } else { format!("door `{JAMMED_DOOR}` refused to open: {err}") };
                println!("  {} -> {}: refused ({reason})", mission.name, mission.place);
                outcomes.push(Outcome::Refused { reason });
                conversations.push(None);
            }
        }
    }

    let step = Duration::from_millis(args.step_ms);
    let total_steps = (args.max_time_s * 1000.0 / args.step_ms as f64).ceil() as u64;
    let bar = ProgressBar::new(total_steps);
    bar.set_style(
        ProgressStyle::with_template("{spinner} sim {msg} [{bar:30}] {percent}% ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    for _ in 0..total_steps {
        fleet.step(step);
        bar.inc(1);
        settle_outcomes(&fleet, &conversations, &mut outcomes);
        let done = outcomes.iter().filter(|o| !matches!(o, Outcome::Pending)).count();
        bar.set_message(format!("{:5.1} s, {done}/{} goals settled", fleet.time_s(), outcomes.len()));
        if done == outcomes.len() {
            break;
        }
    }
    bar.finish_and_clear();

    let exchanges = fleet.exchanges();
    let log_path = log_dir.join("messages.jsonl");
    write_log(&log_path, &exchanges)?;
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
    let summary_path = log_dir.join("summary.json");
    let summary = serde_json::json!({
        "time_s": snapshot.time_s,
        "chairs": reports,
        "messages": exchanges.len(),
        "dropped": exchanges.iter().filter(|e| e.dropped).count(),
        "doors": snapshot.doors,
    });
    write_synced(&summary_path, serde_json::to_string_pretty(&summary)?.as_bytes())?;

    let reached = reports.iter().filter(|r| matches!(r.outcome, Outcome::Reached { .. })).count();
    let collisions: u64 = reports.iter().map(|r| r.collisions).sum();
    println!("Summary after {:.1} s simulated:", snapshot.time_s);
    for r in &reports {
        let outcome = match &r.outcome {
            Outcome::Pending => "not reached in time".to_string(),
            Outcome::Reached { time_s } => format!("reached at {time_s:.1} s"),
            Outcome::Failed { performative } => format!("control answered {performative}"),
            Outcome::Refused { reason } => format!("refused: {reason}"),
        };
        println!("  {:8} {:12} {outcome}; {:.1} m driven, {} collisions", r.name, r.goal, r.distance_m, r.collisions);
    }
    println!("  goals reached: {reached}/{}", reports.len());
    println!("  collisions:    {collisions}");
    println!("  messages:      {} between containers ({} dropped)", exchanges.len(), summary["dropped"]);
    println!("  log:           {} (summary: {})", log_path.display(), summary_path.display());
    Ok(ExitCode::SUCCESS)
}

/// Records the final answer (done, failure, refuse) of each pending goal.
fn settle_outcomes(fleet: &Fleet, conversations: &[Option<String>], outcomes: &mut [Outcome]) {
    let events = fleet.goal_events();
    for (conversation, outcome) in conversations.iter().zip(outcomes.iter_mut()) {
        let (Some(conversation), Outcome::Pending) = (conversation, &*outcome) else { continue };
        for event in events.iter().filter(|e| &e.conversation == conversation) {
            let p = event.performative.to_ascii_lowercase();
            if p == "inform" {
                *outcome = Outcome::Reached { time_s: event.time_s };
            } else if p == "failure" || p == "refuse" || p == "not-understood" {
                *outcome = Outcome::Failed { performative: p };
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
    writer.write_all(bytes).with_context(|| format!("writing {}", path.display()))?;
    let file = writer.into_inner().map_err(|e| e.into_error()).with_context(|| format!("writing {}", path.display()))?;
    file.sync_all().with_context(|| format!("syncing {}", path.display()))?;
    Ok(())
}
