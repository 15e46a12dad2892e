//! The simulator's RGB-D camera as an [`iw_vo::CameraSource`], and the odometry trial that
//! checks the thesis's claim (3.3.2, chapter 5) on the simulator's exact ground truth: wheel
//! odometry from the simulated encoders (tyre compression, slip), visual odometry on rendered
//! frames, and their EKF fusion.
//!
//! Only the images, the time and the camera's calibration cross into the estimate:
//! [`vo_frame`] drops the frame's exact `t_world_camera`, which the trial keeps for scoring.

use std::time::Instant;

use iw_body::WheelSpeeds;
use iw_features::DetectorKind;
use iw_vo::{
    CameraSource, DiffDriveParams, Intrinsics, OdometryFusion, Pipeline, Pose2, VisualOdometry,
    VoConfig, VoError, WheelOdometry, planar_motion,
};
use nalgebra::{Isometry2, Isometry3, Matrix3, Point2, Vector2, Vector3};

use crate::body::lock;
use crate::{
    CameraModel, ChairId, RgbdFrame, Route, SharedWorld, SimError, TUM_DEPTH_PER_M, optical_pose,
};

/// The calibration iw-vo needs for frames of `camera`: its pinhole, no distortion (the renderer
/// is an ideal pinhole), TUM depth units and the camera's valid depth range.
pub fn vo_intrinsics(camera: &CameraModel) -> Intrinsics {
    let cam = CameraModel {
        width_px: camera.width_px.max(1),
        height_px: camera.height_px.max(1),
        ..*camera
    };
    let (fx, fy, cx, cy) = cam.intrinsics();
    Intrinsics {
        fx,
        fy,
        cx,
        cy,
        distortion: None,
        depth_units_per_m: TUM_DEPTH_PER_M,
        min_depth_m: cam.min_depth_m,
        max_depth_m: cam.max_depth_m,
    }
}

/// Where `camera` sits on the base (base frame: x forward, y left, z up; optical frame: x right,
/// y down, z forward), as [`iw_vo::planar_motion`] wants it.
pub fn t_base_camera(camera: &CameraModel) -> Isometry3<f64> {
    optical_pose(&camera.t_body_camera, camera.height_m)
}

/// A rendered frame as iw-vo's frame: images and time only (the ground truth stays behind).
pub fn vo_frame(frame: &RgbdFrame) -> iw_vo::RgbdFrame {
    iw_vo::RgbdFrame {
        timestamp_s: frame.time_ns as f64 * 1e-9,
        rgb: frame.rgb.clone(),
        depth: frame.depth.clone(),
        decode_ms: 0.0,
    }
}

/// The camera of one simulated chair: each [`CameraSource::next_frame`] renders what it sees in
/// the shared world now (whoever owns the loop steps the world). A live source: it never ends.
#[derive(Debug, Clone)]
pub struct SimCamera {
    world: SharedWorld,
    id: ChairId,
    intrinsics: Intrinsics,
    t_base_camera: Isometry3<f64>,
}

impl SimCamera {
    /// The camera of chair `id` (an error if the world has no such chair).
    pub fn new(world: SharedWorld, id: ChairId) -> Result<Self, SimError> {
        let camera = lock(&world).spec(id)?.camera;
        Ok(SimCamera {
            intrinsics: vo_intrinsics(&camera),
            t_base_camera: t_base_camera(&camera),
            world,
            id,
        })
    }

    /// Where the camera sits on the chair's base.
    pub fn t_base_camera(&self) -> Isometry3<f64> {
        self.t_base_camera
    }

    /// The next frame with its ground truth (for scoring; the estimate takes [`vo_frame`] of it).
    pub fn render(&self) -> Result<RgbdFrame, SimError> {
        lock(&self.world).render_rgbd(self.id)
    }
}

impl CameraSource for SimCamera {
    fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    fn next_frame(&mut self) -> Option<Result<iw_vo::RgbdFrame, VoError>> {
        Some(
            self.render()
                .map(|f| vo_frame(&f))
                .map_err(|e| VoError::Camera {
                    camera: format!("simulated camera of chair {}", self.id.0),
                    source: Box::new(e),
                }),
        )
    }
}

/// Visual odometry settings for the simulator's 320x240 camera: upright features (the camera
/// does not roll) and a detector threshold a quarter of the 640x480 default, since a quarter of
/// the pixels gives about a quarter of the responses above it.
pub fn sim_vo_config(detector: DetectorKind, pipeline: Pipeline) -> VoConfig {
    let mut config = VoConfig::new(detector, pipeline);
    config.detector_config.upright = true;
    config.detector_config.threshold *= 0.25;
    config
}

