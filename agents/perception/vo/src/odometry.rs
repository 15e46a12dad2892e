//! The visual odometry pipeline (thesis Algorithm 3) and its keyframe variant.
//!
//! Per frame: detect features (LSAC-SURF, SURF or LN-SURF), back-project them with the depth image,
//! match them to a reference, fit the rigid motion with RANSAC + Umeyama, compose the pose.
//! - [`Pipeline::Thesis`]: the reference is the previous frame; nothing else (Algorithm 3 as written).
//! - [`Pipeline::Keyframe`]: the reference is the current keyframe, replaced only when the overlap
//!   shrinks or the camera moved far; then the pose is refined by motion-only bundle adjustment
//!   against the last few keyframes (brute-force matches with the keyframe, projection-guided
//!   matches with the older ones), so small motions do not integrate frame-to-frame noise.

use std::collections::VecDeque;
use std::time::Instant;

use iw_features::{Detector, DetectorConfig, DetectorKind, Features, MatchConfig, match_features};
use nalgebra::{Isometry3, Point2, Point3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::refine::{Observation, RefineParams, refine_pose};
use crate::source::{DepthImage, RgbdFrame};
use crate::tum::StampedPose;
use crate::{Intrinsics, RansacParams, VoError, ransac_rigid};

/// Which pipeline runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Pipeline {
    /// Thesis Algorithm 3: frame-to-frame RANSAC + Umeyama.
    Thesis,
    /// Frame-to-keyframe tracking with local motion-only bundle adjustment.
    Keyframe,
}

impl std::str::FromStr for Pipeline {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "thesis" => Ok(Pipeline::Thesis),
            "keyframe" => Ok(Pipeline::Keyframe),
            _ => Err(format!(
                "unknown pipeline `{s}` (expected thesis or keyframe)"
            )),
        }
    }
}

/// When the keyframe pipeline starts a new keyframe, and how many it keeps.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KeyframeParams {
    /// New keyframe once the camera is this far from the keyframe, m.
    pub max_translation_m: f64,
    /// New keyframe once the camera turned this much from the keyframe, rad.
    pub max_rotation_rad: f64,
    /// New keyframe once fewer RANSAC inliers than this remain with the keyframe.
    pub min_inliers: usize,
    /// Keyframes the refinement matches against (the current one included).
    pub window: usize,
    /// Search radius of projection-guided matching, px.
    pub guided_radius_px: f64,
    /// Guided matches must be this much closer than the second best (Lowe ratio).
    pub guided_ratio: f32,
}

impl Default for KeyframeParams {
    fn default() -> Self {
        KeyframeParams {
            max_translation_m: 0.08,
            max_rotation_rad: 8f64.to_radians(),
            min_inliers: 30,
            window: 4,
            guided_radius_px: 12.0,
            guided_ratio: 0.85,
        }
    }
}

/// Everything the odometry needs besides the frames.
#[derive(Debug, Clone)]
pub struct VoConfig {
    /// Feature detector.
    pub detector: DetectorKind,
    /// Detector parameters.
    pub detector_config: DetectorConfig,
    /// Brute-force matcher parameters.
    pub match_config: MatchConfig,
    /// Thesis or keyframe pipeline.
    pub pipeline: Pipeline,
    /// RANSAC parameters.
    pub ransac: RansacParams,
    /// Keyframe pipeline settings.
    pub keyframe: KeyframeParams,
    /// Refinement settings (keyframe pipeline).
    pub refine: RefineParams,
    /// Seed of the RANSAC sampler: the same seed and frames give the same trajectory.
    pub seed: u64,
    /// Below this many RANSAC inliers the motion is not trusted and the pose is held.
    pub min_inliers: usize,
}

impl VoConfig {
    /// Defaults for a detector and pipeline (thesis: 35 RANSAC hypotheses; keyframe: 100 and a refit).
    pub fn new(detector: DetectorKind, pipeline: Pipeline) -> Self {
        let ransac = match pipeline {
            Pipeline::Thesis => RansacParams::default(),
            Pipeline::Keyframe => RansacParams {
                iterations: 100,
                refit_rounds: 2,
                ..RansacParams::default()
            },
        };
        // Thesis 5.3: brute force with a cross check only; the keyframe pipeline adds Lowe's ratio.
        let match_config = match pipeline {
            Pipeline::Thesis => MatchConfig {
                ratio: 1.0,
                ..MatchConfig::default()
            },
            Pipeline::Keyframe => MatchConfig::default(),
        };
        VoConfig {
            detector,
            detector_config: DetectorConfig::for_kind(detector),
            match_config,
            pipeline,
            ransac,
            keyframe: KeyframeParams::default(),
            refine: RefineParams::default(),
            seed: 0,
            min_inliers: 8,
        }
    }
}

