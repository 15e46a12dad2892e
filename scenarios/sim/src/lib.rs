//! The 2D world simulator: maps, wheelchair bodies, sensors, RGB-D rendering, mixed reality
//! (thesis 3.4, 3.5).
//!
//! # Organization
//! - [`Map`]: the world description, parsed from the text format of `docs/map-format.md`
//!   ([`Map::load`], [`Map::parse`]) or imported from a PNG occupancy image;
//!   [`Map::free_space_at`] tells a point a chair may start at ([`NotFree`]).
//! - [`World`]: static geometry in a uniform-grid broad phase, doors, chairs. Add chairs with
//!   [`World::add_chair`], command them with [`World::command`], advance with [`step`], read
//!   [`World::sensors`] (16 sonars, 270 deg laser, encoders) and, for chairs that ask,
//!   [`World::rgbd`] frames.
//! - [`ChairSpec`]: footprint, drive limits, encoder errors, and the sensor layout of thesis
//!   figure 3.4 ([`sonar_layout`]).
//! - [`TextureSet`], [`RgbdFrame`]: the RGB-D camera's photographs and output.
//! - [`vo`] (feature `vo`): the RGB-D camera as an `iw_vo::CameraSource` ([`vo::SimCamera`])
//!   and the odometry trial: wheel odometry, visual odometry and their EKF against ground truth.
//! - [`localization`] (feature `localization`): the map's solid geometry and landmarks, and a
//!   chair's laser and sonars, as `iw_localization` takes them.
//! - [`VirtualBody`] (an [`iw_body::Body`] driving a simulated chair) and [`GhostSensors`] (an
//!   [`iw_body::VirtualSensors`] placing a real chair's virtual body, for mixed reality).
//!
//! # Guarantees
//! - Deterministic: the same map, seed and call sequence give bit-identical runs.
//! - Never tunnels: motion is split in substeps of at most 2 cm of footprint travel, and a
//!   footprint cannot pass a segment between substeps; contacts stop the chair and are counted
//!   once per contact.
//! - Map errors name `file:line` and the reason; no input panics the parser. A map file is read
//!   only if it is a regular file of at most [`MAX_MAP_BYTES`] ([`file::read_text`]).
//!
//! # Known limits
//! - Sonars and the laser see every obstacle whatever its height; sonar specular reflection and
//!   crosstalk are not modelled.
//! - The 16-sonar ring covers the sides from 27 cm and every side from 80 cm out, but the corner
//!   arcs between a tip pair and the lateral row keep small blind spots (as on the prototype).
//! - The RGB-D camera is a 2.5D column ray caster: vertical walls and extruded furniture, a flat
//!   floor and ceiling, no shadows.
//! - Chairs are moved one after another within a step (index order), so two chairs meeting
//!   head-on are resolved in favour of the lower index.
#![warn(missing_docs)]

/// Files read only if regular and within a cap (the platform's helper, re-exported for the
/// map, scenario and configuration readers above).
pub use iw_file as file;
mod body;
mod chair;
mod geom;
#[cfg(feature = "localization")]
pub mod localization;
mod map;
mod reach;
mod render;
#[cfg(feature = "vo")]
pub mod vo;
mod world;

pub use body::{GhostSensors, SharedWorld, VirtualBody, shared};
pub use chair::{
    CameraModel, ChairSpec, EncoderModel, LaserModel, SonarModel, SonarMount, sonar_layout,
};
pub use geom::Owner;
pub use map::{
    Area, Door, Furniture, MAX_MAP_BYTES, Map, Marker, NarrowPassage, Place, Route, Start,
};
pub use reach::NotFree;
pub use render::{RgbdFrame, TUM_DEPTH_PER_M, TextureSet, optical_pose};
pub use world::{ChairId, ChairKind, Hit, World, step};

/// What went wrong in the simulator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A map file line could not be parsed (`line` 0: the map as a whole).
    #[error("{file}:{line}: {reason}")]
    Parse {
        /// File name as given.
        file: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong and what was expected.
        reason: String,
    },
    /// A file could not be read.
    #[error("cannot read `{path}`: {source}")]
    Io {
        /// The path.
        path: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// An image (occupancy map, texture) could not be used.
    #[error("image `{path}`: {reason}")]
    Image {
        /// The path.
        path: String,
        /// Why.
        reason: String,
    },
    /// An image file (occupancy map, texture, rendered frame) cannot be read or written.
    #[error("image `{path}`: {source}")]
    ImageFile {
        /// The path.
        path: String,
        /// What the image codec or the OS said (boxed: it is large, and this error is returned
        /// often).
        #[source]
        source: Box<image::ImageError>,
    },
    /// A chair id that this world never handed out.
    #[error("no chair {id} (the world has {count})")]
    NoSuchChair {
        /// The id asked for.
        id: usize,
        /// Chairs in the world.
        count: usize,
    },
    /// A door id not in the map.
    #[error("no door `{id}` in the map")]
    NoSuchDoor {
        /// The id asked for.
        id: String,
    },
    /// A door cannot close on a chair.
    #[error("door `{id}` cannot close: chair {chair} stands in the doorway")]
    DoorBlocked {
        /// Door id.
        id: String,
        /// The chair in the way.
        chair: usize,
    },
}
