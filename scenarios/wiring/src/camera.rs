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
use iw_vo::{CameraSource, Intrinsics, VisualNoise, VoError};
use nalgebra::Isometry2;

use crate::world_link::TruePose;
use crate::{StartError, WiringError};

/// How far one visual-odometry motion on the simulator's camera is trusted: 1 cm and 0.1 degree
/// for any motion, plus 5 % of the distance and of the turn, and 0.5 degree of heading a metre.
/// Measured on blind drives (the laser silent, wheels and camera only, no landmark) through
/// the sample building: with a fixed 1 cm and 0.5 mrad a frame the fused covariance stayed at
/// 2 sigma = 32 cm while the error grew to 56 cm, its heading 4 degrees off against a standard
/// deviation of 1 degree.
pub const VISUAL_NOISE: VisualNoise = VisualNoise {
    floor_m: 0.01,
    floor_rad: 0.002,
    per_metre: 0.05,
    rad_per_rad: 0.05,
    rad_per_metre: 0.009,
};

/// The perception agent's visual odometry over `camera`: LSAC-SURF keyframe odometry, each
/// motion trusted as [`VISUAL_NOISE`] says.
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
        motion_noise: VISUAL_NOISE,
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
