//! Thesis 3.8 and 6.4 in the simulator: how far off is a chair's pose after a long drive, with
//! wheel odometry alone, visual odometry alone, their EKF, and the map-based localizer
//! (iw-localization) that also matches the laser and sonars to the map; and does a chair that
//! starts with no pose find it while it drives?
//!
//! # Protocol
//! - Tracking drives ([`Config::seeds`] of them, [`Config::minutes`] each): a chair follows the
//!   map's closed route at [`Config::speed_mps`] from the route's first point, steered on the
//!   simulator's exact pose (the driver is not under test). Other chairs drive back and forth
//!   along the map's routes named `mover...`: moving obstacles that are not on the map. The simulator's encoder
//!   model (per-wheel tyre compression 0.5-3 %, slip) and sensor noise (laser 1 cm, sonar 1 cm)
//!   are on, seeded per drive. All four estimators start at the true pose and see the same
//!   readings each 50 ms period; visual odometry runs on the rendered RGB-D frames every
//!   [`Config::vo_every`] periods.
//! - Errors: position error against the simulator's pose at every period; RMSE and maximum.
//! - Consistency: the localizer's NEES (3 degrees of freedom) once per simulated second; the
//!   pass rate is the fraction of those samples inside the two-sided 95 % chi-square interval
//!   [0.216, 9.35], which a consistent filter meets 95 % of the time.
//! - Global localization ([`Config::global_runs`] runs): a chair placed at a random point of the
//!   route, facing along it, with no pose; it drives the route with wheel odometry, laser and
//!   sonars. Converged: the localizer first says it tracks within 5 m of driving, and its pose
//!   is then within 10 cm and 3 degrees. A run that reports tracking while more than 30 cm off,
//!   at any time of its drive, counts as falsely confident.
//! - Blind runs ([`Config::blind_runs`] seeds, each after every [`BLIND_LEARN_M`]): the laser
//!   goes silent for [`BLIND_M`] and the localizer dead-reckons; its error then against its
//!   covariance, with the wheel bias in the filter's state and without.
#![warn(missing_docs)]

mod output;

use std::sync::Arc;
use std::time::Instant;

use iw_body::WheelSpeeds;
use iw_features::DetectorKind;
use iw_localization::{LocalizationMap, Localizer, Status, markers_in};
use iw_sim::localization::{drive_params, localization_map, localizer_config};
use iw_sim::vo::{SimCamera, sim_vo_config};
use iw_sim::{ChairId, ChairKind, ChairSpec, Map, Route, SharedWorld, World};
use iw_vo::{
    CameraSource, OdometryFusion, Pipeline, Pose2, VisualOdometry, WheelBias, WheelOdometry,
    planar_motion, wrap_angle,
};
use nalgebra::{Isometry2, Matrix3, Point2, Vector3};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

pub use output::{BlindStats, BlindSummary, ErrorStats, GlobalSummary, Summary, write_outputs};

const SAMPLE_BUILDING: &str = include_str!("../../../maps/sample-building.map");

/// The sample care building (`scenarios/maps/sample-building.map`), with its `tour` route.
pub fn sample_building() -> Result<Map, ExperimentError> {
    Ok(Map::parse(SAMPLE_BUILDING, "sample-building.map")?)
}

