//! The simulator against analytic geometry, its error models, determinism and mixed reality.

use std::path::PathBuf;
use std::time::Duration;

use approx::assert_relative_eq;
use iw_body::{BoardEmulator, Body, MixedBody, Odometry, SerialBody, WheelSpeeds};
use iw_sim::{
    ChairKind, ChairSpec, GhostSensors, Map, TUM_DEPTH_PER_M, TextureSet, VirtualBody, World,
    shared, step,
};
use nalgebra::{Isometry2, Vector2};
use rand::{Rng, SeedableRng};

fn maps_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../maps")
}

fn noiseless() -> ChairSpec {
    let mut spec = ChairSpec::default();
    spec.sonar.noise_std_m = 0.0;
    if let Some(laser) = spec.laser.as_mut() {
        laser.noise_std_m = 0.0;
    }
    spec
}

fn pose(x: f64, y: f64, heading_deg: f64) -> Isometry2<f64> {
    Isometry2::new(Vector2::new(x, y), heading_deg.to_radians())
}

#[test]
fn shipped_maps_parse_and_their_starts_are_free() {
    for name in ["office-circuit.map", "sample-building.map"] {
        let map = Map::load(maps_dir().join(name)).unwrap();
        assert!(!map.starts.is_empty(), "{name}");
        let starts: Vec<_> = map.starts.iter().map(|s| s.t_world_body).collect();
        let mut world = World::new(map, 1);
        for t in starts {
            let id = world.add_chair(ChairSpec::default(), t, ChairKind::Simulated);
            world.command(id, WheelSpeeds::STOP).unwrap();
            step(&mut world, 0.05);
            assert!(
                !world.in_contact(id).unwrap(),
                "{name}: start overlaps something"
            );
        }
    }
    let circuit = Map::load(maps_dir().join("office-circuit.map")).unwrap();
    assert!(
        circuit
            .route("lap")
            .is_some_and(|r| r.closed && r.points.len() >= 8)
    );
}

#[test]
fn sonar_and_laser_ranges_match_analytic_geometry() {
    // a wall 3 m ahead (x = 3) and one 1 m to the right (y = -1)
    let map = Map::parse("wall 3 -20 3 20\nwall -20 -1 20 -1\n", "analytic.map").unwrap();
    let mut world = World::new(map, 7);
    let spec = noiseless();
    let id = world.add_chair(spec.clone(), pose(0.0, 0.0, 0.0), ChairKind::Simulated);
    step(&mut world, 0.05);
    let f = world.sensors(id).unwrap();
    // S16 looks ahead from the left front tip: the wall ahead is nearest straight on
    assert_relative_eq!(f.sonar_m[15].unwrap(), 3.0 - spec.front_m, epsilon = 1e-9);
    // S1 (right front tip) also sees the right wall at the edge of its 45 deg cone
    let half_cone = (spec.sonar.cone_deg / 2.0).to_radians();
    let edge = (1.0 - spec.half_width_m) / half_cone.sin();
    assert_relative_eq!(
        f.sonar_m[0].unwrap(),
        edge.min(3.0 - spec.front_m),
        epsilon = 1e-9
    );
    // S3-S6 face right: the wall at y = -1 is 1 - half width away
    for k in 2..6 {
        assert_relative_eq!(
            f.sonar_m[k].unwrap(),
            1.0 - spec.half_width_m,
            epsilon = 1e-9
        );
    }
    // S11-S14 face left into the open: no echo within 3 m
    for k in 10..14 {
        assert_eq!(f.sonar_m[k], None);
    }
    let laser = spec.laser.unwrap();
    let origin = laser.t_body_laser.translation.vector;
    assert_eq!(f.laser_m.len(), laser.beams);
    for (k, range) in f.laser_m.iter().enumerate() {
        let a = (-laser.fov_deg / 2.0 + laser.fov_deg * k as f64 / (laser.beams - 1) as f64)
            .to_radians();
        let (c, s) = (a.cos(), a.sin());
        let mut expected = laser.max_range_m;
        if c > 1e-9 {
            expected = expected.min((3.0 - origin.x) / c);
        }
        if s < -1e-9 {
            expected = expected.min((-1.0 - origin.y) / s);
        }
        assert_relative_eq!(*range, expected, epsilon = 1e-6);
    }
}

