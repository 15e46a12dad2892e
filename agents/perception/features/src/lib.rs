//! SURF, LN-SURF and LSAC-SURF feature detection, description and matching (thesis 2.8.4, ch. 4).
//!
//! One pipeline, three detector choices: the [`DetectorKind`] only decides which *working image*
//! the box-filter Hessian runs on (gray intensity, or the local space average colour image) and
//! whether the Hessian determinant is divided by the local variance under the filter. Everything
//! else (scale space, non-maximum suppression, interpolation, orientation, descriptor) is shared.
//!
//! # Organization
//! - [`Detector`]: the pipeline with caller-owned scratch buffers, reused frame after frame;
//!   [`detect`] is the one-shot convenience. [`DetectorConfig`] holds every parameter with units.
//! - [`match_features`] with [`MatchConfig`]: brute force, Lowe ratio test, mutual check, hard
//!   features matched against all, opposite Laplacian signs skipped.
//! - [`experiment`]: the thesis's illumination collections (LIC, LIS, LCC), the repeatability
//!   protocol (eq. 4.66); detectors are compared with `iw_stats`' Wilcoxon signed-rank test.
//! - [`sequence`] with [`homography`]: the same protocol on real sequences with ground-truth
//!   homographies (real light, moving camera).
//! - [`GrayImage32`], [`IntegralImage`]: typed buffers the pipeline works on.
//!
//! # Guarantees
//! - Any `RgbImage` is accepted (empty or tiny images give no features, never a panic); only an
//!   inconsistent [`DetectorConfig`] is an error ([`FeatureError`]).
//! - Integral-image box sums are exact (fixed-point integers with wrapping arithmetic), so the
//!   responses do not depend on where a box lies in the image.
//! - `Features::descriptors[i]` belongs to `Features::keypoints[i]`, unit length (or all zero on
//!   a perfectly flat patch). Output is deterministic: the same image gives the same features.
//!
//! The visual odometry (`iw-vo`) builds on [`DetectorKind`], [`Keypoint`], [`FeatureClass`],
//! [`Features`] and [`Match`], through [`detect`], [`Detector::detect`] and [`match_features`].
#![warn(missing_docs)]

mod config;
mod describe;
pub mod experiment;
mod extrema;
mod hessian;
pub mod homography;
mod image32;
mod integral;
mod matching;
mod noise;
mod select;
pub mod sequence;
mod simd;
mod working;

pub use config::{CONTRAST_QUANTILE, DetectorConfig, LsacSpace, MatchConfig};
pub use image32::GrayImage32;
pub use integral::IntegralImage;
pub use matching::match_features;

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
    /// LSAC-SURF with a noise-aware threshold (not in the thesis): the local average division
    /// amplifies sensor noise where the image is dark, so a keypoint must also stand above what
    /// the image's own noise gives in its region, and the strongest by signal-to-noise are kept
    /// (see [`DetectorConfig::noise_factor`]), and above a threshold relative to the image's own
    /// contrast, so the count below the cap follows the structure, not the contrast
    /// ([`DetectorConfig::contrast_threshold`]); of those, [`DetectorConfig::max_keypoints`] are
    /// kept, so the count does not follow the light. Detected on the doubled image ([`DetectorConfig::upsample`]); the kept ones are
    /// ranked toward fine scales and spaced 2 px apart
    /// ([`DetectorConfig::rank_size_exponent`], [`DetectorConfig::min_separation_px`]).
    LsacSurfNt,
}

impl DetectorKind {
    /// All detectors, in the order the thesis compares them.
    pub const ALL: [DetectorKind; 4] = [
        DetectorKind::Surf,
        DetectorKind::LnSurf,
        DetectorKind::LsacSurf,
        DetectorKind::LsacSurfNt,
    ];

    /// The command-line and JSON name: `surf`, `ln-surf`, `lsac-surf`, `lsac-surf-nt`.
    pub fn name(self) -> &'static str {
        match self {
            DetectorKind::Surf => "surf",
            DetectorKind::LnSurf => "ln-surf",
            DetectorKind::LsacSurf => "lsac-surf",
            DetectorKind::LsacSurfNt => "lsac-surf-nt",
        }
    }

    /// Whether the detector runs on the local space average colour image.
    pub fn is_lsac(self) -> bool {
        matches!(self, DetectorKind::LsacSurf | DetectorKind::LsacSurfNt)
    }
}

impl std::str::FromStr for DetectorKind {
    type Err = FeatureError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        DetectorKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| FeatureError::UnknownDetector {
                name: s.to_string(),
            })
    }
}

impl std::fmt::Display for DetectorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
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

