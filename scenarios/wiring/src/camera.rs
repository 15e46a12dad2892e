//! A virtual chair's camera for visual odometry, the same in process and in a chair container.
//!
//! In process the simulator renders what the chair sees in the shared world. A chair container
//! has no shared world: its body lives in the world container, which sends the body's true pose
//! with every sensor frame ([`crate::world_link::WorldBody::true_pose`]). The container keeps a
//! local copy of the map and renders the camera there at that pose ([`mirror_camera`]): the
//! walls, furniture and doors as the map gives them (not other chairs, nor doors moved since).

use iw_perception::VisualConfig;
use iw_sim::vo::SimCamera;
use iw_sim::{ChairKind, ChairSpec, Map, SharedWorld, World};
use iw_vo::{CameraSource, Intrinsics, VoError};
use nalgebra::{Isometry2, Matrix3, Vector3};

use crate::world_link::TruePose;
use crate::{StartError, WiringError};

/// The perception agent's visual odometry over `camera`: LSAC-SURF keyframe odometry. A frame's
/// motion is trusted to 1 cm and 0.5 mrad: at 20 frames/s that lets the camera take out the
/// heading drift of compressed tyres (about 1 degree per metre on the simulated encoders) that
/// made long trips end against a wall, while the EKF's gate still passes most frames (with 4 mm
/// it refused up to a fifth of them and the drift came back); frames the gate finds inconsistent
/// (fast spins close to a wall) are not fused.
pub fn visual_config(camera: SimCamera) -> VisualConfig {
    visual_config_over(camera.t_base_camera(), Box::new(camera))
}

fn visual_config_over(
    t_base_camera: nalgebra::Isometry3<f64>,
    source: Box<dyn CameraSource + Send>,
) -> VisualConfig {
    VisualConfig {
        t_base_camera,
        source,
        vo: iw_sim::vo::sim_vo_config(
            iw_features::DetectorKind::LsacSurf,
            iw_vo::Pipeline::Keyframe,
        ),
        motion_noise: Matrix3::from_diagonal(&Vector3::new(
            0.01f64.powi(2),
            0.01f64.powi(2),
            0.0005f64.powi(2),
        )),
    }
}

/// The camera of chair `chair` of a chair container: `map` rendered at the pose `truth` holds,
/// stamped with its time (at `start` until the first frame).
pub fn mirror_camera(
    chair: &str,
    map: Map,
    start: Isometry2<f64>,
    truth: TruePose,
) -> Result<VisualConfig, WiringError> {
    let setup = |e: iw_sim::SimError| {
        WiringError::Start(StartError {
            container: chair.into(),
            what: "camera".into(),
            source: e.into(),
        })
    };
    let mut world = World::new(map, 0);
    let id = world.add_chair(ChairSpec::default(), start, ChairKind::Tracked);
    let world = iw_sim::shared(world);
    let camera = SimCamera::new(world.clone(), id).map_err(setup)?;
    Ok(visual_config_over(
        camera.t_base_camera(),
        Box::new(Mirror {
            camera,
            world,
            id,
            truth,
        }),
    ))
}

/// A [`SimCamera`] over a local world whose one chair is placed at the true pose first.
struct Mirror {
    camera: SimCamera,
    world: SharedWorld,
    id: iw_sim::ChairId,
    truth: TruePose,
}

impl CameraSource for Mirror {
    fn intrinsics(&self) -> &Intrinsics {
        self.camera.intrinsics()
    }

    fn next_frame(&mut self) -> Option<Result<iw_vo::RgbdFrame, VoError>> {
        let truth = *self
            .truth
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let Some((time_ns, pose)) = truth else {
            return self.camera.next_frame();
        };
        let placed = self
            .world
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .place(self.id, pose);
        if let Err(e) = placed {
            return Some(Err(VoError::Camera {
                camera: "mirrored camera".into(),
                source: Box::new(e),
            }));
        }
        // Stamped with the body's time at that pose (the local world's clock never runs), so
        // the perception agent can bridge the frame to its wheel poses.
        self.camera.next_frame().map(|frame| {
            frame.map(|mut frame| {
                frame.timestamp_s = time_ns as f64 * 1e-9;
                frame
            })
        })
    }
}
