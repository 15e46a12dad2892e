//! The obstacle-avoidance experiment of thesis 3.7.1, run with simulated volunteers: each
//! [`iw_shared_control::driver::HeadGestureDriver`] drives laps of a cluttered office circuit in
//! the [`iw_sim`] world four times with the same seeds: manually, with the thesis's
//! potential-field shared control, with the VFH+ baseline, and with the control agent's policy
//! (the potential field, then the arc guard's footprint sweep). Collisions come from the
//! simulator's contact counter; interventions from comparing the user's command with the one sent
//! to the wheels; "near obstacles" from the true clearance between the chair's footprint and the
//! map.
//!
//! Organization:
//! - [`Config`], [`Mode`]: what to run; [`OFFICE_CIRCUIT`]: the default map, embedded.
//! - [`run_trial`]: one driver, one mode; [`run`]: all of them (in parallel), then [`Report`].
//! - [`Summary`]: the JSON written as `summary.json`; [`write_outputs`] adds path plots.
//!
//! Guarantees: deterministic (a trial depends only on the map, the config and its driver index),
//! whatever the thread count; every failure is an [`ExperimentError`] naming its cause.
#![warn(missing_docs)]

mod clearance;
mod output;

pub use output::{Summary, write_outputs};

use iw_shared_control::basic::{BasicControl, DiffDrive};
use iw_shared_control::driver::{Circuit, DriverProfile, HeadGestureDriver};
use iw_shared_control::{
    ArcGuard, ArcGuardParams, ControlError, Guarded, Intervention, Manual, PotentialField,
    PotentialFieldParams, SharedController, SharedInput, Vfh, VfhParams,
};
use iw_sim::{ChairKind, ChairSpec, Map, SimError, World};
use nalgebra::{Isometry2, Point2};
use rayon::prelude::*;

/// The default circuit: a closed office corridor loop with furniture narrowing it (figure 3.9).
pub const OFFICE_CIRCUIT: &str = include_str!("../../../maps/office-circuit.map");

/// Why the experiment could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExperimentError {
    /// The simulator refused something (bad map, unknown chair).
    #[error("simulator: {0}")]
    Sim(#[from] SimError),
    /// A controller or the driver model refused its input.
    #[error("control: {0}")]
    Control(#[from] ControlError),
    /// The paired samples could not be tested.
    #[error("statistics: {0}")]
    Stats(#[from] iw_stats::StatsError),
    /// The map has no route to drive.
    #[error(
        "map has no route `{name}` (routes: {available}); add `route {name} closed x1 y1 x2 y2 ...`"
    )]
    NoRoute {
        /// Route asked for.
        name: String,
        /// Routes the map has, comma separated.
        available: String,
    },
    /// A plot could not be drawn.
    #[error("plot: {0}")]
    Plot(#[from] iw_plot::PlotError),
    /// The summary could not be serialised (a non-finite number where JSON needs one).
    #[error("serialising the summary: {0}")]
    Json(#[from] serde_json::Error),
    /// An output file could not be written.
    #[error("writing `{path}`: {source}")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        source: std::io::Error,
    },
}

/// The three control paradigms compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// The user's command goes straight to the wheels.
    Manual,
    /// Thesis 3.6 potential field on the 16 sonars.
    Shared,
    /// VFH+ on the sonars and the laser scanner.
    Vfh,
    /// The control agent's policy: the potential field, then the arc guard's footprint sweep on
    /// the same sonars and laser points.
    Guarded,
}

impl Mode {
    /// All modes, in report order.
    pub const ALL: [Mode; 4] = [Mode::Manual, Mode::Shared, Mode::Vfh, Mode::Guarded];

    /// The key used in `summary.json` and file names.
    pub fn key(self) -> &'static str {
        match self {
            Mode::Manual => "manual",
            Mode::Shared => "shared",
            Mode::Vfh => "vfh",
            Mode::Guarded => "guarded",
        }
    }
}

/// What to run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Config {
    /// Simulated volunteers (8 in the thesis).
    pub drivers: usize,
    /// Laps each driver drives per mode.
    pub laps: usize,
    /// Base seed: driver `i` uses `seed + i` for their traits, drive noise and sensor noise.
    pub seed: u64,
    /// Route of the map to drive.
    pub route: String,
    /// Control period, s.
    pub period_s: f64,
    /// A lap not finished within this is abandoned (the trial ends), s.
    pub lap_timeout_s: f64,
    /// Footprint clearance under which the chair counts as near obstacles, m (the 80 cm perimeter).
    pub near_m: f64,
    /// Basic-control watchdog timeout, ns.
    pub watchdog_ns: u64,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            drivers: 8,
            laps: 3,
            seed: 1,
            route: "lap".into(),
            period_s: 0.05,
            lap_timeout_s: 240.0,
            near_m: 0.8,
            watchdog_ns: 300_000_000,
        }
    }
}