#[test]
fn a_chair_at_full_speed_stops_at_the_wall_and_counts_one_collision() {
    let map = Map::parse("wall 5 -5 5 5\n", "wall.map").unwrap();
    for dt in [0.05, 0.5, 2.0] {
        let mut world = World::new(map.clone(), 3);
        let spec = ChairSpec::default();
        let id = world.add_chair(spec.clone(), pose(0.0, 0.0, 0.0), ChairKind::Simulated);
        world
            .command(
                id,
                WheelSpeeds {
                    left_mps: 10.0,
                    right_mps: 10.0,
                },
            )
            .unwrap();
        for _ in 0..(20.0 / dt) as usize {
            step(&mut world, dt);
            let front_x = spec
                .footprint_at(&world.pose(id).unwrap())
                .iter()
                .map(|p| p.x)
                .fold(f64::MIN, f64::max);
            assert!(front_x < 5.0, "tunnelled at dt {dt}: front at {front_x}");
        }
        assert_eq!(world.collisions(id).unwrap(), 1, "dt {dt}");
        let front_x = spec
            .footprint_at(&world.pose(id).unwrap())
            .iter()
            .map(|p| p.x)
            .fold(f64::MIN, f64::max);
        assert!(front_x > 4.9, "stopped early at {front_x}");
        // backing off and driving in again is a second collision
        world
            .command(
                id,
                WheelSpeeds {
                    left_mps: -0.5,
                    right_mps: -0.5,
                },
            )
            .unwrap();
        for _ in 0..20 {
            step(&mut world, 0.05);
        }
        world
            .command(
                id,
                WheelSpeeds {
                    left_mps: 1.0,
                    right_mps: 1.0,
                },
            )
            .unwrap();
        for _ in 0..60 {
            step(&mut world, 0.05);
        }
        assert_eq!(world.collisions(id).unwrap(), 2);
    }
}

#[test]
fn chairs_collide_with_each_other_and_see_each_other() {
    let map = Map::parse("wall closed -10 -10 10 -10 10 10 -10 10\n", "room.map").unwrap();
    let mut world = World::new(map, 4);
    let a = world.add_chair(noiseless(), pose(0.0, 0.0, 0.0), ChairKind::Simulated);
    let b = world.add_chair(noiseless(), pose(4.0, -0.2, 180.0), ChairKind::Simulated);
    step(&mut world, 0.05);
    // front-to-front 4 - 0.75 - 0.75 = 2.5 m
    assert_relative_eq!(
        world.sensors(a).unwrap().sonar_m[0].unwrap(),
        2.5,
        epsilon = 1e-9
    );
    world
        .command(
            a,
            WheelSpeeds {
                left_mps: 1.0,
                right_mps: 1.0,
            },
        )
        .unwrap();
    world
        .command(
            b,
            WheelSpeeds {
                left_mps: 1.0,
                right_mps: 1.0,
            },
        )
        .unwrap();
    for _ in 0..100 {
        step(&mut world, 0.05);
    }
    assert!(world.collisions(a).unwrap() >= 1 && world.collisions(b).unwrap() >= 1);
    let gap = world.pose(b).unwrap().translation.x - world.pose(a).unwrap().translation.x;
    assert!(
        gap >= 1.5 - 1e-9,
        "footprints overlap: centres {gap} m apart"
    );
}

#[test]
fn encoders_overestimate_travel_as_compressed_tyres_and_slip_predict() {
    let map = Map::parse("wall -1000 -1000 -999 -1000\n", "open.map").unwrap();
    let mut world = World::new(map, 11);
    let ids: Vec<_> = (0..40)
        .map(|k| {
            world.add_chair(
                ChairSpec::default(),
                pose(0.0, 5.0 * k as f64, 0.0),
                ChairKind::Simulated,
            )
        })
        .collect();
    for &id in &ids {
        world
            .command(
                id,
                WheelSpeeds {
                    left_mps: 1.0,
                    right_mps: 1.0,
                },
            )
            .unwrap();
    }
    for _ in 0..200 {
        step(&mut world, 0.05);
    }
    let per_tick = ChairSpec::default().geometry.m_per_tick();
    let ratios: Vec<f64> = ids
        .iter()
        .map(|&id| {
            let f = world.sensors(id).unwrap();
            let odo_m = (f.left_ticks + f.right_ticks) as f64 / 2.0 * per_tick;
            odo_m / world.distance_m(id).unwrap()
        })
        .collect();
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    let std = (ratios.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / ratios.len() as f64).sqrt();
    // compression 0.5-3 % (mean 1.75 %) plus ~0.8 % mean half-normal slip
    assert!(
        mean > 1.015 && mean < 1.04,
        "mean odometry/true ratio {mean}"
    );
    assert!(std > 0.002 && std < 0.02, "spread between chairs {std}");
    // unequal tyres make straight commands curve: heading drift, as dead reckoning sees it
    let drifted = ids
        .iter()
        .filter(|&&id| world.pose(id).unwrap().rotation.angle().abs() > 0.01)
        .count();
    assert!(drifted > ids.len() / 2, "{drifted} chairs drifted");
}

