//! The sonar echo memory's cost per 50 ms control period, against the guard's period without it
//! (its peer, measured in the same run): a chair with sonars only driving at 0.5 m/s, turning
//! gently, down a 1.1 m passage past a door jamb, so that most of its 16 sonars echo nearer than
//! the memory's 0.6 m and the memory holds a realistic fill of arc cells. Each measured period
//! starts from a clone of the state after 3 s of such driving (the clone is not timed).

use std::time::Duration;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use iw_body::layout::Footprint;
use iw_shared_control::{
    ArcGuard, ArcGuardParams, EchoMemory, EchoMemoryParams, Motion, SharedController, SharedInput,
    VelocityCommand,
};
use nalgebra::{Isometry2, Point2, Vector2};

#[path = "../tests/support/sonars.rs"]
mod sonar_rig;
use sonar_rig::sonars;

const FP: Footprint = Footprint::PROTOTYPE;
const PERIOD_NS: u64 = 50_000_000;
/// Periods driven before the measured one: 3 s, 1.5 m, more than the memory keeps.
const WARM_PERIODS: u64 = 60;
/// The chair's speed and turn rate, m/s and rad/s.
const TWIST: (f64, f64) = (0.5, 0.05);

/// The passage's walls, 1 cm apart: 0.225 m beside either side of a 0.65 m chair, and a jamb (the
/// end of a wall 10 cm thick) coming in to 8 cm from the left side 1.2 m ahead.
fn world() -> Vec<Point2<f64>> {
    let side = FP.half_width_m + 0.225;
    let mut w: Vec<Point2<f64>> = (0..400)
        .flat_map(|k| {
            let x = -0.5 + k as f64 * 0.01;
            [Point2::new(x, side), Point2::new(x, -side)]
        })
        .collect();
    let jamb = FP.half_width_m + 0.08;
    w.extend((0..=10).map(|k| Point2::new(1.2 + k as f64 * 0.01, jamb)));
    w.extend((0..15).map(|k| Point2::new(1.2, jamb + k as f64 * 0.01)));
    w
}

/// The periods of the drive: time, pose, readings.
fn drive() -> Vec<(Motion, Vec<Option<f64>>)> {
    let world = world();
    let mut pose = Isometry2::identity();
    let twist = VelocityCommand::new(TWIST.0, TWIST.1);
    (0..=WARM_PERIODS)
        .map(|k| {
            let readings = sonars(&pose, &world);
            let motion = Motion {
                time_ns: k * PERIOD_NS,
                t_odom_chair: pose,
                twist,
            };
            pose *= Isometry2::new(Vector2::new(TWIST.0 * 0.05, 0.0), TWIST.1 * 0.05);
            (motion, readings)
        })
        .collect()
}

fn guard(echo_memory: EchoMemoryParams) -> ArcGuard {
    let params = ArcGuardParams {
        echo_memory,
        ..ArcGuardParams::default()
    };
    ArcGuard::new(params, FP, FP.sonar_mounts().to_vec()).expect("valid defaults")
}

fn input<'a>(motion: &Motion, readings: &'a [Option<f64>]) -> SharedInput<'a> {
    SharedInput {
        user: motion.twist,
        speed_mps: motion.twist.linear_mps,
        sonar_m: readings,
        points_chair: &[],
        motion: Some(*motion),
    }
}

fn bench(c: &mut Criterion) {
    let periods = drive();
    let (last, warm) = periods.split_last().expect("periods");
    let near = last.1.iter().flatten().filter(|&&d| d < 0.6).count();
    let mut memory = EchoMemory::new(
        EchoMemoryParams::default(),
        FP,
        FP.sonar_mounts().to_vec(),
        45.0,
    )
    .expect("valid defaults");
    let mut with = guard(EchoMemoryParams::default());
    let mut without = guard(EchoMemoryParams {
        near_m: 0.0,
        ..EchoMemoryParams::default()
    });
    for (motion, readings) in warm {
        memory.update(motion, readings).expect("valid readings");
        for g in [&mut with, &mut without] {
            g.step(&input(motion, readings)).expect("valid input");
        }
    }
    eprintln!(
        "measured period: {near} of 16 sonars nearer than 0.6 m; {} cells remembered, {} recalled",
        memory.len(),
        memory.recall(&last.0.t_odom_chair).count()
    );
    let mut group = c.benchmark_group("echo_memory_period");
    group
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1));
    group.bench_function("memory_update_and_recall", |b| {
        b.iter_batched(
            || memory.clone(),
            |mut m| {
                m.update(&last.0, &last.1).expect("valid readings");
                m.recall(&last.0.t_odom_chair).count()
            },
            BatchSize::SmallInput,
        )
    });
    group.bench_function("guard_step_sonars_with_memory", |b| {
        b.iter_batched(
            || with.clone(),
            |mut g| g.step(&input(&last.0, &last.1)).expect("valid input"),
            BatchSize::SmallInput,
        )
    });
    group.bench_function("peer_guard_step_sonars_without_memory", |b| {
        b.iter_batched(
            || without.clone(),
            |mut g| g.step(&input(&last.0, &last.1)).expect("valid input"),
            BatchSize::SmallInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