/// How the odometry trial drives and estimates.
#[derive(Debug, Clone)]
pub struct TrialConfig {
    /// Camera frames to take.
    pub frames: usize,
    /// Simulator steps (each one wheel-odometry prediction) per camera frame.
    pub steps_per_frame: usize,
    /// Simulator step, s.
    pub dt_s: f64,
    /// Cruise speed, m/s.
    pub speed_mps: f64,
    /// Visual odometry settings (detector, pipeline, thresholds).
    pub vo: VoConfig,
    /// From this frame on, the world's light is set to this level (a light change mid-run).
    pub light_change: Option<(usize, f64)>,
    /// Covariance of one frame-to-frame planar visual motion (x, y, theta) in the EKF.
    pub vo_noise: Matrix3<f64>,
}

impl Default for TrialConfig {
    /// 80 frames at 10 Hz (two 50 ms steps each), 0.4 m/s, LSAC-SURF keyframe VO
    /// ([`sim_vo_config`]), no light change.
    fn default() -> Self {
        TrialConfig {
            frames: 80,
            steps_per_frame: 2,
            dt_s: 0.05,
            speed_mps: 0.4,
            vo: sim_vo_config(DetectorKind::LsacSurf, Pipeline::Keyframe),
            light_change: None,
            vo_noise: Matrix3::from_diagonal(&Vector3::new(
                0.004f64.powi(2),
                0.004f64.powi(2),
                0.002f64.powi(2),
            )),
        }
    }
}

/// The four poses of the base at one camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialPoint {
    /// Simulated time, s.
    pub time_s: f64,
    /// The simulator's exact pose.
    pub truth: Pose2,
    /// Wheel odometry alone.
    pub wheel: Pose2,
    /// Visual odometry alone (its planar motions chained from the start pose).
    pub vo: Pose2,
    /// The EKF of both.
    pub fused: Pose2,
}

/// What the trial measured.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialResult {
    /// One point per camera frame, the start included.
    pub points: Vec<TrialPoint>,
    /// Frames on which visual odometry returned a pose.
    pub vo_frames: usize,
    /// Time spent in visual odometry (detection to pose), s.
    pub vo_seconds: f64,
    /// Time spent rendering frames, s.
    pub render_seconds: f64,
}

impl TrialResult {
    fn rmse(&self, pick: impl Fn(&TrialPoint) -> Pose2) -> f64 {
        let n = self.points.len().max(1) as f64;
        (self
            .points
            .iter()
            .map(|p| (pick(p).x - p.truth.x).powi(2) + (pick(p).y - p.truth.y).powi(2))
            .sum::<f64>()
            / n)
            .sqrt()
    }

    /// Position RMSE of wheel odometry against the truth, m.
    pub fn rmse_wheel_m(&self) -> f64 {
        self.rmse(|p| p.wheel)
    }

    /// Position RMSE of visual odometry alone, m.
    pub fn rmse_vo_m(&self) -> f64 {
        self.rmse(|p| p.vo)
    }

    /// Position RMSE of the fused estimate, m.
    pub fn rmse_fused_m(&self) -> f64 {
        self.rmse(|p| p.fused)
    }

    /// Visual odometry frames per second (processing only).
    pub fn vo_fps(&self) -> f64 {
        self.vo_frames as f64 / self.vo_seconds.max(1e-9)
    }
}

fn pose2(t: &Isometry2<f64>) -> Pose2 {
    Pose2::new(t.translation.x, t.translation.y, t.rotation.angle())
}

/// Wheel speeds that steer the chair at `pose` towards `target` at `speed` (a heading
/// controller on the true pose: it is the driver, not the estimate).
fn steer(pose: &Isometry2<f64>, target: &Point2<f64>, speed: f64, track_m: f64) -> WheelSpeeds {
    let to = target - Point2::from(pose.translation.vector);
    let error = iw_vo::wrap_angle(to.y.atan2(to.x) - pose.rotation.angle());
    let omega = (1.5 * error).clamp(-0.6, 0.6);
    let v = speed * error.cos().max(0.2);
    WheelSpeeds {
        left_mps: v - omega * track_m / 2.0,
        right_mps: v + omega * track_m / 2.0,
    }
}