/// What can stop the experiment.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExperimentError {
    /// The map has no closed route, or one too short to drive.
    #[error("map `{map}`: {reason}")]
    Route {
        /// Map name.
        map: String,
        /// Why.
        reason: String,
    },
    /// The simulator refused something.
    #[error(transparent)]
    Sim(#[from] iw_sim::SimError),
    /// The map cannot be localized on.
    #[error(transparent)]
    Localization(#[from] iw_localization::LocalizationError),
    /// Writing results failed.
    #[error("writing {path}: {source}")]
    Io {
        /// File.
        path: String,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
    /// A plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] iw_plot::PlotError),
}

/// How the experiment runs.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Config {
    /// Simulated minutes per tracking drive.
    pub minutes: f64,
    /// Tracking drives (seeds `seed .. seed + seeds`).
    pub seeds: usize,
    /// Global localization runs (seeds `seed .. seed + global_runs`).
    pub global_runs: usize,
    /// Blind runs (seeds `seed .. seed + blind_runs`, each with every [`BLIND_LEARN_M`]).
    pub blind_runs: usize,
    /// How far each global run drives, m (convergence must come within 5 m; the rest checks
    /// that it never claims a wrong pose).
    pub global_drive_m: f64,
    /// Visual odometry on every this many periods (0: no visual odometry).
    pub vo_every: usize,
    /// Cruise speed, m/s.
    pub speed_mps: f64,
    /// Control period, s.
    pub dt_s: f64,
    /// Chairs drive back and forth along the map's routes named `mover...` (obstacles that are
    /// not on the map).
    pub movers: bool,
    /// First seed.
    pub seed: u64,
}

impl Default for Config {
    /// 30 minutes, 1 drive, 50 global runs of 12 m, 20 blind runs, VO at 10 Hz, 0.5 m/s, 50 ms,
    /// movers.
    fn default() -> Self {
        Config {
            minutes: 30.0,
            seeds: 1,
            global_runs: 50,
            blind_runs: 20,
            global_drive_m: 12.0,
            vo_every: 2,
            speed_mps: 0.5,
            dt_s: 0.05,
            movers: true,
            seed: 1,
        }
    }
}

/// The five poses at one instant of a tracking drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Simulated time, s.
    pub time_s: f64,
    /// Exact pose.
    pub truth: Pose2,
    /// Wheel odometry.
    pub wheel: Pose2,
    /// Visual odometry chained from the start.
    pub vo: Pose2,
    /// EKF of wheel and visual odometry, with the wheels' bias in its state.
    pub fused: Pose2,
    /// The map-based localizer.
    pub localized: Pose2,
    /// The localizer's NEES (x, y, theta).
    pub nees: f64,
    /// Each component's squared error over its variance (x, y, theta): 1 on average if
    /// consistent; where the NEES misses.
    pub nees_components: [f64; 3],
}

/// One tracking drive.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    /// Seed.
    pub seed: u64,
    /// One sample per simulated second.
    pub samples: Vec<Sample>,
    /// Position errors at every period: wheel, vo, fused, localized (sum of squares, max).
    pub errors: [(f64, f64); 4],
    /// Periods.
    pub periods: usize,
    /// Ground distance driven, m.
    pub distance_m: f64,
    /// Visual odometry frames processed.
    pub vo_frames: usize,
    /// Landmark sightings fused by the localizer (in the camera's frames, when the map has
    /// landmarks).
    pub landmark_sightings: usize,
    /// Localizer time per period (predict and range update), µs, every period.
    pub localizer_us: Vec<f64>,
    /// Collisions of the driven chair.
    pub collisions: u64,
    /// Times the localizer lost the pose and searched.
    pub searches: u64,
}

/// How well a chair knows a start it was given: 1 cm and 0.6° at one standard deviation.
fn known_start_cov() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 1e-4))
}

/// A chair set down at a random point of the route, as [`set_down`] leaves it.
struct SetDown {
    s: Setup,
    /// Where on the route it was set down, as a fraction of the route's length.
    fraction: f64,
    /// Its true start pose.
    start: Pose2,
    /// Wheel odometry that has read the first sensor frame.
    wheels: WheelOdometry,
}

/// Sets a chair down at a random point of the route, drawn from `seed ^ salt` so that each kind
/// of run starts somewhere else. Its wheel odometry starts at the true pose when `known_start`,
/// at the origin otherwise (a chair that does not know where it is).
fn set_down(
    map: &Map,
    config: &Config,
    seed: u64,
    salt: u64,
    known_start: bool,
) -> Result<SetDown, ExperimentError> {
    let route = tour(map)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ salt);
    let fraction: f64 = rng.random();
    let s = setup(map, route, fraction, config, seed);
    let start = pose2(&lock(&s.world).pose(s.id)?);
    let mut wheels = WheelOdometry::new(
        drive_params(&s.spec),
        if known_start { start } else { Pose2::default() },
    );
    let first = lock(&s.world).sensors(s.id)?.clone();
    wheels.update(first.left_ticks, first.right_ticks);
    Ok(SetDown {
        s,
        fraction,
        start,
        wheels,
    })
}

