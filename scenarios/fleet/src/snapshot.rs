//! The fleet at one instant, as the demo, the dashboard and the scenario runner read it.

use crate::Exchange;

/// One chair as the snapshot shows it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ChairSnapshot {
    /// Its name.
    pub name: String,
    /// True pose in the world: x, y (m), heading (rad).
    pub pose: [f64; 3],
    /// Linear (m/s) and angular (rad/s) speed.
    pub twist: [f64; 2],
    /// Sonar ranges, m (`None`: no echo).
    pub sonar_m: Vec<Option<f64>>,
    /// Contacts with walls, furniture or chairs so far.
    pub collisions: u64,
    /// Distance driven, m.
    pub distance_m: f64,
    /// Its current goal, if any.
    pub goal: Option<[f64; 2]>,
    /// The waypoints it was sent.
    pub path: Vec<[f64; 2]>,
    /// The agents of its container.
    pub agents: Vec<String>,
}

/// The whole fleet at one instant.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Snapshot {
    /// Simulated time, s.
    pub time_s: f64,
    /// Every chair.
    pub chairs: Vec<ChairSnapshot>,
    /// Door id and whether it is open.
    pub doors: Vec<(String, bool)>,
    /// The service container's agents.
    pub services: Vec<String>,
    /// The last frames between containers.
    pub recent: Vec<Exchange>,
}
