//! A blind drive: chair-0 leaves the sample building's entrance for the dining hall with its
//! laser blind from the start and no landmark on the map (so nothing resets its error), the
//! perception agent fusing wheels and LSAC-SURF visual odometry; prints, per seed, how often the
//! published covariance covered the error against the simulator's true pose.
//!
//! `cargo run --profile test -p iw-fleet --example blind_drive -- 1,2` (seeds; in real time,
//! up to 70 s each: the camera is read on the perception agent's own thread).

use std::time::{Duration, Instant};

use iw_fleet::{ChairConfig, Fleet, FleetOptions};
use iw_sim::Map;
use nalgebra::{Isometry2, Matrix2, Vector2};

const SAMPLE: &str = include_str!("../../maps/sample-building.map");
const CHAIR: &str = "chair-0";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds = std::env::args().nth(1).unwrap_or_else(|| "1".into());
    let seeds = seeds
        .split(',')
        .map(str::parse)
        .collect::<Result<Vec<u64>, _>>()
        .map_err(|e| format!("seeds: a comma-separated list of integers ({e})"))?;
    let text: String = SAMPLE
        .lines()
        .filter(|l| !l.starts_with("landmark"))
        .map(|l| format!("{l}\n"))
        .collect();
    for seed in seeds {
        let chair = ChairConfig {
            name: CHAIR.into(),
            t_world_body: Isometry2::new(Vector2::new(1.0, 6.0), 0.0),
        };
        let options = FleetOptions {
            visual_odometry: true,
            ..FleetOptions::default()
        };
        let map = Map::parse(&text, "sample-building without landmarks")?;
        let mut fleet = Fleet::with_options(map, seed, &[chair], options)?;
        fleet.set_laser_blind(CHAIR, true)?;
        fleet.goal_place(CHAIR, "dining-hall")?;
        let start = Instant::now();
        let (mut periods, mut within_2_sigma, mut nees_inside) = (0, 0, 0);
        let mut last = String::new();
        while fleet.time_s() < 70.0 {
            fleet.step(Duration::from_millis(50));
            if let Some(wait) = Duration::from_secs_f64(fleet.time_s()).checked_sub(start.elapsed())
            {
                std::thread::sleep(wait);
            }
            let truth = fleet.snapshot().chairs[0].pose;
            let Some(estimate) = fleet.estimate(CHAIR)? else {
                continue;
            };
            let c = estimate.covariance;
            let error = Vector2::new(estimate.x_m - truth[0], estimate.y_m - truth[1]);
            let p = Matrix2::new(c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]);
            let nees = p
                .try_inverse()
                .map_or(f64::INFINITY, |inv| (error.transpose() * inv * error)[0]);
            let two_sigma = 2.0 * (c[(0, 0)] + c[(1, 1)]).sqrt();
            periods += 1;
            within_2_sigma += usize::from(error.norm() <= two_sigma);
            // chi-square, 2 degrees of freedom, 95 %
            nees_inside += usize::from(nees <= 5.991);
            last = format!(
                "at {:.1} s: error {:.3} m, 2 sqrt(trace) {:.3} m, heading error {:.2} deg \
                 (sd {:.2} deg)",
                fleet.time_s(),
                error.norm(),
                two_sigma,
                nalgebra::UnitComplex::new(estimate.theta_rad - truth[2])
                    .angle()
                    .to_degrees(),
                c[(2, 2)].sqrt().to_degrees()
            );
            if fleet
                .goal_events()
                .iter()
                .any(|e| e.performative != "AGREE")
            {
                break;
            }
        }
        let answers: Vec<String> = fleet
            .goal_events()
            .iter()
            .map(|e| e.performative.clone())
            .collect();
        println!(
            "seed {seed}: error within 2 sqrt(trace) on {within_2_sigma} of {periods} periods, \
             position NEES inside its 95 % bound on {nees_inside}; last {last}; goal {answers:?}"
        );
    }
    Ok(())
}