fn scripted_run(seed: u64) -> Vec<(Isometry2<f64>, iw_body::SensorFrame, u64)> {
    let map = Map::load(maps_dir().join("office-circuit.map")).unwrap();
    let mut world = World::new(map, seed);
    let ids: Vec<_> = (0..6)
        .map(|k| {
            world.add_chair(
                ChairSpec::default(),
                pose(1.25, 1.0 + 1.2 * k as f64, 90.0),
                ChairKind::Simulated,
            )
        })
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
    for _ in 0..100 {
        for &id in &ids {
            world
                .command(
                    id,
                    WheelSpeeds {
                        left_mps: rng.random_range(-0.5..1.5),
                        right_mps: rng.random_range(-0.5..1.5),
                    },
                )
                .unwrap();
        }
        step(&mut world, 0.05);
    }
    ids.iter()
        .map(|&id| {
            (
                world.pose(id).unwrap(),
                world.sensors(id).unwrap().clone(),
                world.collisions(id).unwrap(),
            )
        })
        .collect()
}

#[test]
fn same_seed_same_run_other_seed_other_run() {
    let a = scripted_run(5);
    let b = scripted_run(5);
    assert_eq!(a, b);
    let c = scripted_run(6);
    assert_ne!(a, c);
}

#[test]
fn a_hundred_chairs_step_with_full_sensors() {
    let map = Map::parse(
        "wall closed 0 0 60 0 60 40 0 40\nbox 30 20 4 4\n",
        "hall.map",
    )
    .unwrap();
    let mut world = World::new(map, 2);
    let ids: Vec<_> = (0..100)
        .map(|k| {
            world.add_chair(
                ChairSpec::default(),
                pose(
                    3.0 + 5.5 * (k % 10) as f64,
                    2.0 + 3.8 * (k / 10) as f64,
                    0.0,
                ),
                ChairKind::Simulated,
            )
        })
        .collect();
    for (k, &id) in ids.iter().enumerate() {
        world
            .command(
                id,
                WheelSpeeds {
                    left_mps: 0.8,
                    right_mps: 0.8 + 0.05 * (k % 3) as f64,
                },
            )
            .unwrap();
    }
    for _ in 0..40 {
        step(&mut world, 0.05);
    }
    assert_eq!(world.time_ns(), 2_000_000_000);
    for &id in &ids {
        let f = world.sensors(id).unwrap();
        assert_eq!(f.laser_m.len(), 271);
        assert!(f.left_ticks > 0);
        assert!(
            world.rgbd(id).unwrap().is_none(),
            "no chair asked for RGB-D"
        );
    }
    // chairs in a row 5.5 m apart: the laser's forward beam sees the next one's back (~4.4 m)
    let ahead = world.sensors(ids[0]).unwrap().laser_m[125..=145]
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    assert!(ahead > 3.5 && ahead < 5.0, "forward beam {ahead}");
}

#[test]
fn doors_block_while_closed_and_cannot_close_on_a_chair() {
    let map = Map::parse(
        "wall 2 -5 2 -0.6\nwall 2 0.6 2 5\ndoor d1 2 -0.6 2 0.6 closed\n",
        "door.map",
    )
    .unwrap();
    let mut world = World::new(map, 1);
    let id = world.add_chair(noiseless(), pose(0.0, 0.0, 0.0), ChairKind::Simulated);
    step(&mut world, 0.05);
    let spec = noiseless();
    assert_relative_eq!(
        world.sensors(id).unwrap().sonar_m[0].unwrap(),
        2.0 - spec.front_m,
        epsilon = 1e-9
    );
    let laser = spec.laser.unwrap();
    let forward = |w: &World| w.sensors(id).unwrap().laser_m[laser.beams / 2];
    assert_relative_eq!(
        forward(&world),
        2.0 - laser.t_body_laser.translation.x,
        epsilon = 1e-9
    );
    world.set_door("d1", true).unwrap();
    step(&mut world, 0.05);
    assert_relative_eq!(forward(&world), laser.max_range_m);
    world
        .command(
            id,
            WheelSpeeds {
                left_mps: 0.5,
                right_mps: 0.5,
            },
        )
        .unwrap();
    for _ in 0..75 {
        step(&mut world, 0.05);
    }
    assert_eq!(world.collisions(id).unwrap(), 0);
    assert!(matches!(
        world.set_door("d1", false),
        Err(iw_sim::SimError::DoorBlocked { .. })
    ));
    assert!(world.set_door("nope", true).is_err());
}

