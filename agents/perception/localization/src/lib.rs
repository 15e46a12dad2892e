//! Map-based localization for the perception agent (thesis 3.8 and 6.4): the chair's pose stays
//! bounded by matching its laser and sonars to the map and by sighting landmarks, and a chair
//! that does not know where it is finds out while it drives.
//!
//! # Organization
//! - [`LocalizationMap`]: solid segments and [`Landmark`]s, indexed for exact nearest-segment
//!   queries and a coarse distance grid.
//! - [`LaserGeometry`], [`SonarGeometry`]: readings to base-frame points, garbage told apart.
//! - [`match_scan`]: Gauss-Newton scan-to-map matching with a Cauchy kernel and an honest,
//!   degeneracy-aware covariance ([`MatcherConfig`]).
//! - [`marker_cell_dark`], [`detect_markers`]: the landmarks' printed pattern, and finding it
//!   in a camera image.
//! - [`GlobalLocalizer`]: multi-hypothesis tracking seeded by an exhaustive search of the free
//!   space, with a bounded amount of work per control period.
//! - [`Localizer`]: the EKF (iw-vo's [`iw_vo::OdometryFusion`]) predicted by wheel odometry,
//!   updated by visual odometry, matched scans and landmarks; searches while lost; drops a
//!   sensor that goes silent or returns garbage.
//!
//! # Guarantees
//! - No panic on any reading: NaN, negative and out-of-range values are counted as garbage.
//! - Deterministic for a given seed and input sequence.
//! - A scan is fused only inside a chi-square gate: the pose does not jump on a bad scan.
//!
//! # Known limits
//! - Doors are left out of the map (they open and close): a closed door reads as an unmapped
//!   object, which the kernel discounts.
//! - Sonar echoes are taken along the transducer's axis; the cone's width goes into their
//!   large standard deviation.
#![warn(missing_docs)]

mod global;
mod localizer;
mod map;
mod marker;
mod matcher;
mod scan;

pub use global::{GlobalConfig, GlobalLocalizer};
pub use localizer::{Confidence, Localizer, LocalizerConfig, ScanOutcome, Status};
pub use map::{Landmark, LocalizationMap, Nearest};
pub use marker::{MARKER_CELLS, MarkerSighting, detect_markers, marker_cell_dark, markers_in};
pub use matcher::{MatcherConfig, ScanMatch, UNOBSERVED_VAR, inlier_fraction, match_scan};
pub use scan::{LaserGeometry, ReadingCount, ScanPoint, SonarGeometry};

/// A map the localizer cannot use.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LocalizationError {
    /// The geometry is empty, not finite or too large.
    #[error("localization map: {reason}")]
    BadMap {
        /// Why.
        reason: String,
    },
}
