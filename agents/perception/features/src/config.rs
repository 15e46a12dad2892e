//! Detector and matcher parameters, each with its unit, default and range.

use crate::{DetectorKind, FeatureError};

/// Which image LSAC-SURF divides by twice its local average.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LsacSpace {
    /// Thesis Algorithm 2 as printed: gray first, then `gray / (2 a_gray)`. Invariant to a common
    /// gain on all channels, not to a change of illuminant colour.
    Gray,
    /// Ebner's descriptor per channel, `O_k = I_k / (2 a_k)` (thesis eq. 4.17), then the luma of
    /// `O`: also invariant to a per-channel gain (the diagonal model, LCC). The default.
    PerChannel,
}

/// LSAC-SURF-NT's noise factor: see [`DetectorConfig::noise_factor`]. Chosen on synthetic
/// dimming sequences (photographs warped, darkened to 1/16 with shot and read noise), not on the
/// real-light ones: with the contrast-normalised threshold, the largest factor tried (4, 6, 8,
/// 11) whose uncapped keypoint count stayed within +-30 % of the reference on every sequence
/// and gain (docs/results/repeatability.md).
const NT_NOISE_FACTOR: f32 = 6.0;
/// Quantile of the finest tested layer's positive responses taken as the image's contrast scale
/// ([`DetectorConfig::contrast_threshold`]).
pub const CONTRAST_QUANTILE: f32 = 0.9;
/// LSAC-SURF-NT's base threshold: low, so that the contrast-normalised threshold, the noise
/// floor and the cap decide.
const NT_THRESHOLD: f32 = 1.0;
/// LSAC-SURF-NT's contrast-normalised threshold: see [`DetectorConfig::contrast_threshold`].
/// Of 0.3, 0.5, 1 and 2 (tuning set and LCC; docs/results/repeatability.md), 1 held the count
/// closest on the tuning set and kept the most of LCC.
const NT_CONTRAST_THRESHOLD: f32 = 1.0;
/// LSAC-SURF-NT's keypoint count: the strongest responses above the noise floor, as many as
/// ORB's default; the thesis's fairness rule (4.6) then compares detectors at this count.
const NT_MAX_KEYPOINTS: usize = 1000;
/// LSAC-SURF-NT's rank: response x (9 / size)^1.5, see [`DetectorConfig::rank_size_exponent`].
const NT_RANK_SIZE_EXPONENT: f32 = 1.5;
/// LSAC-SURF-NT's spacing of the kept keypoints, input px: the protocol's tolerance (2 px).
const NT_MIN_SEPARATION_PX: f32 = 2.0;

/// Most de-quantisation rounds accepted: each costs two passes over every channel.
const MAX_DEQUANTISE_ITERATIONS: usize = 256;

