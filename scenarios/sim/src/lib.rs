//! The 2D world simulator: maps, wheelchair bodies, sensors, RGB-D rendering, mixed reality.
#![warn(missing_docs)]
