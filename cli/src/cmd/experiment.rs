//! `intellwheels experiment ...`: thesis experiments run in the simulator.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use iw_shared_control_experiment::{Config, Summary, office_circuit, write_outputs};
use iw_sim::Map;

/// The `experiment` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Thesis 3.7.1: simulated head-gesture drivers on a cluttered office circuit, manual vs the
    /// thesis's potential-field shared control vs VFH+; writes OUT/summary.json and path plots.
    SharedControl(SharedControlArgs),
}

/// Flags of `experiment shared-control`.
#[derive(clap::Args)]
pub struct SharedControlArgs {
    /// Simulated volunteers (the thesis had 8).
    #[arg(long, default_value_t = 8)]
    drivers: usize,
    /// Laps per driver and paradigm.
    #[arg(long, default_value_t = 3)]
    laps: usize,
    /// Output directory (summary.json, trials.json, paths-*.png, collisions.png).
    #[arg(long, default_value = "shared-control-out")]
    out: PathBuf,
    /// Map file (docs/map-format.md) with a closed route to drive; default: the embedded office
    /// circuit.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Name of the map's route to drive.
    #[arg(long, default_value = "lap")]
    route: String,
    /// Base seed; driver i uses seed + i.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A lap not finished within this many simulated seconds ends the driver's trial.
    #[arg(long, default_value_t = 240.0)]
    lap_timeout_s: f64,
}

pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    match command {
        Command::SharedControl(args) => shared_control(args),
    }
}

fn shared_control(args: SharedControlArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(args.drivers > 0 && args.laps > 0, "--drivers and --laps must be at least 1");
    anyhow::ensure!(args.lap_timeout_s > 0.0, "--lap-timeout-s must be positive");
    let map = match &args.map {
        Some(path) => Map::load(path).with_context(|| format!("loading map {}", path.display()))?,
        None => office_circuit()?,
    };
    let config = Config {
        drivers: args.drivers,
        laps: args.laps,
        seed: args.seed,
        route: args.route.clone(),
        lap_timeout_s: args.lap_timeout_s,
        ..Config::default()
    };
    let bar = indicatif::ProgressBar::new((args.drivers * 3) as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} trials ({elapsed}, eta {eta}) {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let report = iw_shared_control_experiment::run(&map, &config, |trial| {
        bar.set_message(format!("driver {} {}: {} collisions", trial.driver + 1, trial.mode.key(), trial.collisions));
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    let summary = write_outputs(&report, &map, &args.out)?;
    print_table(&summary);
    println!("wrote {}", args.out.join("summary.json").display());
    Ok(ExitCode::SUCCESS)
}

fn print_table(s: &Summary) {
    println!(
        "{:<8} {:>10} {:>10} {:>6} {:>10} {:>12} {:>12} {:>12}",
        "mode", "collisions", "per lap", "laps", "lap time", "interv.rate", "rate near", "rate free"
    );
    for (name, m) in [("manual", &s.manual), ("shared", &s.shared), ("vfh", &s.vfh)] {
        let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
        println!(
            "{:<8} {:>10} {:>10} {:>6} {:>10} {:>12.3} {:>12.3} {:>12.3}",
            name,
            m.collisions,
            opt(m.collisions_per_lap),
            format!("{}/{}", m.laps_completed, m.laps_attempted),
            opt(m.mean_lap_time_s),
            m.intervention_rate,
            m.intervention_rate_near,
            m.intervention_rate_free
        );
    }
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.0}%", 100.0 * v));
    println!(
        "collision reduction vs manual: shared {}, vfh {}; Wilcoxon manual > shared (one-tailed, exact) p = {:.4}",
        pct(s.manual_vs_shared.collision_reduction),
        pct(s.manual_vs_vfh.collision_reduction),
        s.wilcoxon_p
    );
}