/// One global localization run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GlobalRun {
    /// Seed.
    pub seed: u64,
    /// Distance driven when the localizer first reported tracking, m.
    pub distance_m: Option<f64>,
    /// Position and heading error then, m and deg.
    pub error_at_fix: Option<(f64, f64)>,
    /// Converged as the protocol says.
    pub converged: bool,
    /// Largest position error while reporting tracking, m.
    pub max_tracking_error_m: f64,
    /// Reported tracking while more than 30 cm off.
    pub falsely_confident: bool,
}

/// Everything measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Tracking drives.
    pub drives: Vec<Drive>,
    /// Global runs.
    pub global: Vec<GlobalRun>,
    /// Blind runs ([`BLIND_LEARN_M`] each seed).
    pub blind: Vec<BlindRun>,
    /// Map name.
    pub map: String,
    /// Route driven.
    pub route: Vec<Point2<f64>>,
    /// Configuration.
    pub config: Config,
}

/// Progress: simulated seconds of tracking drives done, global runs done.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress {
    /// Simulated seconds of one drive (reported every simulated minute).
    DriveSeconds(f64),
    /// One global run finished.
    GlobalRun,
    /// One blind run finished.
    BlindRun,
}

/// The route to drive: the map's first closed route.
pub fn tour(map: &Map) -> Result<&Route, ExperimentError> {
    let route = map.closed_route().ok_or_else(|| ExperimentError::Route {
        map: map.name.clone(),
        reason: "no closed route (`route NAME closed ...`) to drive round".into(),
    })?;
    if route.points.len() < 2 {
        return Err(ExperimentError::Route {
            map: map.name.clone(),
            reason: format!("route `{}` has fewer than 2 points", route.name),
        });
    }
    Ok(route)
}

fn pose2(t: &Isometry2<f64>) -> Pose2 {
    Pose2::new(t.translation.x, t.translation.y, t.rotation.angle())
}

/// Steers a chair round a closed route on its exact pose: turns in place towards the next
/// waypoint when it points more than 35 degrees away, else drives at speed with a heading
/// controller, slowing as it nears the waypoint.
#[derive(Debug, Clone)]
struct Driver {
    points: Vec<Point2<f64>>,
    next: usize,
    speed_mps: f64,
    track_m: f64,
}

impl Driver {
    fn speeds(&mut self, pose: &Isometry2<f64>) -> WheelSpeeds {
        let here = Point2::from(pose.translation.vector);
        if (self.points[self.next] - here).norm() < 0.15 {
            self.next = (self.next + 1) % self.points.len();
        }
        let to = self.points[self.next] - here;
        let error = wrap_angle(to.y.atan2(to.x) - pose.rotation.angle());
        let (v, omega) = if error.abs() > 0.6 {
            (0.0, 0.5 * error.signum())
        } else {
            (
                self.speed_mps.min(0.8 * to.norm() + 0.1),
                (2.0 * error).clamp(-0.6, 0.6),
            )
        };
        WheelSpeeds {
            left_mps: v - omega * self.track_m / 2.0,
            right_mps: v + omega * self.track_m / 2.0,
        }
    }
}

/// The pose `fraction` (0..1) of the way round the closed route, facing along it, and the index
/// of the waypoint it drives to next.
fn along_route(route: &Route, fraction: f64) -> (Isometry2<f64>, usize) {
    let n = route.points.len();
    let legs: Vec<f64> = (0..n)
        .map(|i| (route.points[(i + 1) % n] - route.points[i]).norm())
        .collect();
    let mut left = fraction.rem_euclid(1.0) * legs.iter().sum::<f64>();
    for (i, leg) in legs.iter().enumerate() {
        if left <= *leg || i + 1 == n {
            let (a, b) = (route.points[i], route.points[(i + 1) % n]);
            let dir = (b - a).normalize();
            let p = a + dir * left.min(*leg);
            return (Isometry2::new(p.coords, dir.y.atan2(dir.x)), (i + 1) % n);
        }
        left -= leg;
    }
    (Isometry2::identity(), 0)
}

