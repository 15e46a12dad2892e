//! RGB-D visual odometry (thesis chapter 5, Algorithm 3), wheel odometry (thesis 3.3.2) and their
//! fusion: the perception agent's estimation algorithms, as a library.
//!
//! # Organization
//! - [`TumSequence`], [`tum`]: the TUM RGB-D layout (lists, timestamp association, trajectories).
//! - [`CameraSource`], [`TumReplay`], [`RgbdFrame`]: frames with timestamps; the replay decodes
//!   PNGs on loader threads ahead of tracking.
//! - [`Intrinsics`]: pinhole + distortion + depth scale, back-projection and projection.
//! - [`umeyama`], [`ransac_rigid`]: rigid fits of 3D point pairs (thesis 5.3).
//! - [`VisualOdometry`] with [`VoConfig`] and [`Pipeline`]: the thesis's frame-to-frame pipeline
//!   and a keyframe pipeline with local motion-only bundle adjustment ([`refine`]).
//! - [`eval`]: ATE and RPE as in the TUM benchmark.
//! - [`WheelOdometry`], [`OdometryFusion`]: differential-drive dead reckoning with the
//!   probabilistic odometry motion model, and the EKF fusing it with visual odometry.
//!
//! # Guarantees
//! - No panic on any file content: malformed lists, trajectories and images are [`VoError`]s that
//!   name the file (and line).
//! - Deterministic: RANSAC draws from a seeded ChaCha generator; the same frames and seed give the
//!   same trajectory, whatever the number of loader threads.
//! - Frames in names: `t_a_b` maps coordinates of frame b into frame a (`t_world_camera`).
//!
//! # Known limits
//! - Visual odometry holds the last pose when fewer than [`VoConfig::min_inliers`] pairs agree
//!   (textureless or blurred frames); there is no relocalisation or loop closure.
#![warn(missing_docs)]

mod camera;
mod error;
pub mod eval;
mod fusion;
mod geometry;
mod odometry;
pub mod refine;
mod source;
pub mod tum;
mod wheel;

pub use camera::{Distortion, Intrinsics};
pub use error::VoError;
pub use fusion::{OdometryFusion, VisualNoise, WheelBias, planar_motion};
pub use geometry::{RansacParams, RigidFit, ransac_rigid, umeyama};
pub use odometry::{FrameStats, KeyframeParams, Pipeline, VisualOdometry, VoConfig};
pub use source::{CameraSource, DepthImage, RgbdFrame, TumReplay, load_pair};
pub use tum::{FramePair, StampedPose, TumSequence};
pub use wheel::{
    AccelerationSlip, DiffDriveParams, OdometryStep, Pose2, WheelOdometry, WheelRates, wrap_angle,
};
