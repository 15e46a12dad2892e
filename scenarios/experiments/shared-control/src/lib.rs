//! The obstacle-avoidance experiment of thesis 3.7.1, run with simulated volunteers who see:
//! each [`iw_shared_control::driver::SeeingDriver`] drives the circuit of a map in the [`iw_sim`]
//! world once per paradigm, in the thesis's order (manual first): manually, with the thesis's
//! potential field as a joystick filter ([`Mode::Shared`]), with the same equations through our
//! older arc-chord mapping ([`Mode::SharedChord`]), with VFH+, and with the control agent's
//! policy (the arc guard's footprint sweep from the encoder-measured motion, with the laser points
//! it no longer sees remembered). Collisions come from the
//! simulator's contact counter (one per new contact); interventions from comparing the user's
//! command with the one sent to the wheels; "near obstacles" from the true clearance between the
//! chair's footprint and the map.
//!
//! Protocol (thesis 3.7.1): one lap per paradigm per driver (`laps = 1`), collisions per lap
//! paired per driver, one-tailed Wilcoxon signed-rank (T, exact and normal-approximation p).
//! `laps > 1` keeps the older multi-lap mode. Simulated drivers do not learn, so the order is
//! recorded but changes nothing.
//!
//! Organization:
//! - [`Config`], [`Mode`], [`Sensors`]: what to run; [`OFFICE_CIRCUIT`]: the default map.
//! - [`run_trial`]: one driver, one mode; [`run`]: all of them (in parallel), then [`Report`].
//! - [`Summary`]: the JSON written as `summary.json`; [`write_outputs`] adds plots;
//!   [`sweep`]: the sensitivity of the `shared` result to the assumptions the thesis leaves open.
//!
//! Guarantees: deterministic (a trial depends only on the map, the config and its driver index),
//! whatever the thread count; every failure is an [`ExperimentError`] naming its cause.
#![warn(missing_docs)]

mod clearance;
mod output;
mod sweep;

pub use iw_shared_control::driver::{DriverModel, InputDevice};
pub use output::{ModeSummary, Summary, write_outputs};
pub use sweep::{SweepRow, Variant, sweep, sweep_trials, variants, write_sweep};

use iw_shared_control::basic::{BasicControl, DiffDrive};
use iw_shared_control::driver::{Circuit, DriverProfile, Perception, SeeingDriver};
use iw_shared_control::{
    ArcGuard, ArcGuardParams, ControlError, Intervention, Manual, PotentialField,
    PotentialFieldParams, SharedController, SharedInput, ThesisField, ThesisFieldParams, Vfh,
    VfhParams, WheelMotion,
};
use iw_sim::{ChairId, ChairKind, ChairSpec, Map, SimError, World};
use nalgebra::{Isometry2, Point2, Vector2};
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
    /// The route is open: a lap needs a closed one.
    #[error("route `{name}` is not closed; a lap needs `route {name} closed x1 y1 ...`")]
    OpenRoute {
        /// Route asked for.
        name: String,
    },
    /// A summary needs every paradigm's trials.
    #[error("the report has no `{mode}` trials; a summary needs every paradigm")]
    MissingMode {
        /// The paradigm missing.
        mode: &'static str,
    },
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

/// The control paradigms compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// The user's command goes straight to the wheels.
    Manual,
    /// Thesis 3.6 on the 16 sonars, read as a filter on the joystick's input vector
    /// ([`ThesisField`]).
    Shared,
    /// The same equations through our arc-chord mapping ([`PotentialField`]), the reading this
    /// experiment used before; kept as a variant.
    SharedChord,
    /// VFH+ on the configured [`Sensors`].
    Vfh,
    /// The control agent's policy: the arc guard's footprint sweep from the measured motion, on
    /// the configured [`Sensors`].
    Guarded,
}

impl Mode {
    /// All modes, in the order each driver drives them (the thesis's: manual first).
    pub const ALL: [Mode; 5] = [
        Mode::Manual,
        Mode::Shared,
        Mode::SharedChord,
        Mode::Vfh,
        Mode::Guarded,
    ];

