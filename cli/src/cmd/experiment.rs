//! `intellwheels experiment ...`: thesis experiments run in the simulator.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use iw_features::{DetectorConfig, DetectorKind};
use iw_shared_control_experiment::{
    Config, DriverModel, InputDevice, Mode, Sensors, Summary, office_circuit, sweep, sweep_trials,
    write_outputs, write_sweep,
};
use iw_sim::vo::{TrialConfig, TrialPoint, run_trial, sim_vo_config, waypoints_ahead};
use iw_sim::{ChairKind, ChairSpec, Map, TextureSet, World};
use iw_vo::Pipeline;

/// The `experiment` subcommands.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Thesis 3.7.1: simulated drivers who see, one lap per paradigm each (manual first), on a
    /// map's closed route: manual vs the thesis's potential field (`shared`) vs its arc-chord
    /// variant vs VFH+ vs the control agent's guarded policy; writes OUT/summary.json and plots.
    /// `--sweep` varies the assumptions thesis 3.6 leaves open instead.
    SharedControl(SharedControlArgs),
    /// Thesis 3.3.2 and chapter 5: a chair drives a textured map with encoder errors; wheel
    /// odometry, RGB-D visual odometry on the rendered frames and their EKF against the
    /// simulator's exact pose. Prints the position RMSEs; `--plot` draws the four paths.
    Odometry(OdometryArgs),
    /// Thesis 3.8 and 6.4: chairs drive a map's closed route with encoder bias, slip and sensor
    /// noise; wheel odometry, visual odometry, their EKF and the map-based localizer against the
    /// exact pose, and global localization from unknown starts. Writes OUT/summary.json,
    /// OUT/paths.png and OUT/error.png.
    Localization(LocalizationArgs),
}

/// Flags of `experiment localization`.
#[derive(clap::Args)]
pub struct LocalizationArgs {
    /// Output directory (summary.json, paths.png, error.png).
    #[arg(long)]
    out: PathBuf,
    /// Map file with a closed route (docs/map-format.md); default: the sample building.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Simulated minutes per tracking drive.
    #[arg(long, default_value_t = 30.0)]
    minutes: f64,
    /// Tracking drives (one seed each).
    #[arg(long, default_value_t = 1, value_parser = super::flags::at_most(10_000))]
    seeds: usize,
    /// Global localization runs (unknown start).
    #[arg(long, default_value_t = 50, value_parser = super::flags::at_most(100_000))]
    global_runs: usize,
    /// Blind runs (laser silent for 10 m, after 0 and after 30 m with it; one seed each).
    #[arg(long, default_value_t = 20, value_parser = super::flags::at_most(100_000))]
    blind_runs: usize,
    /// Visual odometry on every this many 50 ms periods (0: none).
    #[arg(long, default_value_t = 2)]
    vo_every: usize,
    /// First seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// No chairs on the map's `mover...` routes (moving obstacles that are not on the map).
    #[arg(long)]
    no_movers: bool,
}

