//! The landmark detour end to end (thesis 3.8, issue 19): real agents in the in-process fleet,
//! the chair's laser blinded so its localizer can only dead-reckon (wheels and visual
//! odometry). The perception agent says it dropped the laser and the chair first goes past the
//! nearest landmark; then the covariance, honest while blind, grows past the deployment's
//! default threshold, the chair detours to a landmark again, the perception agent reads the
//! marker in the simulator's rendered camera, and its error against the simulator's true pose
//! and its covariance drop.

use std::time::{Duration, Instant};

use iw_fleet::{ChairConfig, Fleet, FleetOptions};
use iw_sim::Map;
use nalgebra::{Isometry2, Point2, Vector2};

const SAMPLE: &str = include_str!("../../maps/sample-building.map");
const STEP: Duration = Duration::from_millis(50);
const CHAIR: &str = "chair-0";

/// One control period of the run: simulated time, the true position, the published estimate and
/// the trace of its x-y covariance.
#[derive(Debug, Clone, Copy)]
struct Sample {
    t_s: f64,
    truth: Point2<f64>,
    error_m: f64,
    trace_m2: f64,
}

/// Drives chair-0 from the entrance to `place` with its laser blind from the start and the
/// landmark detour at `threshold_m2` (the default when `None`), for at most `max_s` (or until
/// the goal's answer), in real time; returns every period with an estimate, and the fleet.
fn drive(place: &str, threshold_m2: Option<f64>, max_s: f64) -> (Vec<Sample>, Fleet) {
    let map = Map::parse(SAMPLE, "sample-building.map").unwrap();
    let chair = ChairConfig {
        name: CHAIR.into(),
        t_world_body: Isometry2::new(Vector2::new(1.0, 6.0), 0.0),
    };
    let options = FleetOptions {
        visual_odometry: true,
        landmark_uncertainty_m2: threshold_m2,
        ..FleetOptions::default()
    };
    let mut fleet = Fleet::with_options(map, 5, &[chair], options).unwrap();
    fleet.set_laser_blind(CHAIR, true).unwrap();
    fleet.goal_place(CHAIR, place).unwrap();
    let mut samples = Vec::new();
    let start = Instant::now();
    while fleet.time_s() < max_s {
        fleet.step(STEP);
        // No faster than real time: the perception agent reads the camera on its own thread at
        // the pace it can (as on the chair); stepped faster, the simulated chair outruns its
        // camera and passes the marker between two frames.
        let due = Duration::from_secs_f64(fleet.time_s());
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        let truth = fleet.snapshot().chairs[0].pose;
        let truth = Point2::new(truth[0], truth[1]);
        if let Some(estimate) = fleet.estimate(CHAIR).unwrap() {
            let c = estimate.covariance;
            samples.push(Sample {
                t_s: fleet.time_s(),
                truth,
                error_m: (Point2::new(estimate.x_m, estimate.y_m) - truth).norm(),
                trace_m2: c[(0, 0)] + c[(1, 1)],
            });
        }
        if fleet
            .goal_events()
            .iter()
            .any(|e| e.performative != "AGREE")
        {
            break;
        }
    }
    (samples, fleet)
}

/// The deployment's detour threshold, which the test does not set.
const THRESHOLD_M2: f64 = iw_fleet::compose::LANDMARK_UNCERTAINTY_M2;

fn print(samples: &[Sample]) {
    for s in samples.iter().step_by(20) {
        println!(
            "{:6.1} s  ({:5.2}, {:5.2})  error {:5.3} m  trace {:.4} m2",
            s.t_s, s.truth.x, s.truth.y, s.error_m, s.trace_m2
        );
    }
}

#[test]
fn a_blind_chair_detours_to_a_landmark_and_the_marker_resets_its_error() {
    let (samples, fleet) = drive("dining-hall", None, 60.0);
    print(&samples);
    println!("{:?}", fleet.goal_events());
    let stops: Vec<Point2<f64>> = fleet
        .building()
        .plan
        .landmarks
        .iter()
        .map(|l| l.at)
        .collect();
    // the covariance passes the threshold (dead reckoning only)
    let crossed = samples
        .iter()
        .position(|s| s.trace_m2 > THRESHOLD_M2)
        .expect("the covariance never passed the threshold");
    let before = samples[crossed];
    // until then the chair dead-reckoned (past the first landmark, as the silent laser had it),
    // and its covariance covered its error: a consistent 2-D estimate is within 2 sqrt(trace)
    // 98 % of the time (95 % measured; the bar leaves room for a loaded machine's camera rate)
    let covered = samples[..crossed]
        .iter()
        .filter(|s| s.error_m <= 2.0 * s.trace_m2.sqrt())
        .count();
    println!("error within 2 sigma on {covered} of {crossed} periods before the crossing");
    assert!(
        covered as f64 >= 0.9 * crossed as f64,
        "the covariance did not cover the error: {covered} of {crossed} periods"
    );
    // the chair then goes to a landmark's stop
    let arrived = samples[crossed..]
        .iter()
        .position(|s| stops.iter().any(|p| (p - s.truth).norm() < 0.4))
        .map(|i| crossed + i)
        .expect("the chair never went to a landmark");
    // what the marker did: the least covariance within 10 s of getting there
    let after = samples[arrived..]
        .iter()
        .take_while(|s| s.t_s < samples[arrived].t_s + 10.0)
        .min_by(|a, b| a.trace_m2.total_cmp(&b.trace_m2))
        .copied()
        .unwrap();
    let peak = samples[crossed..arrived]
        .iter()
        .map(|s| s.error_m)
        .fold(before.error_m, f64::max);
    println!(
        "crossed {before:?}\narrived {:?}\nafter {after:?}\nlargest error on the way {peak:.3} m",
        samples[arrived]
    );
    // the same drive with no detour for the uncertainty: nothing resets the error again
    let (plain, _) = drive("dining-hall", Some(1e3), after.t_s + 0.1);
    print(&plain);
    let without = plain
        .iter()
        .min_by(|a, b| {
            (a.t_s - after.t_s)
                .abs()
                .total_cmp(&(b.t_s - after.t_s).abs())
        })
        .copied()
        .unwrap();
    println!("the same time without the detour: {without:?}");
    assert!(
        after.trace_m2 < before.trace_m2 / 2.0 && after.trace_m2 < without.trace_m2 / 3.0,
        "the covariance did not drop at the landmark: {:.4} m² when the detour began, {:.4} m² \
         after, {:.4} m² without the detour",
        before.trace_m2,
        after.trace_m2,
        without.trace_m2
    );
    assert!(
        after.error_m < 0.05 && after.error_m < peak / 2.0 && after.error_m < without.error_m / 3.0,
        "the error was not reset: {peak:.3} m on the way, {:.3} m after the sightings, {:.3} m \
         without the detour",
        after.error_m,
        without.error_m
    );
}
