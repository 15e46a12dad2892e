//! What the landmark tests share: a chair driven to a place in real time with visual odometry,
//! and every control period's truth against the pose its perception agent published.
#![allow(dead_code)] // each test binary uses part of it

use std::time::{Duration, Instant};

use iw_cognitive::agent::worst_variance_m2;
use iw_fleet::{ChairConfig, Fleet, FleetOptions};
use iw_sim::Map;
use nalgebra::{Isometry2, Matrix2, Point2, Vector2};

pub const STEP: Duration = Duration::from_millis(50);
pub const CHAIR: &str = "chair-0";

/// The deployment's detour threshold (on the worst direction's variance), which the tests do
/// not set.
pub const THRESHOLD_M2: f64 = iw_fleet::compose::LANDMARK_UNCERTAINTY_M2;

/// One control period of a drive: simulated time, the true position, the published estimate and
/// its x-y covariance.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub t_s: f64,
    pub truth: Point2<f64>,
    /// The true positions when the agents read the body this period (before the world moved)
    /// and the period before: the published estimate is of one of them (the perception agent
    /// publishes every second period), while `truth` is a period on (2.5 cm at 0.5 m/s).
    pub sensed: [Point2<f64>; 2],
    pub estimate: Point2<f64>,
    pub covariance: Matrix2<f64>,
    /// Its variance in the worst direction, m²: what the cognitive agent decides the detour on.
    pub worst_m2: f64,
}

impl Sample {
    /// The estimate's error (estimate less truth), m.
    pub fn error(&self) -> Vector2<f64> {
        self.estimate - self.truth
    }

    pub fn error_m(&self) -> f64 {
        self.error().norm()
    }

    /// The estimate's error against the pose it estimates (the nearer of the two reads), m.
    pub fn error_at_read_m(&self) -> f64 {
        self.sensed
            .iter()
            .map(|p| (self.estimate - p).norm())
            .fold(f64::INFINITY, f64::min)
    }

    pub fn trace_m2(&self) -> f64 {
        self.covariance.trace()
    }
}

/// How a test drive is set up.
pub struct Drive<'a> {
    pub map: &'a Map,
    pub seed: u64,
    pub start: Isometry2<f64>,
    pub place: &'a str,
    /// The laser is blind from the start.
    pub blind: bool,
    /// The detour threshold; `None`: the deployment's default.
    pub threshold_m2: Option<f64>,
    /// Longest simulated time, s (the drive also ends at the goal's answer).
    pub max_s: f64,
}

impl Drive<'_> {
    /// Drives chair-0 from `start` to `place` with visual odometry, in real time (never faster:
    /// the perception agent reads the camera on its own thread at the pace it can, as on the
    /// chair; stepped faster, the simulated chair outruns its camera and passes a marker between
    /// two frames); returns every period with an estimate, and the fleet. Prints the goal's
    /// answers when the drive ends; with `RUST_LOG` set, the agents' log lines too (those on
    /// this thread, each under a `drive` span naming the seed and the threshold).
    pub fn run(&self) -> (Vec<Sample>, Fleet) {
        let _log = std::env::var("RUST_LOG").ok().map(|filter| {
            let subscriber = tracing_subscriber::fmt()
                .with_env_filter(tracing_subscriber::EnvFilter::new(format!(
                    "{filter},{}=info",
                    module_path!()
                )))
                .with_test_writer()
                .finish();
            tracing::subscriber::set_default(subscriber)
        });
        let _drive =
            tracing::info_span!("drive", seed = self.seed, threshold_m2 = ?self.threshold_m2)
                .entered();
        let chair = ChairConfig {
            name: CHAIR.into(),
            t_world_body: self.start,
        };
        let options = FleetOptions {
            visual_odometry: true,
            landmark_uncertainty_m2: self.threshold_m2,
            ..FleetOptions::default()
        };
        let mut fleet =
            Fleet::with_options(self.map.clone(), self.seed, &[chair], options).unwrap();
        fleet.set_laser_blind(CHAIR, self.blind).unwrap();
        fleet.goal_place(CHAIR, self.place).unwrap();
        let mut samples = Vec::new();
        let start = Instant::now();
        let at = |p: [f64; 3]| Point2::new(p[0], p[1]);
        let mut read_before = at(fleet.snapshot().chairs[0].pose);
        while fleet.time_s() < self.max_s {
            let read = at(fleet.snapshot().chairs[0].pose);
            fleet.step(STEP);
            let due = Duration::from_secs_f64(fleet.time_s());
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
            let truth = fleet.snapshot().chairs[0].pose;
            if let Some(estimate) = fleet.estimate(CHAIR).unwrap() {
                let c = estimate.covariance;
                samples.push(Sample {
                    t_s: fleet.time_s(),
                    truth: Point2::new(truth[0], truth[1]),
                    sensed: [read, read_before],
                    estimate: Point2::new(estimate.x_m, estimate.y_m),
                    covariance: c.fixed_view::<2, 2>(0, 0).into_owned(),
                    worst_m2: worst_variance_m2(&estimate),
                });
            }
            read_before = read;
            if fleet
                .goal_events()
                .iter()
                .any(|e| e.performative != "AGREE")
            {
                break;
            }
        }
        for e in fleet.goal_events() {
            println!(
                "seed {} goal answer at {:.1} s: {} from {} ({})",
                self.seed,
                e.time_s,
                e.performative,
                e.from,
                e.reason.as_deref().unwrap_or("no reason given")
            );
        }
        (samples, fleet)
    }
}

