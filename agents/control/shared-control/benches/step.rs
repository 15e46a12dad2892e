//! Shared-control step time: the thesis's potential field against the VFH+ baseline and the
//! manual pass-through, on one period of a chair in a corridor near a doorway (16 sonars, a
//! 270-degree laser of 541 beams).

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use iw_shared_control::{
    Manual, PotentialField, PotentialFieldParams, SharedController, SharedInput, VelocityCommand,
    Vfh, VfhParams,
};
use nalgebra::{Isometry2, Point2, Vector2};

/// 16 sonars on a 1.1 m x 0.66 m chair: three per corner at 45 degrees, two lateral pairs.
fn mounts() -> Vec<Isometry2<f64>> {
    let q = std::f64::consts::FRAC_PI_4;
    let (x, y) = (0.55, 0.33);
    let mut m = Vec::new();
    for (sx, sy) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        let base = f64::atan2(sy, sx);
        for da in [-q / 2.0, q / 2.0] {
            m.push(Isometry2::new(Vector2::new(sx * x, sy * y), base + da));
        }
        m.push(Isometry2::new(
            Vector2::new(sx * 0.11, sy * y),
            sy * std::f64::consts::FRAC_PI_2,
        ));
        m.push(Isometry2::new(
            Vector2::new(sx * 0.33, sy * y),
            sy * std::f64::consts::FRAC_PI_2,
        ));
    }
    m
}

fn bench(c: &mut Criterion) {
    let sonar: Vec<Option<f64>> = (0..16)
        .map(|i| {
            if i % 3 == 0 {
                Some(0.25 + 0.03 * i as f64)
            } else {
                None
            }
        })
        .collect();
    // A corridor 1.4 m wide with a wall ending 1 m ahead on the right.
    let laser: Vec<Point2<f64>> = (0..541)
        .map(|i| {
            let a = (-135.0 + 0.5 * i as f64).to_radians();
            let r = if a.sin().abs() > 1e-3 {
                (0.7 / a.sin().abs()).min(4.0)
            } else {
                4.0
            };
            Point2::new(r * a.cos(), r * a.sin())
        })
        .collect();
    let input = SharedInput {
        user: VelocityCommand::new(0.7, 0.2),
        speed_mps: 0.7,
        sonar_m: &sonar,
        points_chair: &laser,
        motion: None,
    };
    let mut group = c.benchmark_group("shared_control_step");
    group
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1));
    let mut pf =
        PotentialField::new(PotentialFieldParams::default(), mounts()).expect("valid defaults");
    group.bench_function("potential_field", |b| {
        b.iter(|| pf.step(std::hint::black_box(&input)))
    });
    let mut vfh = Vfh::new(VfhParams::default(), mounts()).expect("valid defaults");
    group.bench_function("vfh_plus", |b| {
        b.iter(|| vfh.step(std::hint::black_box(&input)))
    });
    let mut manual = Manual;
    group.bench_function("manual", |b| {
        b.iter(|| manual.step(std::hint::black_box(&input)))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