struct Setup {
    world: SharedWorld,
    id: ChairId,
    spec: ChairSpec,
    drivers: Vec<(ChairId, Driver)>,
}

fn setup(map: &Map, route: &Route, start_fraction: f64, config: &Config, seed: u64) -> Setup {
    let mut world = World::new(map.clone(), seed);
    let spec = ChairSpec::default();
    let mut drivers = Vec::new();
    let mut add = |world: &mut World, route: &Route, fraction: f64| {
        let (pose, next) = along_route(route, fraction);
        let id = world.add_chair(spec.clone(), pose, ChairKind::Simulated);
        let driver = Driver {
            points: route.points.clone(),
            next,
            speed_mps: config.speed_mps,
            track_m: spec.geometry.track_m,
        };
        drivers.push((id, driver));
        id
    };
    let id = add(&mut world, route, start_fraction);
    if config.movers {
        for mover in map.routes.iter().filter(|r| r.name.starts_with("mover")) {
            // an open route is driven there and back: the driver cycles through its points
            add(&mut world, mover, 0.0);
        }
    }
    Setup {
        world: iw_sim::shared(world),
        id,
        spec,
        drivers,
    }
}

fn lock(world: &SharedWorld) -> std::sync::MutexGuard<'_, World> {
    world.lock().unwrap_or_else(|p| p.into_inner())
}

/// Commands every chair and steps the world one period.
fn step_world(s: &mut Setup, dt_s: f64) -> Result<(), ExperimentError> {
    let mut world = lock(&s.world);
    for (id, driver) in &mut s.drivers {
        let pose = world.pose(*id)?;
        world.command(*id, driver.speeds(&pose))?;
    }
    iw_sim::step(&mut world, dt_s);
    Ok(())
}

/// The error of `estimate` against `truth` (x, y, theta), the heading's wrapped.
fn pose_error(estimate: &Pose2, truth: &Pose2) -> Vector3<f64> {
    Vector3::new(
        estimate.x - truth.x,
        estimate.y - truth.y,
        wrap_angle(estimate.theta - truth.theta),
    )
}

/// NEES of `estimate` with `covariance` against `truth`.
pub fn nees(estimate: &Pose2, covariance: &Matrix3<f64>, truth: &Pose2) -> f64 {
    let e = pose_error(estimate, truth);
    covariance
        .try_inverse()
        .map_or(f64::INFINITY, |inv| (e.transpose() * inv * e)[0])
}

/// Each component's squared error over its variance (x, y, theta).
pub fn nees_components(estimate: &Pose2, covariance: &Matrix3<f64>, truth: &Pose2) -> [f64; 3] {
    let e = pose_error(estimate, truth);
    std::array::from_fn(|k| e[k] * e[k] / covariance[(k, k)])
}

fn position_error(a: &Pose2, b: &Pose2) -> f64 {
    ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt()
}

