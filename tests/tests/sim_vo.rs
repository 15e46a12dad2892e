//! Visual odometry on the simulator's camera: units and frames of the adapter, and the thesis's
//! claim that fusing wheel and visual odometry beats either alone, on exact ground truth.

use std::path::Path;

use iw_features::DetectorKind;
use iw_sim::vo::{
    SimCamera, TrialConfig, run_trial, sim_vo_config, t_base_camera, vo_frame, waypoints_ahead,
};
use iw_sim::{ChairKind, ChairSpec, Map, SharedWorld, TextureSet, World, shared};
use iw_vo::{CameraSource, Pipeline, VisualOdometry, planar_motion};
use nalgebra::{Isometry2, Point2, Vector2};

/// The office circuit with one chair at its start, textured with `textures` (photographs) or,
/// without them, the simulator's procedural textures.
fn office(seed: u64, textures: Option<&Path>) -> (SharedWorld, iw_sim::ChairId, Vec<Point2<f64>>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/maps/office-circuit.map");
    let map = Map::load(&path).unwrap();
    let start = map.start("lap").unwrap();
    let route = waypoints_ahead(&start, map.route("lap").unwrap());
    let mut world = World::new(map, seed);
    if let Some(dir) = textures {
        world.set_textures(TextureSet::load_dir(dir).unwrap());
    }
    let id = world.add_chair(ChairSpec::default(), start, ChairKind::Simulated);
    (shared(world), id, route)
}

#[test]
fn known_camera_motion_comes_back_from_vo() {
    let textures = iw_testdata::require(
        "known_camera_motion_comes_back_from_vo",
        "data/images/skimage",
    );
    let (world, id, _) = office(1, textures.as_deref());
    let mut camera = SimCamera::new(world.clone(), id).unwrap();
    let k = *camera.intrinsics();
    assert_eq!(
        (k.fx, k.cx, k.depth_units_per_m),
        (ChairSpec::default().camera.intrinsics().0, 159.5, 5000.0)
    );
    let mut vo = VisualOdometry::new(sim_vo_config(DetectorKind::LsacSurf, Pipeline::Thesis), k);
    let start = world.lock().unwrap().pose(id).unwrap();
    let first = camera.render().unwrap();
    vo.process(&vo_frame(&first)).unwrap();
    // 5 cm forward, 2 cm left, 2 degrees to the left (a frame at 0.5 m/s and 10 Hz)
    let moved = start * Isometry2::new(Vector2::new(0.05, 0.02), 2f64.to_radians());
    world.lock().unwrap().place(id, moved).unwrap();
    let second = camera.render().unwrap();
    let (estimate, stats) = vo.process(&camera_frame(&mut camera)).unwrap();
    let truth = first.t_world_camera.inverse() * second.t_world_camera;
    // VO's world is the first camera frame
    let error = truth.inverse() * estimate.t_world_camera;
    assert!(stats.inliers >= 20, "{stats:?}");
    assert!(
        error.translation.vector.norm() < 0.015,
        "translation error {:?}",
        error.translation.vector
    );
    assert!(
        error.rotation.angle() < 0.5f64.to_radians(),
        "rotation error {} rad",
        error.rotation.angle()
    );
    // the base's planar motion, through the mount
    let motion = planar_motion(
        &t_base_camera(&ChairSpec::default().camera),
        &estimate.t_world_camera,
    );
    assert!(
        (motion.x - 0.05).abs() < 0.015 && (motion.y - 0.02).abs() < 0.015,
        "{motion:?}"
    );
    assert!(
        (motion.theta - 2f64.to_radians()).abs() < 0.5f64.to_radians(),
        "{motion:?}"
    );
}

fn camera_frame(camera: &mut SimCamera) -> iw_vo::RgbdFrame {
    camera.next_frame().unwrap().unwrap()
}

#[test]
fn fused_odometry_beats_wheels_and_vision_alone() {
    // The claim is about the photographed walls: on procedural textures VO alone is this exact,
    // so the fusion has nothing to add and the comparison says nothing.
    let Some(textures) = iw_testdata::require(
        "fused_odometry_beats_wheels_and_vision_alone",
        "data/images/skimage",
    ) else {
        return;
    };
    let (world, id, route) = office(7, Some(&textures));
    let result = run_trial(&world, id, &route, &TrialConfig::default()).unwrap();
    let (wheel, vo, fused) = (
        result.rmse_wheel_m(),
        result.rmse_vo_m(),
        result.rmse_fused_m(),
    );
    eprintln!(
        "RMSE wheel {wheel:.4} m, VO {vo:.4} m, fused {fused:.4} m; VO on {} frames",
        result.vo_frames
    );
    let travelled: f64 = result
        .points
        .windows(2)
        .map(|w| {
            ((w[1].truth.x - w[0].truth.x).powi(2) + (w[1].truth.y - w[0].truth.y).powi(2)).sqrt()
        })
        .sum();
    assert!(travelled > 2.5, "the chair drove only {travelled} m");
    assert_eq!(result.vo_frames, result.points.len());
    assert!(
        fused < wheel && fused < vo,
        "wheel {wheel}, VO {vo}, fused {fused}"
    );
}