#[test]
fn rgbd_depth_is_exact_and_light_changes_colour_only() {
    let map = Map::parse("wall 2 -10 2 10\n", "wall.map").unwrap();
    let mut world = World::new(map, 1);
    if let Some(dir) = iw_testdata::require("rgbd_textures", "data/images/skimage") {
        world.set_textures(TextureSet::load_dir(&dir).unwrap());
    }
    let spec = ChairSpec::default();
    let id = world.add_chair(spec.clone(), pose(-1.0, 0.0, 0.0), ChairKind::Simulated);
    world.request_rgbd(id, true).unwrap();
    step(&mut world, 0.05);
    let frame = world.rgbd(id).unwrap().unwrap().clone();
    // camera at x = -1 + 0.75, wall at x = 2: optical depth 2.25 m everywhere on the wall
    let (w, h) = frame.depth.dimensions();
    for u in [0, w / 2, w - 1] {
        let raw = frame.depth.get_pixel(u, h / 2).0[0];
        assert_relative_eq!(
            f64::from(raw) / TUM_DEPTH_PER_M,
            2.25,
            epsilon = 1.0 / TUM_DEPTH_PER_M
        );
    }
    assert_relative_eq!(
        frame.t_world_camera.translation.vector.x,
        -0.25,
        epsilon = 1e-12
    );
    // the optical axis looks along world +x
    let z_axis = frame.t_world_camera.rotation * nalgebra::Vector3::z();
    assert_relative_eq!(z_axis, nalgebra::Vector3::x(), epsilon = 1e-12);
    // a wall pixel back-projects onto the wall
    let (fx, fy, cx, cy) = frame.intrinsics;
    let (u, v) = (40u32, 60u32);
    let z = f64::from(frame.depth.get_pixel(u, v).0[0]) / TUM_DEPTH_PER_M;
    let p_camera = nalgebra::Point3::new((u as f64 - cx) / fx * z, (v as f64 - cy) / fy * z, z);
    assert_relative_eq!((frame.t_world_camera * p_camera).x, 2.0, epsilon = 1e-3);
    let mean = |img: &image::RgbImage| {
        img.pixels()
            .map(|p| p.0.iter().map(|&c| f64::from(c)).sum::<f64>())
            .sum::<f64>()
            / img.len() as f64
    };
    world.set_light(0.5);
    step(&mut world, 0.05);
    let dim = world.rgbd(id).unwrap().unwrap().clone();
    assert_eq!(dim.depth, frame.depth);
    assert!(mean(&dim.rgb) < 0.6 * mean(&frame.rgb));
}

#[test]
fn occupancy_png_becomes_walls_at_the_right_place() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.png");
    // 100 x 100 px at 5 cm: a dark 20 px square from x = 60..80 px, rows 40..60
    let img = image::GrayImage::from_fn(100, 100, |x, y| {
        image::Luma([if (60..80).contains(&x) && (40..60).contains(&y) {
            0
        } else {
            255
        }])
    });
    img.save(&path).unwrap();
    let map = Map::load(&path).unwrap();
    assert_eq!(map.walls.len(), 4);
    let mut world = World::new(map, 1);
    let id = world.add_chair(noiseless(), pose(0.5, 2.5, 0.0), ChairKind::Simulated);
    step(&mut world, 0.05);
    // square's left face at x = 3.0 m; S1 sits on the right bar at y = 2.5 - 0.325 (inside 2..3)
    assert_relative_eq!(
        world.sensors(id).unwrap().sonar_m[0].unwrap(),
        3.0 - 0.5 - 0.75,
        epsilon = 1e-9
    );
    assert!(Map::load(dir.path().join("missing.png")).is_err());
}

