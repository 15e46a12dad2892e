//! SURF, LN-SURF and LSAC-SURF feature detection, description and matching (thesis 2.8.4, ch. 4).
//!
//! API CONTRACT (shared with `iw-vo`; the vision work fills in the bodies and may extend, but keeps
//! these names and signatures): one pipeline, three detector choices.
#![warn(missing_docs)]

use image::RgbImage;

/// Which response the shared SURF pipeline detects on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DetectorKind {
    /// Plain SURF (Bay et al.) on the intensity image.
    Surf,
    /// SURF with the Hessian normalised by the local variance (thesis Algorithm 1).
    LnSurf,
    /// SURF on the local space average colour image (thesis Algorithm 2).
    LsacSurf,
}

/// Hard features are trusted everywhere; soft ones lie near saturation (thesis Algorithm 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FeatureClass {
    /// Away from saturated pixels.
    Hard,
    /// Near saturated pixels.
    Soft,
}

/// One detected interest point, in pixel coordinates of the input image.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Keypoint {
    /// Column, px (sub-pixel).
    pub x: f32,
    /// Row, px (sub-pixel).
    pub y: f32,
    /// SURF scale s (1.2 for the 9x9 filter).
    pub scale: f32,
    /// Diameter in px, as OpenCV's `KeyPoint.size`.
    pub size: f32,
    /// Dominant orientation, radians.
    pub orientation: f32,
    /// Detector response (Hessian determinant, normalised for LN-SURF).
    pub response: f32,
    /// Sign of the Laplacian (+1 or -1): matching skips pairs of opposite sign.
    pub laplacian_sign: i8,
    /// Hard or soft.
    pub class: FeatureClass,
}

/// Keypoints with their 64-element descriptors, `descriptors[i]` belongs to `keypoints[i]`.
#[derive(Debug, Clone, Default)]
pub struct Features {
    /// The keypoints.
    pub keypoints: Vec<Keypoint>,
    /// Unit-length SURF descriptors.
    pub descriptors: Vec<[f32; 64]>,
}

/// A correspondence `query[query_index] <-> train[train_index]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Index into the first feature set.
    pub query_index: usize,
    /// Index into the second feature set.
    pub train_index: usize,
    /// Euclidean descriptor distance.
    pub distance: f32,
}