    /// The key used in `summary.json` and file names.
    pub fn key(self) -> &'static str {
        match self {
            Mode::Manual => "manual",
            Mode::Shared => "shared",
            Mode::SharedChord => "shared_chord",
            Mode::Vfh => "vfh",
            Mode::Guarded => "guarded",
        }
    }
}

/// Which sensors VFH+ and the guarded policy see (the thesis's field always uses the sonars).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sensors {
    /// The 16 sonars only (what the thesis's field sees).
    Sonars,
    /// The sonars and the 270-degree laser scanner.
    SonarsLaser,
}

/// What to run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Config {
    /// Simulated volunteers (8 in the thesis).
    pub drivers: usize,
    /// Laps each driver drives per mode (1: the thesis's protocol).
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
    /// The drivers' input device (the thesis's volunteers used the head cap).
    pub device: InputDevice,
    /// How the drivers' judgement moves in time.
    pub driver_model: DriverModel,
    /// What VFH+ and the guarded policy see.
    pub sensors: Sensors,
    /// The `shared` paradigm's constants and open assumptions.
    pub field: ThesisFieldParams,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            drivers: 8,
            laps: 1,
            seed: 1,
            route: "lap".into(),
            period_s: 0.05,
            lap_timeout_s: 240.0,
            near_m: 0.8,
            watchdog_ns: 300_000_000,
            device: InputDevice::HeadCap,
            driver_model: DriverModel::default(),
            sensors: Sensors::SonarsLaser,
            field: ThesisFieldParams::default(),
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
    /// Collision events counted by the simulator (one per new contact).
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
    /// Simulated time driven, s.
    pub duration_s: f64,
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
    /// Trials ordered by driver, then in the order driven.
    pub trials: Vec<Trial>,
}