/// One driver's run in one mode.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Trial {
    /// Driver index.
    pub driver: usize,
    /// Paradigm.
    pub mode: Mode,
    /// Collision events counted by the simulator.
    pub collisions: u64,
    /// Laps finished.
    pub laps_completed: usize,
    /// Time of each finished lap, s.
    pub lap_times_s: Vec<f64>,
    /// True when a lap hit the timeout.
    pub timed_out: bool,
    /// Control periods run.
    pub periods: u64,
    /// Periods with the footprint within `near_m` of an obstacle.
    pub periods_near: u64,
    /// Periods where the command reaching the wheels differed from the user's, near / free.
    pub changed_near: u64,
    /// Same, in free space.
    pub changed_free: u64,
    /// Sum of the wheel-speed change over changed periods, m/s.
    pub change_sum_mps: f64,
    /// Smallest footprint clearance seen, m.
    pub min_clearance_m: f64,
    /// Ground distance driven, m.
    pub distance_m: f64,
    /// Positions every 0.25 s, m (for the plots).
    #[serde(skip)]
    pub path: Vec<(f64, f64)>,
    /// Where each collision happened, m.
    #[serde(skip)]
    pub collision_points: Vec<(f64, f64)>,
}

/// All trials of a run.
#[derive(Debug, Clone)]
pub struct Report {
    /// The configuration run.
    pub config: Config,
    /// Map name.
    pub map_name: String,
    /// Trials ordered by driver, then [`Mode::ALL`] order.
    pub trials: Vec<Trial>,
}

fn seed_of(config: &Config, driver: usize) -> u64 {
    config.seed.wrapping_add(driver as u64)
}