/// Why detection could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FeatureError {
    /// A [`DetectorConfig`] or [`MatchConfig`] field is out of its range.
    #[error("invalid config `{field}` = {value}: {reason}")]
    InvalidConfig {
        /// Field name.
        field: &'static str,
        /// The offending value, printed.
        value: String,
        /// The accepted range.
        reason: &'static str,
    },
    /// A detector name that is none of `surf`, `ln-surf`, `lsac-surf`, `lsac-surf-nt`.
    #[error("unknown detector `{name}` (expected surf, ln-surf, lsac-surf or lsac-surf-nt)")]
    UnknownDetector {
        /// The name given.
        name: String,
    },
}

/// The shared pipeline with its scratch buffers; keep one per thread and call [`Detector::detect`]
/// for every frame to avoid re-allocating the integral images and response maps.
#[derive(Debug, Default)]
pub struct Detector {
    scratch: working::Scratch,
    /// The input in float, de-quantised ([`DetectorConfig::dequantise_iterations`]) and doubled
    /// ([`DetectorConfig::upsample`]) as the config asks.
    planes: working::Planes,
    /// One plane of the input (a channel, or the luma), where the noise model measures the
    /// camera's noise.
    input_plane: GrayImage32,
    layers: hessian::ScaleSpace,
}

impl Detector {
    /// An empty pipeline; buffers grow on the first frame.
    pub fn new() -> Self {
        Self::default()
    }

    /// Detects and describes the features of `image` with detector `kind`.
    pub fn detect(
        &mut self,
        kind: DetectorKind,
        image: &RgbImage,
        config: &DetectorConfig,
    ) -> Result<Features, FeatureError> {
        config.validate()?;
        let (width, height) = (image.width() as usize, image.height() as usize);
        if width == 0 || height == 0 {
            return Ok(Features::default());
        }
        let (source, pixel) = if config.upsample || config.dequantise_iterations > 0 {
            self.planes.load(image, config.dequantise_iterations);
            if config.upsample {
                self.planes.double(config.doubled_sigma);
            }
            let pixel = if config.upsample { 2.0 } else { 1.0 };
            (working::Source::Planes(&self.planes), pixel)
        } else {
            (working::Source::Rgb(image), 1.0)
        };
        self.scratch.prepare(kind, source, config);
        let normalise = (kind == DetectorKind::LnSurf).then_some(&self.scratch.gray_integral);
        self.layers
            .compute(self.scratch.working(kind), normalise, config);
        let mut keypoints = extrema::find(&self.layers, config);
        // Contrast-normalised threshold (LSAC-SURF-NT): relative to the image's own responses.
        if config.contrast_threshold > 0.0 {
            let floor = config.contrast_threshold * self.layers.contrast(CONTRAST_QUANTILE);
            keypoints.retain(|kp| kp.response > floor);
        }
        // The noise model (LSAC-SURF-NT): drop responses noise could give in their region, and
        // rank the rest by signal-to-noise (the weights) rather than by the bare response.
        let weights = if config.noise_factor > 0.0 && kind.is_lsac() {
            let floor = noise::NoiseFloor::measure(image, &mut self.input_plane, config);
            let mut weights = Vec::with_capacity(keypoints.len());
            keypoints.retain(|kp| {
                let unit = floor.unit(self.scratch.local_averages_at(kp.x, kp.y, config));
                let keep = kp.response > floor.threshold(kp, unit);
                if keep {
                    weights.push(1.0 / unit);
                }
                keep
            });
            Some(weights)
        } else {
            None
        };
        // LN-SURF describes on the intensity image (Algorithm 1), LSAC-SURF on its working space.
        let describe_on = self.scratch.working(kind);
        let mut keypoints = select::apply(keypoints, weights.as_deref(), config, pixel);
        for kp in &mut keypoints {
            kp.class = working::classify(&self.scratch.gray, kp, config.soft_band);
        }
        let descriptors = describe::describe(describe_on, &mut keypoints, config.upright);
        if config.upsample {
            // Pixel centres: doubled pixel X covers input [X / 2, (X + 1) / 2).
            for kp in &mut keypoints {
                kp.x = (kp.x + 0.5) / pixel - 0.5;
                kp.y = (kp.y + 0.5) / pixel - 0.5;
                kp.size /= pixel;
                kp.scale /= pixel;
            }
        }
        Ok(Features {
            keypoints,
            descriptors,
        })
    }
}

/// One-shot detection with fresh buffers (see [`Detector`] to reuse them across frames).
pub fn detect(
    kind: DetectorKind,
    image: &RgbImage,
    config: &DetectorConfig,
) -> Result<Features, FeatureError> {
    Detector::new().detect(kind, image, config)
}

#[cfg(test)]
mod tests;