/// One tracking drive.
pub fn drive(
    map: &Map,
    lmap: &Arc<LocalizationMap>,
    config: &Config,
    seed: u64,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Drive, ExperimentError> {
    let route = tour(map)?;
    let mut s = setup(map, route, 0.0, config, seed);
    let params = drive_params(&s.spec);
    let start = pose2(&lock(&s.world).pose(s.id)?);
    let start_cov = known_start_cov();
    let mut wheels = WheelOdometry::new(params, start);
    // the wheel + VO baseline with the wheels' bias in its state, as the perception agent's
    // filter without a map has it: like for like with `localized`, whose filter has it too
    let mut fusion =
        OdometryFusion::new(start, start_cov, params.alpha).with_bias(WheelBias::WHEELCHAIR);
    let mut localizer = Localizer::new(
        lmap.clone(),
        localizer_config(&s.spec),
        Some((start, start_cov)),
    );
    let mut camera = if config.vo_every > 0 {
        Some(SimCamera::new(s.world.clone(), s.id)?)
    } else {
        None
    };
    let mut vo = camera.as_ref().map(|c| {
        VisualOdometry::new(
            sim_vo_config(DetectorKind::LsacSurf, Pipeline::Keyframe),
            *c.intrinsics(),
        )
    });
    let t_base_camera = camera.as_ref().map(|c| c.t_base_camera());
    // the per-frame covariance of the odometry trial (iw_sim::vo::TrialConfig)
    let vo_noise = Matrix3::from_diagonal(&Vector3::new(
        0.004f64.powi(2),
        0.004f64.powi(2),
        0.002f64.powi(2),
    ));
    let (mut vo_pose, mut last_camera) = (start, None);
    let first = lock(&s.world).sensors(s.id)?.clone();
    wheels.update(first.left_ticks, first.right_ticks);
    let periods = (config.minutes * 60.0 / config.dt_s).round() as usize;
    let per_second = (1.0 / config.dt_s).round().max(1.0) as usize;
    let mut result = Drive {
        seed,
        samples: Vec::new(),
        errors: [(0.0, 0.0); 4],
        periods,
        distance_m: 0.0,
        vo_frames: 0,
        landmark_sightings: 0,
        localizer_us: Vec::with_capacity(periods),
        collisions: 0,
        searches: 0,
    };
    for k in 1..=periods {
        step_world(&mut s, config.dt_s)?;
        let sensed = lock(&s.world).sensors(s.id)?.clone();
        let timer = Instant::now();
        if let Some(step) = wheels.update(sensed.left_ticks, sensed.right_ticks) {
            fusion.predict(&step);
            localizer.predict(&step);
        }
        localizer.update_ranges(&sensed.laser_m, &sensed.sonar_m);
        result
            .localizer_us
            .push(timer.elapsed().as_secs_f64() * 1e6);
        if let (Some(camera), Some(vo), Some(t_base_camera)) =
            (camera.as_mut(), vo.as_mut(), t_base_camera.as_ref())
            && k % config.vo_every == 0
            && let Some(Ok(frame)) = camera.next_frame()
        {
            // the map's landmarks, where it has them, seen in the same frames as VO's
            if !map.landmarks.is_empty() {
                for (id, p) in markers_in(&frame, camera.intrinsics(), t_base_camera) {
                    if localizer.update_landmark(u32::from(id), p.coords.norm(), p.y.atan2(p.x)) {
                        result.landmark_sightings += 1;
                    }
                }
            }
            if let Ok((stamped, _)) = vo.process(&frame) {
                result.vo_frames += 1;
                if let Some(last) = last_camera {
                    let motion = planar_motion(
                        t_base_camera,
                        &(nalgebra::Isometry3::inverse(&last) * stamped.t_world_camera),
                    );
                    vo_pose = vo_pose.compose(&motion);
                    fusion.update_visual(&motion, &vo_noise);
                    localizer.update_visual(&motion, &vo_noise);
                }
                last_camera = Some(stamped.t_world_camera);
            }
        }
        let truth = pose2(&lock(&s.world).pose(s.id)?);
        let estimates = [wheels.pose(), vo_pose, fusion.pose(), localizer.pose()];
        for (acc, e) in result.errors.iter_mut().zip(&estimates) {
            let err = position_error(e, &truth);
            acc.0 += err * err;
            acc.1 = acc.1.max(err);
        }
        if k % per_second == 0 {
            let covariance = localizer.covariance();
            result.samples.push(Sample {
                time_s: k as f64 * config.dt_s,
                truth,
                wheel: estimates[0],
                vo: estimates[1],
                fused: estimates[2],
                localized: estimates[3],
                nees: nees(&estimates[3], &covariance, &truth),
                nees_components: nees_components(&estimates[3], &covariance, &truth),
            });
        }
        if k % (60 * per_second) == 0 {
            progress(Progress::DriveSeconds(60.0));
        }
    }
    let world = lock(&s.world);
    result.distance_m = world.distance_m(s.id)?;
    result.collisions = world.collisions(s.id)?;
    result.searches = localizer.searches();
    Ok(result)
}

/// One global localization run: a chair at a random point of the route with no pose.
pub fn global_run(
    map: &Map,
    lmap: &Arc<LocalizationMap>,
    config: &Config,
    seed: u64,
) -> Result<GlobalRun, ExperimentError> {
    let SetDown {
        mut s, mut wheels, ..
    } = set_down(map, config, seed, 0x5EED, false)?;
    let mut localizer = Localizer::new(lmap.clone(), localizer_config(&s.spec), None);
    let mut run = GlobalRun {
        seed,
        distance_m: None,
        error_at_fix: None,
        converged: false,
        max_tracking_error_m: 0.0,
        falsely_confident: false,
    };
    let max_periods = (config.global_drive_m / config.speed_mps * 4.0 / config.dt_s) as usize;
    for _ in 0..max_periods {
        step_world(&mut s, config.dt_s)?;
        let (sensed, truth, distance_m) = {
            let w = lock(&s.world);
            (
                w.sensors(s.id)?.clone(),
                pose2(&w.pose(s.id)?),
                w.distance_m(s.id)?,
            )
        };
        if let Some(step) = wheels.update(sensed.left_ticks, sensed.right_ticks) {
            localizer.predict(&step);
        }
        localizer.update_ranges(&sensed.laser_m, &sensed.sonar_m);
        if localizer.status() == Status::Tracking {
            let estimate = localizer.pose();
            let error_m = position_error(&estimate, &truth);
            if run.distance_m.is_none() {
                let heading_deg = wrap_angle(estimate.theta - truth.theta).abs().to_degrees();
                run.distance_m = Some(distance_m);
                run.error_at_fix = Some((error_m, heading_deg));
                run.converged = distance_m <= 5.0 && error_m <= 0.10 && heading_deg <= 3.0;
            }
            run.max_tracking_error_m = run.max_tracking_error_m.max(error_m);
            run.falsely_confident |= error_m > 0.30;
        }
        if distance_m >= config.global_drive_m {
            break;
        }
    }
    Ok(run)
}

/// One kidnapped-robot run: the chair tracks from its true start, is carried to the opposite
/// side of the route after [`KIDNAP_AFTER_M`], and drives on up to [`Config::global_drive_m`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KidnapRun {
    /// Seed.
    pub seed: u64,
    /// How far the chair was carried, m.
    pub carried_m: f64,
    /// Distance driven after the kidnap until the localizer gave up its pose and searched, m
    /// (`None`: it never did).
    pub noticed_m: Option<f64>,
    /// Distance driven after the kidnap until it tracked again within 10 cm, m.
    pub recovered_m: Option<f64>,
    /// Largest error while it reported tracking after it had searched, m.
    pub max_error_after_fix_m: f64,
}