/// The landmark stops the chair's cognitive agent may detour to.
pub fn stops(fleet: &Fleet) -> Vec<Point2<f64>> {
    fleet
        .building()
        .plan
        .landmarks
        .iter()
        .map(|l| l.at)
        .collect()
}

/// Prints every second of a drive.
pub fn print(label: &str, samples: &[Sample]) {
    for s in samples.iter().step_by(20) {
        println!(
            "{label} {:6.1} s  ({:5.2}, {:5.2})  error {:5.3} m (at the read {:5.3} m)  trace {:.4} m2  worst {:.4} m2",
            s.t_s,
            s.truth.x,
            s.truth.y,
            s.error_m(),
            s.error_at_read_m(),
            s.trace_m2(),
            s.worst_m2
        );
    }
}

/// What a detour to a landmark did, read from a drive's samples.
#[derive(Debug, Clone, Copy)]
pub struct Detour {
    /// The first period whose worst direction's variance passed the threshold.
    pub crossed: Sample,
    /// Index of that period.
    pub crossed_at: usize,
    /// The first period after it at a landmark's stop (within 0.4 m).
    pub arrived: Sample,
    /// Index of that period.
    pub arrived_at: usize,
    /// The least covariance within 10 s of getting there.
    pub after: Sample,
    /// The largest error between the crossing and the arrival, m.
    pub peak_m: f64,
}

/// Finds the crossing of the threshold, the arrival at a stop and what the marker did; panics,
/// saying which, when the drive had none.
pub fn detour(samples: &[Sample], stops: &[Point2<f64>], threshold_m2: f64) -> Detour {
    let crossed_at = samples
        .iter()
        .position(|s| s.worst_m2 > threshold_m2)
        .expect("the covariance never passed the threshold");
    let arrived_at = samples[crossed_at..]
        .iter()
        .position(|s| stops.iter().any(|p| (p - s.truth).norm() < 0.4))
        .map(|i| crossed_at + i)
        .expect("the chair never went to a landmark");
    let arrived = samples[arrived_at];
    let after = samples[arrived_at..]
        .iter()
        .take_while(|s| s.t_s < arrived.t_s + 10.0)
        .min_by(|a, b| a.trace_m2().total_cmp(&b.trace_m2()))
        .copied()
        .unwrap();
    let crossed = samples[crossed_at];
    let peak_m = samples[crossed_at..arrived_at]
        .iter()
        .map(Sample::error_m)
        .fold(crossed.error_m(), f64::max);
    Detour {
        crossed,
        crossed_at,
        arrived,
        arrived_at,
        after,
        peak_m,
    }
}

/// The share of `samples` whose error (against the pose the agents read) is within
/// 2 sqrt(trace): a consistent 2-D estimate is there 98 % of the time.
pub fn covered(samples: &[Sample]) -> f64 {
    let n = samples
        .iter()
        .filter(|s| s.error_at_read_m() <= 2.0 * s.trace_m2().sqrt())
        .count();
    n as f64 / samples.len().max(1) as f64
}
