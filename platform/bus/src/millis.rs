//! Serde for a [`Duration`] written as whole milliseconds: files and JSON keep their `*_ms`
//! keys and integers (`heartbeat_ms = 50`) while the code holds a `Duration`. Use it as
//! `#[serde(rename = "lease_ms", with = "iw_bus::millis")]`. A value that is not a
//! non-negative integer is refused by the format's parser, which names the key (and, for
//! TOML, the line).
//!
//! It lives here, at the bottom of the platform, so that every crate with a configuration
//! (the transports, the nodes, the scenarios, the command line) writes durations one way.

use std::time::Duration;

use serde::{Deserialize, Deserializer, Serializer};

/// Writes `d` as whole milliseconds (saturating at `u64::MAX`).
pub fn serialize<S: Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_u64(u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
}

/// Reads whole milliseconds.
pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Duration, D::Error> {
    u64::deserialize(d).map(Duration::from_millis)
}