/// Distance driven before the chair is carried away, m.
pub const KIDNAP_AFTER_M: f64 = 2.0;

/// Runs one kidnapped-robot case (wheels, laser and sonars; no VO).
pub fn kidnap_run(
    map: &Map,
    lmap: &Arc<LocalizationMap>,
    config: &Config,
    seed: u64,
) -> Result<KidnapRun, ExperimentError> {
    let SetDown {
        mut s,
        fraction,
        start,
        mut wheels,
    } = set_down(map, config, seed, 0x0C4A1, true)?;
    let route = tour(map)?;
    let mut localizer = Localizer::new(
        lmap.clone(),
        localizer_config(&s.spec),
        Some((start, known_start_cov())),
    );
    let mut run = KidnapRun {
        seed,
        carried_m: 0.0,
        noticed_m: None,
        recovered_m: None,
        max_error_after_fix_m: 0.0,
    };
    let mut kidnapped_at: Option<f64> = None;
    let total_m = KIDNAP_AFTER_M + config.global_drive_m;
    let max_periods = (total_m / config.speed_mps * 4.0 / config.dt_s) as usize;
    for _ in 0..max_periods {
        step_world(&mut s, config.dt_s)?;
        let mut distance_m = lock(&s.world).distance_m(s.id)?;
        if kidnapped_at.is_none() && distance_m >= KIDNAP_AFTER_M {
            let (to, next) = along_route(route, fraction + 0.5);
            let mut w = lock(&s.world);
            let from = w.pose(s.id)?;
            w.place(s.id, to)?;
            run.carried_m = (to.translation.vector - from.translation.vector).norm();
            if let Some((_, driver)) = s.drivers.iter_mut().find(|(id, _)| *id == s.id) {
                driver.next = next;
            }
            distance_m = w.distance_m(s.id)?;
            kidnapped_at = Some(distance_m);
        }
        let (sensed, truth) = {
            let w = lock(&s.world);
            (w.sensors(s.id)?.clone(), pose2(&w.pose(s.id)?))
        };
        if let Some(step) = wheels.update(sensed.left_ticks, sensed.right_ticks) {
            localizer.predict(&step);
        }
        localizer.update_ranges(&sensed.laser_m, &sensed.sonar_m);
        let Some(at) = kidnapped_at else { continue };
        let since = distance_m - at;
        if localizer.status() == Status::Searching && run.noticed_m.is_none() {
            run.noticed_m = Some(since);
        }
        if run.noticed_m.is_some() && localizer.status() == Status::Tracking {
            let error_m = position_error(&localizer.pose(), &truth);
            if run.recovered_m.is_none() && error_m <= 0.10 {
                run.recovered_m = Some(since);
            }
            run.max_error_after_fix_m = run.max_error_after_fix_m.max(error_m);
        }
        if since >= config.global_drive_m {
            break;
        }
    }
    Ok(run)
}