/// What happened on one frame, and where the time went.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct FrameStats {
    /// Frame time, s.
    pub timestamp_s: f64,
    /// Features detected.
    pub features: usize,
    /// Features with a valid depth reading.
    pub with_depth: usize,
    /// Descriptor matches with the reference (both ends with depth).
    pub matches: usize,
    /// RANSAC inliers among them.
    pub inliers: usize,
    /// Observations kept by the refinement (keyframe pipeline), 0 otherwise.
    pub refined_inliers: usize,
    /// The motion was estimated (false: too few inliers, pose held).
    pub tracked: bool,
    /// This frame became a keyframe.
    pub keyframe: bool,
    /// PNG decoding on the loader threads, ms (overlaps tracking).
    pub decode_ms: f64,
    /// Detection and description, ms.
    pub detect_ms: f64,
    /// Back-projection and matching, ms.
    pub match_ms: f64,
    /// RANSAC and Umeyama, ms.
    pub ransac_ms: f64,
    /// Guided matching and bundle adjustment, ms.
    pub refine_ms: f64,
}

/// `t_reference_current` and the inlier pairs `(current index, reference index)`.
type ReferenceFit = (Isometry3<f64>, Vec<(usize, usize)>);

/// Features of one frame with their camera-frame 3D points.
struct Observed {
    features: Features,
    /// Camera-frame point of keypoint `i`, when its depth is valid.
    points: Vec<Option<Point3<f64>>>,
    /// Undistorted normalised coordinates of keypoint `i`.
    normalised: Vec<Point2<f64>>,
}

struct Keyframe {
    t_world_camera: Isometry3<f64>,
    observed: Observed,
}

/// Depth at a keypoint: the reading at its pixel, rejected when missing, out of range, or on a
/// depth edge (3x3 neighbours disagree by more than 4 %, where Kinect depth is interpolated).
fn keypoint_depth(depth: &DepthImage, k: &Intrinsics, x: f32, y: f32) -> Option<f64> {
    let (u, v) = (x.round() as i64, y.round() as i64);
    let (w, h) = (i64::from(depth.width()), i64::from(depth.height()));
    if u < 1 || v < 1 || u >= w - 1 || v >= h - 1 {
        return None;
    }
    let at = |du: i64, dv: i64| depth.get_pixel((u + du) as u32, (v + dv) as u32).0[0];
    let z = k.depth_m(at(0, 0))?;
    for (du, dv) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
        let zn = k.depth_m(at(du, dv))?;
        if (zn - z).abs() > 0.04 * z {
            return None;
        }
    }
    Some(z)
}