/// Parameters of the shared SURF pipeline. Build with [`DetectorConfig::for_kind`], then adjust.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DetectorConfig {
    /// Octaves of the box-filter scale space, 1..=6 (default 4: filters up to 195 px).
    pub octaves: usize,
    /// Filter sizes per octave, 3..=8 (default 4: 9, 15, 21, 27 in the first octave).
    pub levels: usize,
    /// Minimum response kept before non-maximum suppression. Units: the Hessian determinant of
    /// 8-bit intensities normalised by the filter area (OpenCV's `hessianThreshold` scale) for
    /// SURF and LSAC-SURF; dimensionless (determinant / variance) for LN-SURF.
    pub threshold: f32,
    /// Skip the orientation step (U-SURF): faster, for a camera that does not roll.
    pub upright: bool,
    /// LN-SURF: smallest variance used as divisor, in 8-bit intensity units squared (default 1.0,
    /// about the rounding noise of an 8-bit camera): keeps perfectly flat patches at zero response.
    pub ln_min_variance: f32,
    /// LSAC-SURF: radius of the largest of the three nested boxes approximating the Gaussian
    /// local average, px (default 12; the thesis found small neighbourhoods work best).
    pub lsac_radius_px: usize,
    /// LSAC-SURF: smallest local average used as divisor, 8-bit units (default 4): a black region
    /// would otherwise turn its rounding noise into full-contrast texture.
    pub lsac_min_average: f32,
    /// LSAC-SURF: per-channel or gray local average (see [`LsacSpace`]).
    pub lsac_space: LsacSpace,
    /// `(lower, upper)` 8-bit gray thresholds: a keypoint whose pixel lies strictly between them is
    /// hard, otherwise soft (thesis Algorithm 2, lines 13-20). `None`: every keypoint is hard.
    pub soft_band: Option<(u8, u8)>,
    /// Keep at most this many keypoints, highest rank first (`None`: all; the rank is the
    /// response unless [`Self::rank_size_exponent`] says otherwise).
    pub max_keypoints: Option<usize>,
    /// Detect on the input doubled in size (bilinear, then a Gaussian of sigma 1.6 doubled px,
    /// kept in float: no rounding back to 8 bits), Lowe's octave -1: the finest interior filter
    /// (15 px) then sees 7.5 input px, closer to the scales where a keypoint localises within a
    /// pixel or two. Keypoints, sizes and scales are reported in input pixels; the LSAC radius
    /// and the noise tile stay in pixels of the doubled image. Costs 4x the pixels.
    #[serde(default)]
    pub upsample: bool,
    /// With `max_keypoints`: rank keypoints by `response x (9 / size)^e` instead of the response
    /// (0: the response). A coarse keypoint's position is interpolated on a grid of step
    /// `2^octave` and blurred by its filter, so under a fixed pixel tolerance a fine keypoint of
    /// the same response is the likelier to repeat; 0..=8.
    #[serde(default)]
    pub rank_size_exponent: f32,
    /// With `max_keypoints`: drop a keypoint within this distance (input px, any scale) of a
    /// higher-ranked kept one (0: off; 0..=64). Two keypoints closer than the repeatability
    /// tolerance can correspond to one point of the other image only once.
    #[serde(default)]
    pub min_separation_px: f32,
    /// Noise-aware threshold, LSAC kinds only (0: off, the thesis's detectors). The camera's
    /// noise is estimated from the input (Immerkaer's finest-scale operator, a low quantile over
    /// tiles) and carried into the working image through the local average at each keypoint
    /// (the LSAC division multiplies it by `255 / (2 a)`): a keypoint is kept only if its
    /// response also exceeds `noise_factor` times what that noise gives at its filter size in
    /// its region, and the cap ranks by response over that noise (signal-to-noise) rather than
    /// by the response (see `noise`).
    #[serde(default)]
    pub noise_factor: f32,
    /// Contrast-normalised threshold (0: off, the thesis's detectors): a keypoint is kept only if
    /// its response also exceeds this fraction of the image's contrast scale, the
    /// [`CONTRAST_QUANTILE`] of the finest tested layer's positive responses. A fixed threshold
    /// keeps more keypoints the more contrast the image has (a haze or a dim, flat light loses
    /// them, a sharp postcard gains them); relative to the image's own response distribution the
    /// count follows the structure, not the contrast. 0..=1000.
    #[serde(default)]
    pub contrast_threshold: f32,
    /// Side of the square tiles of the input the camera's noise is estimated in, input px
    /// (16..=512; default 32).
    #[serde(default = "default_noise_tile_px")]
    pub noise_tile_px: usize,
    /// With [`Self::upsample`]: sigma of the Gaussian the doubled image is blurred by, doubled px
    /// (default 1.6, SIFT's base scale; 0.5..=8).
    #[serde(default = "default_doubled_sigma")]
    pub doubled_sigma: f32,
    /// De-quantisation before detection, rounds (0: off; 0..=256). An 8-bit value `v` says only
    /// that the light there lay within `[v - 0.5, v + 0.5]`; where the contrast is low (a dim or
    /// tinted light, LCC) whole regions round to one value and their edges become steps that
    /// move with the rounding, and the LSAC division magnifies them. Each round blurs every
    /// channel by the binomial `[1, 2, 1] / 4` and clamps each sample back into its
    /// quantisation cell: toward the smoothest image the 8 bits allow, moving no sample more
    /// than half a grey level, the same rule for every image. Off in every detector's defaults:
    /// it lost on LIC and LCC (docs/results/repeatability.md, tenth round), since at low
    /// contrast a photograph's pixel-scale texture is a fraction of a step, and the smoothest
    /// image flattens it by more than the rounding moved it.
    #[serde(default)]
    pub dequantise_iterations: usize,
}

fn default_noise_tile_px() -> usize {
    32
}

fn default_doubled_sigma() -> f32 {
    1.6
}