/// Where a blind localizer ended up: its error and what its covariance said.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BlindEnd {
    /// Position error when the blind stretch ends, m.
    pub error_m: f64,
    /// Twice the standard deviation along the covariance's longest x-y axis then, m.
    pub two_sigma_m: f64,
    /// Trace of the x-y covariance then, m² (what the cognitive agent compares with its
    /// landmark threshold).
    pub trace_m2: f64,
    /// Share of the once-a-second samples of the blind stretch whose position NEES (2 degrees of
    /// freedom) is under its 95 % bound, [`POSITION_NEES_95`].
    pub inside_rate: f64,
}

/// One blind run: the chair tracks with its laser for `learn_m`, then the laser is silent for
/// [`BLIND_M`] (wheels and sonars read on; no VO, no landmarks). Two localizers see the same
/// readings: the default one, which estimates the wheels' bias ([`WheelBias`]), and one
/// without the bias states (the motion model's random noise only).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BlindRun {
    /// Seed.
    pub seed: u64,
    /// Metres driven with the laser before it went silent.
    pub learn_m: f64,
    /// With the bias states.
    pub modelled: BlindEnd,
    /// Without them.
    pub unmodelled: BlindEnd,
}

/// How far a blind run drives without its laser, m: about a corridor's length.
pub const BLIND_M: f64 = 10.0;

/// The 95 % bound of a chi-square with 2 degrees of freedom.
pub const POSITION_NEES_95: f64 = 5.991;