/// The route's waypoints in driving order from `start`: from the nearest one if it lies ahead,
/// else the one after it; a closed route wraps round to end where it began.
pub fn waypoints_ahead(start: &Isometry2<f64>, route: &Route) -> Vec<Point2<f64>> {
    let from = Point2::from(start.translation.vector);
    let Some(nearest) = (0..route.points.len()).min_by(|&a, &b| {
        (route.points[a] - from)
            .norm()
            .total_cmp(&(route.points[b] - from).norm())
    }) else {
        return Vec::new();
    };
    let ahead = (route.points[nearest] - from).dot(&(start.rotation * Vector2::x())) > 0.0;
    let first = if ahead { nearest } else { nearest + 1 };
    let mut points = route.points[first.min(route.points.len())..].to_vec();
    if route.closed {
        points.extend_from_slice(&route.points[..first.min(route.points.len())]);
    }
    points
}

/// Drives chair `id` of `world` through `waypoints` for [`TrialConfig::frames`] camera frames and
/// estimates its pose three ways from its encoders and camera: wheel odometry, visual odometry
/// on the rendered frames ([`SimCamera`]), and their EKF ([`OdometryFusion`]), all started at
/// the true start pose. The caller owns the world; the trial steps it.
pub fn run_trial(
    world: &SharedWorld,
    id: ChairId,
    waypoints: &[Point2<f64>],
    config: &TrialConfig,
) -> Result<TrialResult, SimError> {
    let spec = lock(world).spec(id)?.clone();
    let mut camera = SimCamera::new(world.clone(), id)?;
    let drive = DiffDriveParams {
        wheel_radius_m: spec.geometry.wheel_radius_m,
        track_m: spec.geometry.track_m,
        ticks_per_rev: spec.geometry.ticks_per_rev,
        ..DiffDriveParams::default()
    };
    let start = pose2(&lock(world).pose(id)?);
    let mut wheels = WheelOdometry::new(drive, start);
    let mut fusion = OdometryFusion::new(
        start,
        Matrix3::from_diagonal(&Vector3::new(1e-6, 1e-6, 1e-6)),
        drive.alpha,
    );
    let mut vo = VisualOdometry::new(config.vo.clone(), *camera.intrinsics());
    let t_base_camera = camera.t_base_camera();
    let (mut vo_pose, mut last_camera): (Pose2, Option<Isometry3<f64>>) = (start, None);
    let first = lock(world).sensors(id)?.clone();
    wheels.update(first.left_ticks, first.right_ticks);
    let mut result = TrialResult {
        points: Vec::with_capacity(config.frames),
        vo_frames: 0,
        vo_seconds: 0.0,
        render_seconds: 0.0,
    };
    let mut next_waypoint = 0;
    for frame_index in 0..config.frames {
        if frame_index > 0 {
            for _ in 0..config.steps_per_frame.max(1) {
                let truth = lock(world).pose(id)?;
                while next_waypoint + 1 < waypoints.len()
                    && (waypoints[next_waypoint] - Point2::from(truth.translation.vector)).norm()
                        < 0.5
                {
                    next_waypoint += 1;
                }
                if let Some(target) = waypoints.get(next_waypoint) {
                    lock(world).command(
                        id,
                        steer(&truth, target, config.speed_mps, spec.geometry.track_m),
                    )?;
                }
                crate::step(&mut lock(world), config.dt_s);
                let sensed = lock(world).sensors(id)?.clone();
                if let Some(step) = wheels.update(sensed.left_ticks, sensed.right_ticks) {
                    fusion.predict(&step);
                }
            }
        }
        if let Some((at, level)) = config.light_change
            && frame_index == at
        {
            lock(world).set_light(level);
        }
        let rendered = Instant::now();
        let frame = camera.next_frame();
        result.render_seconds += rendered.elapsed().as_secs_f64();
        if let Some(Ok(frame)) = frame {
            let started = Instant::now();
            let tracked = vo.process(&frame);
            result.vo_seconds += started.elapsed().as_secs_f64();
            match tracked {
                Ok((stamped, _)) => {
                    result.vo_frames += 1;
                    if let Some(last) = last_camera {
                        let motion = planar_motion(
                            &t_base_camera,
                            &(last.inverse() * stamped.t_world_camera),
                        );
                        vo_pose = vo_pose.compose(&motion);
                        fusion.update_visual(&motion, &config.vo_noise);
                    }
                    last_camera = Some(stamped.t_world_camera);
                }
                Err(err) => {
                    tracing::warn!(frame = frame_index, error = %err, "visual odometry failed on a simulated frame")
                }
            }
        }
        let w = lock(world);
        result.points.push(TrialPoint {
            time_s: w.time_ns() as f64 * 1e-9,
            truth: pose2(&w.pose(id)?),
            wheel: wheels.pose(),
            vo: vo_pose,
            fused: fusion.pose(),
        });
    }
    Ok(result)
}