#[test]
fn virtual_body_drives_like_a_real_one() {
    let map = Map::parse("wall 10 -5 10 5\n", "wall.map").unwrap();
    let world = shared(World::new(map, 1));
    let id = world.lock().unwrap().add_chair(
        ChairSpec::default(),
        pose(0.0, 0.0, 0.0),
        ChairKind::Simulated,
    );
    let mut body: Box<dyn Body> = Box::new(VirtualBody::new(world.clone(), id));
    body.command(WheelSpeeds {
        left_mps: 0.5,
        right_mps: 0.5,
    })
    .unwrap();
    for _ in 0..40 {
        step(&mut world.lock().unwrap(), 0.05);
    }
    let f = body.read().unwrap();
    assert!(f.left_ticks > 0 && f.right_ticks > 0);
    assert!(world.lock().unwrap().pose(id).unwrap().translation.x > 0.5);
    body.stop().unwrap();
}

#[test]
fn mixed_reality_real_board_plus_virtual_world_nearest_wins() {
    // the virtual world holds a wall 1.5 m ahead of where the real chair starts
    let map = Map::parse("wall 2.25 -5 2.25 5\n", "virtual.map").unwrap();
    let world = shared(World::new(map, 1));
    let ghost =
        world
            .lock()
            .unwrap()
            .add_chair(noiseless(), pose(0.0, 0.0, 0.0), ChairKind::Tracked);
    let board = BoardEmulator::spawn(ChairSpec::default().geometry, 50_000_000).unwrap();
    // the real sonars: an obstacle 0.4 m right (S3), nothing ahead
    board.handle().set_sonar(2, Some(0.4));
    let real = SerialBody::open(board.port_name(), 115_200, Duration::from_secs(2)).unwrap();
    let odometry = Odometry::new(ChairSpec::default().geometry, pose(0.0, 0.0, 0.0));
    let mut body = MixedBody::new(real, GhostSensors::new(world.clone(), ghost), odometry);
    let f = body.read().unwrap();
    assert_eq!(f.sonar_m[2], Some(0.4), "real reading kept where nearer");
    assert_relative_eq!(f.sonar_m[0].unwrap(), 1.5, epsilon = 1e-9);
    // drive the real chair 1 m forward (20 periods at 1 m/s): the ghost follows, the wall nears
    body.command(WheelSpeeds {
        left_mps: 1.0,
        right_mps: 1.0,
    })
    .unwrap();
    let mut last = f;
    for _ in 0..20 {
        last = body.read().unwrap();
    }
    assert_relative_eq!(
        world.lock().unwrap().pose(ghost).unwrap().translation.x,
        1.0,
        epsilon = 0.01
    );
    assert_relative_eq!(last.sonar_m[0].unwrap(), 0.5, epsilon = 0.01);
    assert_eq!(
        board.handle().state().speeds,
        WheelSpeeds {
            left_mps: 1.0,
            right_mps: 1.0
        }
    );
}

#[test]
fn random_driving_in_the_cluttered_circuit_never_ends_inside_an_obstacle() {
    let map = Map::load(maps_dir().join("office-circuit.map")).unwrap();
    let start = map.start("lap").unwrap();
    let mut world = World::new(map, 21);
    let ids: Vec<_> = [start, pose(1.6, 4.4, 90.0), pose(7.0, 8.75, 180.0)]
        .into_iter()
        .map(|t| world.add_chair(ChairSpec::default(), t, ChairKind::Simulated))
        .collect();
    for &id in &ids {
        assert!(!world.overlapping(id).unwrap(), "bad test start {id:?}");
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..1500 {
        for &id in &ids {
            if rng.random_bool(0.1) {
                // full speed in a random direction, including spins
                let v = rng.random_range(-1.5..1.5);
                world
                    .command(
                        id,
                        WheelSpeeds {
                            left_mps: v + rng.random_range(-1.0..1.0),
                            right_mps: v + rng.random_range(-1.0..1.0),
                        },
                    )
                    .unwrap();
            }
        }
        step(&mut world, 0.1);
        for &id in &ids {
            assert!(
                !world.overlapping(id).unwrap(),
                "chair {id:?} inside an obstacle at {}",
                world.pose(id).unwrap()
            );
        }
    }
    let total: u64 = ids.iter().map(|&id| world.collisions(id).unwrap()).sum();
    assert!(total > 0, "random driving should have hit something");
}