/// The circuit and start pose for `config.route`.
fn circuit_of(map: &Map, config: &Config) -> Result<(Circuit, Isometry2<f64>), ExperimentError> {
    let route = map
        .route(&config.route)
        .ok_or_else(|| ExperimentError::NoRoute {
            name: config.route.clone(),
            available: map
                .routes
                .iter()
                .map(|r| r.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        })?;
    let circuit = Circuit::new(route.points.clone())?;
    // Start where the map says for this route, else on the first waypoint facing the second.
    let start = map.start(&config.route).unwrap_or_else(|| {
        let (a, b) = (circuit.point_at(0.0), circuit.point_at(0.1));
        Isometry2::new(a.coords, (b - a).y.atan2((b - a).x))
    });
    Ok((circuit, start))
}

/// Laser ranges to obstacle points in the body frame (beams at max range dropped).
fn laser_points(spec: &ChairSpec, ranges: &[f64], out: &mut Vec<Point2<f64>>) {
    out.clear();
    let Some(laser) = &spec.laser else { return };
    let n = ranges.len();
    let fov = laser.fov_deg.to_radians();
    for (i, &r) in ranges.iter().enumerate() {
        if !(r.is_finite() && r < laser.max_range_m - 1e-6) {
            continue;
        }
        let a = if n > 1 {
            -fov / 2.0 + fov * i as f64 / (n - 1) as f64
        } else {
            0.0
        };
        out.push(laser.t_body_laser * Point2::new(r * a.cos(), r * a.sin()));
    }
}

/// Runs driver `driver` for `config.laps` laps in `mode`.
pub fn run_trial(
    map: &Map,
    config: &Config,
    driver: usize,
    mode: Mode,
) -> Result<Trial, ExperimentError> {
    let (circuit, start) = circuit_of(map, config)?;
    let seed = seed_of(config, driver);
    let spec = ChairSpec::default();
    let mut world = World::new(map.clone(), seed);
    let id = world.add_chair(spec.clone(), start, ChairKind::Simulated);
    let mounts: Vec<_> = spec.sonars.iter().map(|m| m.t_body_sonar).collect();
    let mut controller: Box<dyn SharedController> = match mode {
        Mode::Manual => Box::new(Manual),
        Mode::Shared => Box::new(PotentialField::new(
            PotentialFieldParams::default(),
            mounts,
        )?),
        Mode::Guarded => Box::new(Guarded {
            inner: PotentialField::new(PotentialFieldParams::default(), mounts.clone())?,
            guard: ArcGuard::new(ArcGuardParams::default(), spec.body_footprint(), mounts)?,
        }),
        Mode::Vfh => Box::new(Vfh::new(
            VfhParams {
                robot_radius_m: spec.half_width_m,
                ..VfhParams::default()
            },
            mounts,
        )?),
    };
    let drive = DiffDrive::new(
        spec.geometry.track_m,
        spec.max_wheel_mps,
        spec.max_wheel_accel_mps2,
    )?;
    let mut basic = BasicControl::new(drive, config.watchdog_ns);
    let mut person = HeadGestureDriver::new(DriverProfile::from_seed(seed), circuit, seed);
    let obstacles = clearance::Obstacles::from_map(map);
    let period_ns = (config.period_s * 1e9).round() as u64;
    let record_every = ((0.25 / config.period_s).round() as u64).max(1);
    let mut trial = Trial {
        driver,
        mode,
        collisions: 0,
        laps_completed: 0,
        lap_times_s: Vec::new(),
        timed_out: false,
        periods: 0,
        periods_near: 0,
        changed_near: 0,
        changed_free: 0,
        change_sum_mps: 0.0,
        min_clearance_m: f64::INFINITY,
        distance_m: 0.0,
        path: Vec::new(),
        collision_points: Vec::new(),
    };
    let mut points = Vec::new();
    let mut lap_start_ns = world.time_ns();
    while trial.laps_completed < config.laps {
        let now_ns = world.time_ns();
        if (now_ns - lap_start_ns) as f64 * 1e-9 > config.lap_timeout_s {
            trial.timed_out = true;
            break;
        }
        let pose = world.pose(id)?;
        let out = person.step(now_ns, pose)?;
        if out.laps > trial.laps_completed {
            trial
                .lap_times_s
                .push((now_ns - lap_start_ns) as f64 * 1e-9);
            trial.laps_completed = out.laps;
            lap_start_ns = now_ns;
            continue;
        }
        let frame = world.sensors(id)?;
        laser_points(&spec, &frame.laser_m, &mut points);
        let (speed_mps, _) = world.twist(id)?;
        let shared = controller.step(&SharedInput {
            user: out.command,
            speed_mps,
            sonar_m: &frame.sonar_m,
            points_chair: &points,
        })?;
        basic.command(shared.command, now_ns)?;
        world.command(id, basic.output(now_ns))?;
        account(
            &mut trial,
            &obstacles,
            &spec,
            pose,
            &shared.intervention,
            config,
        );
        if trial.periods.is_multiple_of(record_every) {
            trial.path.push((pose.translation.x, pose.translation.y));
        }
        let before = world.collisions(id)?;
        world.step(period_ns as f64 * 1e-9);
        if world.collisions(id)? > before {
            let p = world.pose(id)?;
            trial
                .collision_points
                .push((p.translation.x, p.translation.y));
        }
    }
    trial.collisions = world.collisions(id)?;
    trial.distance_m = world.distance_m(id)?;
    Ok(trial)
}

/// Counts one period: near or free, changed or not, by how much.
fn account(
    trial: &mut Trial,
    obstacles: &clearance::Obstacles,
    spec: &ChairSpec,
    pose: Isometry2<f64>,
    intervention: &Intervention,
    config: &Config,
) {
    let footprint = spec.footprint_at(&pose);
    let clearance = obstacles.clearance(&footprint, config.near_m + spec.reach_m());
    trial.min_clearance_m = trial.min_clearance_m.min(clearance);
    let near = clearance < config.near_m;
    trial.periods += 1;
    trial.periods_near += u64::from(near);
    if intervention.changed() {
        if near {
            trial.changed_near += 1;
        } else {
            trial.changed_free += 1;
        }
        trial.change_sum_mps += intervention.wheel_change_mps(spec.geometry.track_m);
    }
}

/// Runs every driver in every mode (in parallel), calling `on_trial` as each trial finishes.
pub fn run(
    map: &Map,
    config: &Config,
    on_trial: impl Fn(&Trial) + Sync,
) -> Result<Report, ExperimentError> {
    circuit_of(map, config)?;
    let jobs: Vec<(usize, Mode)> = (0..config.drivers)
        .flat_map(|d| Mode::ALL.map(|m| (d, m)))
        .collect();
    let trials = jobs
        .par_iter()
        .map(|&(driver, mode)| {
            let trial = run_trial(map, config, driver, mode)?;
            tracing::debug!(
                driver,
                mode = mode.key(),
                collisions = trial.collisions,
                "trial done"
            );
            on_trial(&trial);
            Ok(trial)
        })
        .collect::<Result<Vec<_>, ExperimentError>>()?;
    Ok(Report {
        config: config.clone(),
        map_name: map.name.clone(),
        trials,
    })
}

/// The default map, parsed.
pub fn office_circuit() -> Result<Map, ExperimentError> {
    Ok(Map::parse(OFFICE_CIRCUIT, "office-circuit.map")?)
}