fn descriptor_distance2(a: &[f32; 64], b: &[f32; 64]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The odometry state: current pose, reference frame or keyframes, scratch buffers.
pub struct VisualOdometry {
    config: VoConfig,
    intrinsics: Intrinsics,
    detector: Detector,
    rng: ChaCha8Rng,
    t_world_camera: Isometry3<f64>,
    /// Thesis: the previous frame; keyframe pipeline: the newest keyframe is `window.back()`.
    window: VecDeque<Keyframe>,
}

impl VisualOdometry {
    /// Starts at the identity pose (the first frame defines the world frame).
    pub fn new(config: VoConfig, intrinsics: Intrinsics) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(config.seed);
        VisualOdometry {
            config,
            intrinsics,
            detector: Detector::new(),
            rng,
            t_world_camera: Isometry3::identity(),
            window: VecDeque::new(),
        }
    }

    /// The current pose estimate.
    pub fn t_world_camera(&self) -> Isometry3<f64> {
        self.t_world_camera
    }

    fn observe(&mut self, frame: &RgbdFrame, stats: &mut FrameStats) -> Result<Observed, VoError> {
        let started = Instant::now();
        let features = self.detector.detect(
            self.config.detector,
            &frame.rgb,
            &self.config.detector_config,
        )?;
        stats.detect_ms = started.elapsed().as_secs_f64() * 1e3;
        let k = &self.intrinsics;
        let normalised: Vec<Point2<f64>> = features
            .keypoints
            .iter()
            .map(|kp| k.normalise(Point2::new(f64::from(kp.x), f64::from(kp.y))))
            .collect();
        let points: Vec<Option<Point3<f64>>> = features
            .keypoints
            .iter()
            .zip(&normalised)
            .map(|(kp, n)| {
                keypoint_depth(&frame.depth, k, kp.x, kp.y)
                    .map(|z| Point3::new(n.x * z, n.y * z, z))
            })
            .collect();
        stats.features = features.keypoints.len();
        stats.with_depth = points.iter().filter(|p| p.is_some()).count();
        Ok(Observed {
            features,
            points,
            normalised,
        })
    }

    /// Processes the next frame: returns its pose and what happened.
    pub fn process(&mut self, frame: &RgbdFrame) -> Result<(StampedPose, FrameStats), VoError> {
        let mut stats = FrameStats {
            timestamp_s: frame.timestamp_s,
            decode_ms: frame.decode_ms,
            ..FrameStats::default()
        };
        let current = self.observe(frame, &mut stats)?;
        match self.window.back() {
            None => {
                stats.keyframe = true;
                stats.tracked = true;
                self.window.push_back(Keyframe {
                    t_world_camera: self.t_world_camera,
                    observed: current,
                });
            }
            Some(_) => match self.config.pipeline {
                Pipeline::Thesis => self.track_thesis(current, &mut stats),
                Pipeline::Keyframe => self.track_keyframe(current, &mut stats),
            },
        }
        Ok((
            StampedPose {
                timestamp_s: frame.timestamp_s,
                t_world_camera: self.t_world_camera,
            },
            stats,
        ))
    }

    /// RANSAC + Umeyama between the newest reference and `current`: `t_reference_current` and inliers.
    fn fit_to_reference(
        &mut self,
        current: &Observed,
        stats: &mut FrameStats,
    ) -> Option<ReferenceFit> {
        let started = Instant::now();
        let reference = &self.window.back()?.observed;
        let matches = match_features(
            &current.features,
            &reference.features,
            &self.config.match_config,
        );
        let mut pairs = Vec::new();
        let (mut src, mut dst) = (Vec::new(), Vec::new());
        for m in &matches {
            if let (Some(Some(pc)), Some(Some(pr))) = (
                current.points.get(m.query_index),
                reference.points.get(m.train_index),
            ) {
                pairs.push((m.query_index, m.train_index));
                src.push(*pc);
                dst.push(*pr);
            }
        }
        stats.matches = pairs.len();
        stats.match_ms = started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        let fit = ransac_rigid(&src, &dst, &self.config.ransac, &mut self.rng);
        stats.ransac_ms = started.elapsed().as_secs_f64() * 1e3;
        let fit = fit.ok()?;
        stats.inliers = fit.inliers.len();
        (fit.inliers.len() >= self.config.min_inliers).then(|| {
            (
                fit.t_dst_src,
                fit.inliers.iter().map(|&i| pairs[i]).collect(),
            )
        })
    }

    fn track_thesis(&mut self, current: Observed, stats: &mut FrameStats) {
        if let Some((t_previous_current, _)) = self.fit_to_reference(&current, stats) {
            self.t_world_camera *= t_previous_current;
            stats.tracked = true;
        }
        // Algorithm 3 returns the current keypoints as the next call's previous ones.
        self.window.clear();
        self.window.push_back(Keyframe {
            t_world_camera: self.t_world_camera,
            observed: current,
        });
    }

    fn track_keyframe(&mut self, current: Observed, stats: &mut FrameStats) {
        let Some(t_world_keyframe) = self.window.back().map(|kf| kf.t_world_camera) else {
            return;
        };
        let fit = self.fit_to_reference(&current, stats);
        let Some((t_keyframe_current, inlier_pairs)) = fit else {
            // Lost the keyframe: hold the pose and restart tracking from this frame.
            self.push_keyframe(current, stats);
            return;
        };
        stats.tracked = true;
        let started = Instant::now();
        let t_world_current = t_world_keyframe * t_keyframe_current;
        let observations = self.observations(&current, &inlier_pairs, &t_world_current);
        let refined = refine_pose(
            t_world_current.inverse(),
            &observations,
            &self.config.refine,
        );
        stats.refined_inliers = refined.inlier_count;
        self.t_world_camera = refined.t_camera_world.inverse();
        stats.refine_ms = started.elapsed().as_secs_f64() * 1e3;
        let t_keyframe_refined = t_world_keyframe.inverse() * self.t_world_camera;
        let p = &self.config.keyframe;
        if stats.inliers < p.min_inliers
            || t_keyframe_refined.translation.vector.norm() > p.max_translation_m
            || t_keyframe_refined.rotation.angle() > p.max_rotation_rad
        {
            self.push_keyframe(current, stats);
        }
    }

    fn push_keyframe(&mut self, current: Observed, stats: &mut FrameStats) {
        stats.keyframe = true;
        self.window.push_back(Keyframe {
            t_world_camera: self.t_world_camera,
            observed: current,
        });
        while self.window.len() > self.config.keyframe.window.max(1) {
            self.window.pop_front();
        }
    }

    /// Observations for the refinement: the RANSAC inliers with the newest keyframe, plus
    /// projection-guided matches with the older keyframes of the window.
    fn observations(
        &self,
        current: &Observed,
        inlier_pairs: &[(usize, usize)],
        t_world_current: &Isometry3<f64>,
    ) -> Vec<Observation> {
        let mut out = Vec::new();
        let Some(newest) = self.window.back() else {
            return out;
        };
        let observation = |kf: &Keyframe, i_kf: usize, i_cur: usize| {
            kf.observed.points[i_kf].map(|p| Observation {
                p_world: kf.t_world_camera * p,
                normalised: current.normalised[i_cur],
                depth_m: current.points[i_cur].map(|q| q.z),
                source_depth_m: p.z,
            })
        };
        out.extend(
            inlier_pairs
                .iter()
                .filter_map(|&(i_cur, i_kf)| observation(newest, i_kf, i_cur)),
        );
        let older = self.window.len().saturating_sub(1);
        if older == 0 {
            return out;
        }
        let grid = Grid::new(&current.features, 16.0);
        let t_current_world = t_world_current.inverse();
        let p = &self.config.keyframe;
        for kf in self.window.iter().take(older) {
            for (i_kf, point) in kf.observed.points.iter().enumerate() {
                let Some(point) = point else { continue };
                let Some(pixel) = self
                    .intrinsics
                    .project(&(t_current_world * (kf.t_world_camera * point)))
                else {
                    continue;
                };
                let kp = &kf.observed.features.keypoints[i_kf];
                let desc = &kf.observed.features.descriptors[i_kf];
                let (mut best, mut second) = ((f32::INFINITY, usize::MAX), f32::INFINITY);
                grid.near(pixel, p.guided_radius_px, |i_cur| {
                    if current.features.keypoints[i_cur].laplacian_sign != kp.laplacian_sign {
                        return;
                    }
                    let d = descriptor_distance2(desc, &current.features.descriptors[i_cur]);
                    if d < best.0 {
                        second = best.0;
                        best = (d, i_cur);
                    } else if d < second {
                        second = d;
                    }
                });
                let ratio2 = p.guided_ratio * p.guided_ratio;
                if best.1 != usize::MAX && best.0 < 0.25 && best.0 < ratio2 * second {
                    out.extend(observation(kf, i_kf, best.1));
                }
            }
        }
        out
    }
}