impl Report {
    /// The trials of one paradigm, in driver order.
    pub fn trials_of(&self, mode: Mode) -> Vec<&Trial> {
        self.trials.iter().filter(|t| t.mode == mode).collect()
    }
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
    if !route.closed {
        return Err(ExperimentError::OpenRoute {
            name: config.route.clone(),
        });
    }
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

/// Bearings the simulated person looks along, chair frame, rad: every 15 degrees.
fn bearings() -> Vec<f64> {
    (0..24)
        .map(|k| iw_shared_control::tactical::wrap_angle(k as f64 * 15f64.to_radians()))
        .collect()
}

/// What a person sees: the clearance from the footprint to the nearest solid along each bearing,
/// cast from the footprint's centre (what the person judges, not what the sensors report).
fn perceive(
    world: &World,
    id: ChairId,
    spec: &ChairSpec,
    pose: &Isometry2<f64>,
    bearings: &[f64],
    out: &mut Vec<f64>,
) {
    const SIGHT_M: f64 = 5.0;
    let half_length = (spec.front_m + spec.rear_m) / 2.0;
    let origin = pose * Point2::new((spec.front_m - spec.rear_m) / 2.0, 0.0);
    out.clear();
    out.extend(bearings.iter().map(|&b| {
        let (sin, cos) = b.sin_cos();
        // Distance from the centre to the rectangle's edge along this bearing.
        let edge = (half_length / cos.abs()).min(spec.half_width_m / sin.abs());
        let dir = pose.rotation * Vector2::new(cos, sin);
        world
            .cast(&origin, &dir, SIGHT_M, Some(id.0))
            .map_or(f64::INFINITY, |hit| (hit.range_m - edge).max(0.0))
    }));
}

/// The controller a mode drives through.
fn controller(
    mode: Mode,
    config: &Config,
    spec: &ChairSpec,
) -> Result<Box<dyn SharedController>, ExperimentError> {
    let mounts: Vec<_> = spec.sonars.iter().map(|m| m.t_body_sonar).collect();
    Ok(match mode {
        Mode::Manual => Box::new(Manual),
        Mode::Shared => Box::new(ThesisField::new(
            config.field,
            mounts,
            spec.front_m,
            spec.rear_m,
        )?),
        Mode::SharedChord => Box::new(PotentialField::new(
            PotentialFieldParams::default(),
            mounts,
        )?),
        Mode::Guarded => {
            let guard = ArcGuard::new(ArcGuardParams::default(), spec.body_footprint(), mounts)?;
            Box::new(match (&spec.laser, config.sensors) {
                (Some(laser), Sensors::SonarsLaser) => {
                    guard.with_dense_view(laser.t_body_laser, laser.fov_deg.to_radians())
                }
                _ => guard,
            })
        }
        Mode::Vfh => Box::new(Vfh::new(
            VfhParams {
                robot_radius_m: spec.half_width_m,
                ..VfhParams::default()
            },
            mounts,
        )?),
    })
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
    let mut controller = controller(mode, config, &spec)?;
    let drive = DiffDrive::new(
        spec.geometry.track_m,
        spec.max_wheel_mps,
        spec.max_wheel_accel_mps2,
    )?;
    let mut basic = BasicControl::new(drive, config.watchdog_ns);
    // The guarded policy reads the encoders as the control agent does; the thesis's field and
    // VFH+ take no motion input.
    let mut wheels = (mode == Mode::Guarded).then(|| WheelMotion::new(spec.geometry));
    let mapping = config.field.mapping;
    let mut person =
        SeeingDriver::new(DriverProfile::from_seed(seed), config.device, circuit, seed)
            .with_model(config.driver_model);
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
        duration_s: 0.0,
        path: Vec::new(),
        collision_points: Vec::new(),
    };
    let mut points = Vec::new();
    let bearings = bearings();
    let mut seen = Vec::with_capacity(bearings.len());
    let start_ns = world.time_ns();
    let mut lap_start_ns = start_ns;
    while trial.laps_completed < config.laps {
        let now_ns = world.time_ns();
        if (now_ns - lap_start_ns) as f64 * 1e-9 > config.lap_timeout_s {
            trial.timed_out = true;
            break;
        }
        let pose = world.pose(id)?;
        let (speed_mps, _) = world.twist(id)?;
        perceive(&world, id, &spec, &pose, &bearings, &mut seen);
        let out = person.step(
            now_ns,
            pose,
            speed_mps,
            &Perception {
                bearings_rad: &bearings,
                clearance_m: &seen,
                touching: world.in_contact(id)?,
            },
        )?;
        if out.laps > trial.laps_completed {
            trial
                .lap_times_s
                .push((now_ns - lap_start_ns) as f64 * 1e-9);
            trial.laps_completed = out.laps;
            lap_start_ns = now_ns;
            continue;
        }
        let frame = world.sensors(id)?;
        match (mode, config.sensors) {
            (Mode::Vfh | Mode::Guarded, Sensors::SonarsLaser) => {
                laser_points(&spec, &frame.laser_m, &mut points)
            }
            _ => points.clear(),
        }
        let motion = wheels
            .as_mut()
            .and_then(|w| w.update(frame.time_ns, frame.left_ticks, frame.right_ticks));
        let shared = controller.step(&SharedInput {
            user: mapping.to_command(out.input),
            speed_mps,
            sonar_m: &frame.sonar_m,
            points_chair: &points,
            motion,
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
    trial.duration_s = (world.time_ns() - start_ns) as f64 * 1e-9;
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

/// Runs every driver in every mode of `modes` (in parallel), calling `on_trial` as each trial
/// finishes.
pub fn run_modes(
    map: &Map,
    config: &Config,
    modes: &[Mode],
    on_trial: impl Fn(&Trial) + Sync,
) -> Result<Report, ExperimentError> {
    circuit_of(map, config)?;
    let jobs: Vec<(usize, Mode)> = (0..config.drivers)
        .flat_map(|d| modes.iter().map(move |&m| (d, m)))
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

/// Runs every driver in every mode of [`Mode::ALL`].
pub fn run(
    map: &Map,
    config: &Config,
    on_trial: impl Fn(&Trial) + Sync,
) -> Result<Report, ExperimentError> {
    run_modes(map, config, &Mode::ALL, on_trial)
}

/// The default map, parsed.
pub fn office_circuit() -> Result<Map, ExperimentError> {
    Ok(Map::parse(OFFICE_CIRCUIT, "office-circuit.map")?)
}