/// Runs one blind case from a random point of the route (see [`BlindRun`]).
pub fn blind_run(
    map: &Map,
    lmap: &Arc<LocalizationMap>,
    config: &Config,
    seed: u64,
    learn_m: f64,
) -> Result<BlindRun, ExperimentError> {
    let SetDown {
        mut s,
        start,
        mut wheels,
        ..
    } = set_down(map, config, seed, 0xB11D, true)?;
    let modelled = localizer_config(&s.spec);
    let unmodelled = iw_localization::LocalizerConfig {
        wheel_bias: WheelBias::NONE,
        ..modelled.clone()
    };
    let mut localizers = [modelled, unmodelled]
        .map(|c| Localizer::new(lmap.clone(), c, Some((start, known_start_cov()))));
    let per_second = (1.0 / config.dt_s).round().max(1.0) as usize;
    let mut inside = [0usize; 2];
    let mut samples = 0usize;
    let max_periods = ((learn_m + BLIND_M) / config.speed_mps * 4.0 / config.dt_s) as usize;
    let mut truth = start;
    for k in 1..=max_periods {
        step_world(&mut s, config.dt_s)?;
        let (sensed, distance_m) = {
            let w = lock(&s.world);
            truth = pose2(&w.pose(s.id)?);
            (w.sensors(s.id)?.clone(), w.distance_m(s.id)?)
        };
        let blind = distance_m >= learn_m;
        let laser: &[f64] = if blind { &[] } else { &sensed.laser_m };
        let step = wheels.update(sensed.left_ticks, sensed.right_ticks);
        for l in &mut localizers {
            if let Some(step) = &step {
                l.predict(step);
            }
            l.update_ranges(laser, &sensed.sonar_m);
        }
        if blind && k % per_second == 0 {
            samples += 1;
            for (n, l) in inside.iter_mut().zip(&localizers) {
                *n += usize::from(position_nees(l, &truth) <= POSITION_NEES_95);
            }
        }
        if distance_m >= learn_m + BLIND_M {
            break;
        }
    }
    let end = |l: &Localizer, inside: usize| {
        let c = l.covariance().fixed_view::<2, 2>(0, 0).into_owned();
        let largest = c.symmetric_eigenvalues().max().max(0.0);
        BlindEnd {
            error_m: position_error(&l.pose(), &truth),
            two_sigma_m: 2.0 * largest.sqrt(),
            trace_m2: c.trace(),
            inside_rate: inside as f64 / samples.max(1) as f64,
        }
    };
    Ok(BlindRun {
        seed,
        learn_m,
        modelled: end(&localizers[0], inside[0]),
        unmodelled: end(&localizers[1], inside[1]),
    })
}

/// NEES of the localizer's x-y position against `truth`.
fn position_nees(l: &Localizer, truth: &Pose2) -> f64 {
    let p = l.pose();
    let e = nalgebra::Vector2::new(p.x - truth.x, p.y - truth.y);
    l.covariance()
        .fixed_view::<2, 2>(0, 0)
        .into_owned()
        .try_inverse()
        .map_or(f64::INFINITY, |inv| (e.transpose() * inv * e)[0])
}

/// Metres driven with the laser before a blind run's laser goes silent: none (the bias is only
/// the prior) and a lap of the sample building's corridor and rooms (the bias observed).
pub const BLIND_LEARN_M: [f64; 2] = [0.0, 30.0];

/// Runs the tracking drives and the global runs (in parallel, deterministic per seed).
pub fn run(
    map: &Map,
    config: &Config,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Report, ExperimentError> {
    let route = tour(map)?.points.clone();
    let lmap = Arc::new(localization_map(map)?);
    let drives = (0..config.seeds as u64)
        .into_par_iter()
        .map(|i| drive(map, &lmap, config, config.seed + i, progress))
        .collect::<Result<Vec<_>, _>>()?;
    let global = (0..config.global_runs as u64)
        .into_par_iter()
        .map(|i| {
            let run = global_run(map, &lmap, config, config.seed + i);
            progress(Progress::GlobalRun);
            run
        })
        .collect::<Result<Vec<_>, _>>()?;
    let blind = (0..config.blind_runs as u64)
        .into_par_iter()
        .flat_map_iter(|i| BLIND_LEARN_M.map(|learn_m| (i, learn_m)))
        .map(|(i, learn_m)| {
            let run = blind_run(map, &lmap, config, config.seed + i, learn_m);
            progress(Progress::BlindRun);
            run
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Report {
        drives,
        global,
        blind,
        map: map.name.clone(),
        route,
        config: config.clone(),
    })
}