/// Keypoints bucketed by pixel cell for radius queries.
struct Grid<'a> {
    features: &'a Features,
    cell_px: f64,
    cols: usize,
    rows: usize,
    cells: Vec<Vec<usize>>,
}

impl<'a> Grid<'a> {
    fn new(features: &'a Features, cell_px: f64) -> Self {
        let max_x = features
            .keypoints
            .iter()
            .map(|k| f64::from(k.x))
            .fold(0.0, f64::max);
        let max_y = features
            .keypoints
            .iter()
            .map(|k| f64::from(k.y))
            .fold(0.0, f64::max);
        let cols = (max_x / cell_px) as usize + 1;
        let rows = (max_y / cell_px) as usize + 1;
        let mut cells = vec![Vec::new(); cols * rows];
        for (i, k) in features.keypoints.iter().enumerate() {
            let (c, r) = (
                (f64::from(k.x).max(0.0) / cell_px) as usize,
                (f64::from(k.y).max(0.0) / cell_px) as usize,
            );
            cells[r.min(rows - 1) * cols + c.min(cols - 1)].push(i);
        }
        Grid {
            features,
            cell_px,
            cols,
            rows,
            cells,
        }
    }

    /// Calls `visit` with every keypoint within `radius_px` of `pixel`.
    fn near(&self, pixel: Point2<f64>, radius_px: f64, mut visit: impl FnMut(usize)) {
        let span = |lo: f64, hi: f64, n: usize| {
            let a = (lo / self.cell_px).floor().max(0.0) as usize;
            let b = ((hi / self.cell_px).floor().max(0.0) as usize).min(n - 1);
            a..=b
        };
        if pixel.x + radius_px < 0.0 || pixel.y + radius_px < 0.0 {
            return;
        }
        for r in span(pixel.y - radius_px, pixel.y + radius_px, self.rows) {
            for c in span(pixel.x - radius_px, pixel.x + radius_px, self.cols) {
                for &i in &self.cells[r * self.cols + c] {
                    let k = &self.features.keypoints[i];
                    let (dx, dy) = (f64::from(k.x) - pixel.x, f64::from(k.y) - pixel.y);
                    if dx * dx + dy * dy <= radius_px * radius_px {
                        visit(i);
                    }
                }
            }
        }
    }
}