/// Flags of `experiment odometry`.
#[derive(clap::Args)]
pub struct OdometryArgs {
    /// Camera frames (10 per simulated second at the default step).
    #[arg(long, default_value_t = 80, value_parser = super::flags::count(100_000))]
    frames: usize,
    /// Cruise speed, m/s.
    #[arg(long, default_value_t = 0.4)]
    speed: f64,
    /// Detectors to run, one trial each on the same drive (lsac-surf, surf, ln-surf).
    #[arg(long, value_delimiter = ',', default_value = "lsac-surf")]
    detectors: Vec<DetectorKind>,
    /// `thesis` (frame-to-frame) or `keyframe` visual odometry.
    #[arg(long, default_value = "keyframe")]
    pipeline: Pipeline,
    /// Detector threshold as a fraction of its 640x480 default (default 0.25 at 320x240).
    #[arg(long)]
    threshold_scale: Option<f32>,
    /// Change the light at this frame (with `--light`).
    #[arg(long)]
    light_at: Option<usize>,
    /// Light level from `--light-at` on (1 nominal, 0 dark).
    #[arg(long, default_value_t = 0.4)]
    light: f64,
    /// Folder of photographs for walls and furniture (png/jpg); default: procedural textures.
    #[arg(long)]
    textures: Option<PathBuf>,
    /// Map file with a start and a route of the same name; default: the embedded office circuit.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Start pose and route to follow.
    #[arg(long, default_value = "lap")]
    route: String,
    /// Seed of the encoder errors (tyre compression, slip).
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Top view of truth, wheel, VO and fused paths (PNG; first detector's trial).
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// Flags of `experiment shared-control`.
#[derive(clap::Args)]
pub struct SharedControlArgs {
    /// Simulated volunteers (the thesis had 8).
    #[arg(long, default_value_t = 8, value_parser = super::flags::count(1000))]
    drivers: usize,
    /// Laps per driver and paradigm (1: the thesis's protocol; more: the multi-lap mode).
    #[arg(long, default_value_t = 1, value_parser = super::flags::count(1000))]
    laps: usize,
    /// Output directory (summary.json, trials.json, paths-*.png, collisions.png; sweep.json and
    /// sweep.png with --sweep).
    #[arg(long, default_value = "shared-control-out")]
    out: PathBuf,
    /// Map file (docs/map-format.md) with a closed route to drive; default: the embedded office
    /// circuit.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Name of the map's route to drive (must be `closed`).
    #[arg(long, default_value = "lap")]
    route: String,
    /// First driver's seed; driver i is the person of seed + i, whatever the set's size, so
    /// `--drivers 16 --seed 101` runs seeds 101-116 and `--drivers 8` (seed 1) the page's 1-8.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A lap not finished within this many simulated seconds ends the driver's trial.
    #[arg(long, default_value = "240", value_parser = super::flags::seconds)]
    lap_timeout_s: std::time::Duration,
    /// The drivers' input device.
    #[arg(long, default_value = "head-cap", value_parser = ["head-cap", "joystick"])]
    device: String,
    /// How the simulated drivers' judgement moves in time: `steady` (the default: a smaller
    /// misjudgement correlated over a reaction time, head-cap steps with hysteresis) or
    /// `per-period` (a fresh misjudgement every period, the model before the calibration).
    #[arg(long, default_value = "steady", value_parser = ["per-period", "steady"])]
    driver_model: String,
    /// What VFH+ and the guarded policy see (the thesis's field always uses the sonars).
    #[arg(long, default_value = "sonars-laser", value_parser = ["sonars", "sonars-laser"])]
    sensors: String,
    /// Run the sensitivity sweep of the `shared` field over the thesis's open assumptions instead.
    #[arg(long)]
    sweep: bool,
}

pub fn run(command: Command) -> anyhow::Result<ExitCode> {
    match command {
        Command::SharedControl(args) => shared_control(args),
        Command::Odometry(args) => odometry(args),
        Command::Localization(args) => localization(args),
    }
}

fn localization(args: LocalizationArgs) -> anyhow::Result<ExitCode> {
    use iw_localization_experiment as exp;
    anyhow::ensure!(
        args.minutes.is_finite() && args.minutes > 0.0 && args.minutes <= 24.0 * 60.0,
        "--minutes must lie in (0, 1440], got {}",
        args.minutes
    );
    anyhow::ensure!(
        args.seeds > 0 || args.global_runs > 0 || args.blind_runs > 0,
        "--seeds, --global-runs and --blind-runs are all 0: nothing to run"
    );
    let map = match &args.map {
        Some(path) => Map::load(path).with_context(|| format!("loading map {}", path.display()))?,
        None => exp::sample_building()?,
    };
    exp::tour(&map)?;
    let config = exp::Config {
        minutes: args.minutes,
        seeds: args.seeds,
        global_runs: args.global_runs,
        blind_runs: args.blind_runs,
        vo_every: args.vo_every,
        seed: args.seed,
        movers: !args.no_movers,
        ..exp::Config::default()
    };
    let total = (args.minutes.ceil() as u64) * args.seeds as u64
        + args.global_runs as u64
        + (args.blind_runs * exp::BLIND_LEARN_M.len()) as u64;
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} (simulated minutes + global and blind runs) ({elapsed}, eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let report = exp::run(&map, &config, &|_| bar.inc(1))?;
    bar.finish_and_clear();
    let s = exp::write_outputs(&report, &map, &args.out)?;
    let row = |name: &str, e: Option<&exp::ErrorStats>| match e {
        Some(e) => println!(
            "{name:<10} RMSE {:>7.1} cm  max {:>7.1} cm",
            e.rmse_m * 100.0,
            e.max_m * 100.0
        ),
        None => println!("{name:<10} (not run)"),
    };
    row("wheel", Some(&s.wheel));
    row("vo", s.vo.as_ref());
    row("fused", Some(&s.fused));
    row("localized", Some(&s.localized));
    println!(
        "NEES: pass rate {:.3} (0.95 if consistent), mean {:.2} (3), above {:.3}; localizer {:.0} us median, {:.0} us p99 per period",
        s.nees_pass_rate, s.nees_mean, s.nees_above_rate, s.localizer_us.0, s.localizer_us.1
    );
    println!(
        "global: {}/{} converged, median {} m, {} falsely confident",
        s.global.converged,
        s.global.runs,
        s.global
            .median_distance_m
            .map_or("-".into(), |d| format!("{d:.2}")),
        s.global.falsely_confident
    );
    for b in &s.blind {
        let line = |name: &str, m: &exp::BlindStats| {
            println!(
                "blind {:.0} m after {:.0} m with the laser, {name:<11}: error median {:.1} cm (max {:.1}), 2 sigma median {:.1} cm, within 2 sigma {}/{}, position NEES inside 95 % {:.2}",
                exp::BLIND_M,
                b.learn_m,
                m.median_error_m * 100.0,
                m.max_error_m * 100.0,
                m.median_two_sigma_m * 100.0,
                m.within_two_sigma,
                b.runs,
                m.inside_rate
            )
        };
        line("bias states", &b.modelled);
        line("without", &b.unmodelled);
    }
    println!("wrote {}", args.out.join("summary.json").display());
    Ok(ExitCode::SUCCESS)
}

/// Fastest `--speed` accepted, m/s: far above a wheelchair's, and a NaN or 1e300 speed was run.
const MAX_SPEED_MPS: f64 = 10.0;

fn odometry(args: OdometryArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(args.frames >= 2, "--frames must be at least 2");
    anyhow::ensure!(
        args.speed.is_finite() && args.speed > 0.0 && args.speed <= MAX_SPEED_MPS,
        "--speed must lie in (0, {MAX_SPEED_MPS}] m/s, got {}",
        args.speed
    );
    if let Some(factor) = args.threshold_scale {
        anyhow::ensure!(
            factor.is_finite() && factor > 0.0,
            "--threshold-scale must be a positive, finite factor, got {factor}"
        );
    }
    anyhow::ensure!(
        args.light.is_finite() && args.light >= 0.0,
        "--light must be a finite level from 0 (dark) up, got {}",
        args.light
    );
    anyhow::ensure!(!args.detectors.is_empty(), "--detectors names none");
    let map = match &args.map {
        Some(path) => Map::load(path).with_context(|| format!("loading map {}", path.display()))?,
        None => office_circuit()?,
    };
    let start = map
        .start(&args.route)
        .with_context(|| format!("the map has no start named `{}`", args.route))?;
    let route = map
        .route(&args.route)
        .with_context(|| format!("the map has no route named `{}`", args.route))?;
    let waypoints = waypoints_ahead(&start, route);
    let textures = match &args.textures {
        Some(dir) => Some(TextureSet::load_dir(dir)?),
        None => None,
    };
    let mut trials = Vec::new();
    println!(
        "{:<10} {:>12} {:>12} {:>12} {:>10} {:>10} {:>12}",
        "detector", "wheel RMSE", "VO RMSE", "fused RMSE", "VO frames", "VO fps", "render ms"
    );
    for &detector in &args.detectors {
        let mut world = World::new(map.clone(), args.seed);
        if let Some(t) = &textures {
            world.set_textures(t.clone());
        }
        let id = world.add_chair(ChairSpec::default(), start, ChairKind::Simulated);
        let world = iw_sim::shared(world);
        let config = TrialConfig {
            frames: args.frames,
            speed_mps: args.speed,
            vo: {
                let mut vo = sim_vo_config(detector, args.pipeline);
                if let Some(factor) = args.threshold_scale {
                    vo.detector_config.threshold =
                        DetectorConfig::for_kind(detector).threshold * factor;
                }
                vo
            },
            light_change: args.light_at.map(|at| (at, args.light)),
            ..TrialConfig::default()
        };
        let trial = run_trial(&world, id, &waypoints, &config)?;
        println!(
            "{:<10} {:>10.1} cm {:>9.1} cm {:>9.1} cm {:>10} {:>10.1} {:>12.1}",
            detector.to_string(),
            trial.rmse_wheel_m() * 100.0,
            trial.rmse_vo_m() * 100.0,
            trial.rmse_fused_m() * 100.0,
            format!("{}/{}", trial.vo_frames, trial.points.len()),
            trial.vo_fps(),
            trial.render_seconds * 1e3 / trial.points.len().max(1) as f64
        );
        trials.push((detector, trial));
    }
    if let (Some(path), Some((detector, trial))) = (&args.plot, trials.first()) {
        let series = |name: &str, pick: &dyn Fn(&TrialPoint) -> iw_vo::Pose2| {
            iw_plot::trajectory::Trajectory {
                name: name.to_string(),
                samples: trial
                    .points
                    .iter()
                    .map(|p| (p.time_s, [pick(p).x, pick(p).y, pick(p).theta]))
                    .collect(),
            }
        };
        let title = format!(
            "odometry in the simulator ({detector}): wheel {:.1} cm, VO {:.1} cm, fused {:.1} cm RMSE (z panel: heading, rad)",
            trial.rmse_wheel_m() * 100.0,
            trial.rmse_vo_m() * 100.0,
            trial.rmse_fused_m() * 100.0
        );
        iw_plot::trajectory::plot_trajectories(
            path,
            &title,
            &[
                series("ground truth", &|p| p.truth),
                series("wheel odometry", &|p| p.wheel),
                series("visual odometry", &|p| p.vo),
                series("fused (EKF)", &|p| p.fused),
            ],
        )?;
        println!("wrote {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn shared_control(args: SharedControlArgs) -> anyhow::Result<ExitCode> {
    let map = match &args.map {
        Some(path) => Map::load(path).with_context(|| format!("loading map {}", path.display()))?,
        None => office_circuit()?,
    };
    let config = Config {
        drivers: args.drivers,
        laps: args.laps,
        seed: args.seed,
        route: args.route.clone(),
        lap_timeout_s: args.lap_timeout_s.as_secs_f64(),
        device: match args.device.as_str() {
            "joystick" => InputDevice::Joystick,
            _ => InputDevice::HeadCap,
        },
        driver_model: match args.driver_model.as_str() {
            "steady" => DriverModel::Steady,
            _ => DriverModel::PerPeriod,
        },
        sensors: match args.sensors.as_str() {
            "sonars" => Sensors::Sonars,
            _ => Sensors::SonarsLaser,
        },
        ..Config::default()
    };
    let total = if args.sweep {
        sweep_trials(args.drivers)
    } else {
        args.drivers * Mode::ALL.len()
    };
    let bar = indicatif::ProgressBar::new(total as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} trials ({elapsed}, eta {eta}) {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let on_trial = |trial: &iw_shared_control_experiment::Trial| {
        bar.set_message(format!(
            "driver {} {}: {} collisions",
            trial.driver + 1,
            trial.mode.key(),
            trial.collisions
        ));
        bar.inc(1);
    };
    if args.sweep {
        let rows = sweep(&map, &config, on_trial)?;
        bar.finish_and_clear();
        write_sweep(&rows, &map.name, &args.out)?;
        println!(
            "{:<12} {:>10} {:>8} {:>9} {:>10} {:>6} {:>8}",
            "reading", "coll/lap", "laps", "lap time", "reduction", "T", "p exact"
        );
        for r in &rows {
            println!(
                "{:<12} {:>10.2} {:>8} {:>9} {:>10} {:>6} {:>8}",
                r.name,
                r.collisions_per_lap,
                format!("{}/{}", r.laps_completed, r.laps_attempted),
                r.mean_lap_time_s
                    .map_or("-".into(), |t| format!("{t:.0} s")),
                pct(r.collision_reduction),
                r.wilcoxon.t,
                r.wilcoxon.p_exact.map_or("-".into(), |p| format!("{p:.4}")),
            );
        }
        println!("wrote {}", args.out.join("sweep.json").display());
        return Ok(ExitCode::SUCCESS);
    }
    let report = iw_shared_control_experiment::run(&map, &config, on_trial)?;
    bar.finish_and_clear();
    let summary = write_outputs(&report, &map, &args.out)?;
    print_table(&summary);
    println!("wrote {}", args.out.join("summary.json").display());
    Ok(ExitCode::SUCCESS)
}

fn pct(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |v| format!("{:.1}%", 100.0 * v))
}

fn print_table(s: &Summary) {
    println!(
        "{:<13} {:>10} {:>9} {:>7} {:>9} {:>9} {:>10} {:>6} {:>9} {:>9}",
        "mode",
        "collisions",
        "coll/lap",
        "laps",
        "lap time",
        "speed",
        "reduction",
        "T",
        "p exact",
        "p normal"
    );
    let comparisons = [
        None,
        Some(&s.manual_vs_shared),
        Some(&s.manual_vs_shared_chord),
        Some(&s.manual_vs_vfh),
        Some(&s.manual_vs_guarded),
    ];
    for (mode, c) in Mode::ALL.into_iter().zip(comparisons) {
        let m = s.mode(mode);
        println!(
            "{:<13} {:>10} {:>9.2} {:>7} {:>9} {:>9} {:>10} {:>6} {:>9} {:>9}",
            mode.key(),
            m.collisions,
            m.collisions_per_lap,
            format!("{}/{}", m.laps_completed, m.laps_attempted),
            m.mean_lap_time_s
                .map_or("-".into(), |t| format!("{t:.0} s")),
            format!("{:.2} m/s", m.mean_speed_mps),
            pct(c.and_then(|c| c.collision_reduction)),
            c.map_or("-".into(), |c| c.wilcoxon.t.to_string()),
            c.and_then(|c| c.wilcoxon.p_exact)
                .map_or("-".into(), |p| format!("{p:.4}")),
            c.map_or("-".into(), |c| format!("{:.4}", c.wilcoxon.p_normal)),
        );
    }
    let g = &s.guarded_task;
    println!(
        "guarded task target (>= 95 % laps, <= 0.05 collisions/lap, <= 1.5x manual lap time): {} (completes {}, safe {}, timely {})",
        if g.met { "met" } else { "NOT met" },
        g.completes,
        g.safe,
        g.timely
    );
}
