//! The one error type of the crate.

use std::path::Path;

/// Why a sequence, trajectory or estimate could not be produced.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VoError {
    /// A text file (rgb.txt, associations.txt, a trajectory) has a malformed line.
    #[error("{path}:{line}: {reason}")]
    Parse {
        /// File being parsed.
        path: String,
        /// 1-based line number.
        line: usize,
        /// What was wrong, quoting the offending text.
        reason: String,
    },
    /// A file or folder could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// File or folder.
        path: String,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The system refused a loader thread.
    #[error("could start only {started} of {requested} loader threads: {source}")]
    Threads {
        /// Threads asked for.
        requested: usize,
        /// Threads running when the system refused one (stopped again).
        started: usize,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// An image has the wrong pixel format or size.
    #[error("image {path}: {reason}")]
    Image {
        /// Image file.
        path: String,
        /// The mismatch (e.g. "depth must be 16-bit grey, got Rgb8").
        reason: String,
    },
    /// An image file could not be decoded.
    #[error("image {path}: {source}")]
    Decode {
        /// Image file.
        path: String,
        /// What the decoder said.
        #[source]
        source: image::ImageError,
    },
    /// A camera that is not a file (the simulator's, a mirrored one) could not give a frame.
    /// Its error is kept whole; this crate does not know its type (the simulator sits above).
    #[error("camera {camera}: {source}")]
    Camera {
        /// Which camera, e.g. `simulated camera of chair 0`.
        camera: String,
        /// What it said.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// rgb.txt and depth.txt have no pair of timestamps closer than the limit.
    #[error("{dir}: no rgb/depth pair is closer than {max_dt_s} s (check rgb.txt and depth.txt)")]
    NoAssociations {
        /// Sequence folder.
        dir: String,
        /// Largest accepted time difference, s.
        max_dt_s: f64,
    },
    /// The camera model name is not one this crate knows.
    #[error("unknown camera `{name}` (expected freiburg1, freiburg2 or freiburg3)")]
    UnknownCamera {
        /// The name given.
        name: String,
    },
    /// Too few correspondences for a rigid transform or an alignment.
    #[error("too few point pairs: {found} (need at least {needed})")]
    TooFewPoints {
        /// Pairs available.
        found: usize,
        /// Pairs required.
        needed: usize,
    },
    /// The feature detector refused its configuration.
    #[error("feature detector: {source}")]
    Detector {
        /// What the detector said.
        #[from]
        source: iw_features::FeatureError,
    },
    /// Two trajectories share no timestamps within the association limit.
    #[error(
        "no estimate pose is within {max_dt_s} s of a ground-truth pose ({estimate} vs {reference} poses)"
    )]
    NoCommonTimestamps {
        /// Poses in the estimate.
        estimate: usize,
        /// Poses in the reference.
        reference: usize,
        /// Largest accepted time difference, s.
        max_dt_s: f64,
    },
}

impl VoError {
    /// An I/O error on `path`.
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        VoError::Io {
            path: path.display().to_string(),
            source,
        }
    }

    /// A parse error at `path:line`.
    pub(crate) fn parse(path: &Path, line: usize, reason: impl Into<String>) -> Self {
        VoError::Parse {
            path: path.display().to_string(),
            line,
            reason: reason.into(),
        }
    }
}