impl DetectorConfig {
    /// The defaults used in the experiments for `kind`. Thresholds were chosen so that the three
    /// detectors find similar numbers of keypoints on the shared photographs (as the thesis set
    /// LN-SURF's to match SURF's count).
    pub fn for_kind(kind: DetectorKind) -> Self {
        let base = DetectorConfig {
            octaves: 4,
            levels: 4,
            threshold: 100.0,
            upright: false,
            ln_min_variance: 1.0,
            lsac_radius_px: 12,
            lsac_min_average: 4.0,
            lsac_space: LsacSpace::PerChannel,
            soft_band: None,
            max_keypoints: None,
            upsample: false,
            rank_size_exponent: 0.0,
            min_separation_px: 0.0,
            noise_factor: 0.0,
            contrast_threshold: 0.0,
            noise_tile_px: default_noise_tile_px(),
            doubled_sigma: default_doubled_sigma(),
            dequantise_iterations: 0,
        };
        match kind {
            DetectorKind::Surf => base,
            DetectorKind::LnSurf => DetectorConfig {
                threshold: 0.02,
                ..base
            },
            DetectorKind::LsacSurf => DetectorConfig {
                soft_band: Some((10, 245)),
                ..base
            },
            DetectorKind::LsacSurfNt => DetectorConfig {
                soft_band: Some((10, 245)),
                noise_factor: NT_NOISE_FACTOR,
                threshold: NT_THRESHOLD,
                contrast_threshold: NT_CONTRAST_THRESHOLD,
                max_keypoints: Some(NT_MAX_KEYPOINTS),
                upsample: true,
                rank_size_exponent: NT_RANK_SIZE_EXPONENT,
                min_separation_px: NT_MIN_SEPARATION_PX,
                ..base
            },
        }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |field, value: String, reason| {
            Err(FeatureError::InvalidConfig {
                field,
                value,
                reason,
            })
        };
        if !(1..=6).contains(&self.octaves) {
            return bad("octaves", self.octaves.to_string(), "expected 1..=6");
        }
        if !(3..=8).contains(&self.levels) {
            return bad(
                "levels",
                self.levels.to_string(),
                "expected 3..=8 (two neighbours per tested level)",
            );
        }
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return bad(
                "threshold",
                self.threshold.to_string(),
                "expected a finite value >= 0",
            );
        }
        if !(self.ln_min_variance.is_finite() && self.ln_min_variance > 0.0) {
            return bad(
                "ln_min_variance",
                self.ln_min_variance.to_string(),
                "expected a finite value > 0",
            );
        }
        if !(1..=256).contains(&self.lsac_radius_px) {
            return bad(
                "lsac_radius_px",
                self.lsac_radius_px.to_string(),
                "expected 1..=256",
            );
        }
        if !(self.lsac_min_average.is_finite() && self.lsac_min_average >= 0.5) {
            return bad(
                "lsac_min_average",
                self.lsac_min_average.to_string(),
                "expected a finite value >= 0.5",
            );
        }
        if !(self.noise_factor.is_finite() && self.noise_factor >= 0.0) {
            return bad(
                "noise_factor",
                self.noise_factor.to_string(),
                "expected a finite value >= 0 (0: off)",
            );
        }
        if !(self.rank_size_exponent.is_finite() && (0.0..=8.0).contains(&self.rank_size_exponent))
        {
            return bad(
                "rank_size_exponent",
                self.rank_size_exponent.to_string(),
                "expected 0..=8 (0: rank by the response)",
            );
        }
        if !(self.min_separation_px.is_finite() && (0.0..=64.0).contains(&self.min_separation_px)) {
            return bad(
                "min_separation_px",
                self.min_separation_px.to_string(),
                "expected 0..=64 px (0: off)",
            );
        }
        if !(self.contrast_threshold.is_finite()
            && (0.0..=1000.0).contains(&self.contrast_threshold))
        {
            return bad(
                "contrast_threshold",
                self.contrast_threshold.to_string(),
                "expected 0..=1000 (0: off)",
            );
        }
        if !(16..=512).contains(&self.noise_tile_px) {
            return bad(
                "noise_tile_px",
                self.noise_tile_px.to_string(),
                "expected 16..=512",
            );
        }
        if !(self.doubled_sigma.is_finite() && (0.5..=8.0).contains(&self.doubled_sigma)) {
            return bad(
                "doubled_sigma",
                self.doubled_sigma.to_string(),
                "expected 0.5..=8 doubled px",
            );
        }
        if self.dequantise_iterations > MAX_DEQUANTISE_ITERATIONS {
            return bad(
                "dequantise_iterations",
                self.dequantise_iterations.to_string(),
                "expected 0..=256 rounds (0: off)",
            );
        }
        if let Some((lower, upper)) = self.soft_band
            && lower >= upper
        {
            return bad(
                "soft_band",
                format!("({lower}, {upper})"),
                "expected lower < upper",
            );
        }
        Ok(())
    }
}

/// Parameters of [`crate::match_features`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MatchConfig {
    /// Lowe's ratio: keep a match when best < ratio * second best, (0, 1] (default 0.8).
    pub ratio: f32,
    /// Keep a match only if each side is the other's nearest neighbour (default true).
    pub mutual: bool,
    /// Only hard query features are matched, against all train features (thesis 4.5; default true).
    pub hard_queries_only: bool,
    /// Reject matches with a larger descriptor distance (default 0.6 for unit descriptors).
    pub max_distance: f32,
}

impl Default for MatchConfig {
    fn default() -> Self {
        MatchConfig {
            ratio: 0.8,
            mutual: true,
            hard_queries_only: true,
            max_distance: 0.6,
        }
    }
}

impl MatchConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), FeatureError> {
        if !(self.ratio > 0.0 && self.ratio <= 1.0) {
            return Err(FeatureError::InvalidConfig {
                field: "ratio",
                value: self.ratio.to_string(),
                reason: "expected 0 < ratio <= 1",
            });
        }
        if self.max_distance.is_nan() || self.max_distance <= 0.0 {
            return Err(FeatureError::InvalidConfig {
                field: "max_distance",
                value: self.max_distance.to_string(),
                reason: "expected > 0",
            });
        }
        Ok(())
    }
}
