//! Simulator steps per second for 1, 10 and 100 chairs (sonars, laser, encoders at 20 Hz), and
//! one RGB-D frame as the peer.

use std::path::PathBuf;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use iw_body::WheelSpeeds;
use iw_sim::{ChairKind, ChairSpec, Map, World, step};
use nalgebra::{Isometry2, Vector2};

/// `n` chairs spread over a 60 x 40 m hall with furniture, circling at different rates.
fn hall(n: usize) -> World {
    let text = "wall closed 0 0 60 0 60 40 0 40\nbox 30 20 4 4\nbox 15 10 2 1\nbox 45 30 2 1\nbox 15 30 1 2\nbox 45 10 1 2\n";
    let mut world = World::new(Map::parse(text, "hall.map").expect("bench map"), 1);
    for k in 0..n {
        let t = Isometry2::new(
            Vector2::new(3.0 + 5.5 * (k % 10) as f64, 2.0 + 3.8 * (k / 10) as f64),
            0.0,
        );
        let id = world.add_chair(ChairSpec::default(), t, ChairKind::Simulated);
        world
            .command(
                id,
                WheelSpeeds {
                    left_mps: 0.6,
                    right_mps: 0.7 + 0.02 * (k % 5) as f64,
                },
            )
            .expect("chair exists");
    }
    world
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("sim_step_20hz");
    group
        .measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(30);
    for n in [1usize, 10, 100] {
        let mut world = hall(n);
        group.throughput(Throughput::Elements(1));
        group.bench_with_input(BenchmarkId::new("chairs", n), &n, |b, _| {
            b.iter(|| step(&mut world, 0.05))
        });
    }
    group.finish();
    let mut group = c.benchmark_group("sim_rgbd");
    group
        .measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(20);
    let map =
        Map::load(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../maps/office-circuit.map"))
            .expect("office circuit");
    let start = map.start("lap").expect("lap start");
    let mut world = World::new(map, 1);
    let id = world.add_chair(ChairSpec::default(), start, ChairKind::Simulated);
    group.bench_function("render_320x240", |b| {
        b.iter(|| world.render_rgbd(id).expect("chair exists"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
