//! The map and a chair's range sensors as [`iw_localization`] takes them: what the perception
//! agent's localizer is given when a chair runs on this map.

use iw_localization::{
    Landmark, LaserGeometry, LocalizationError, LocalizationMap, LocalizerConfig, SonarGeometry,
};
use iw_vo::{DiffDriveParams, Pose2};
use nalgebra::Isometry2;

use crate::{ChairSpec, Map};

/// Nearest-segment queries answer within this distance, m: the matcher's basin of attraction
/// and the global search's likelihood cap.
const REACH_M: f64 = 1.0;

fn pose2(t: &Isometry2<f64>) -> Pose2 {
    Pose2::new(t.translation.x, t.translation.y, t.rotation.angle())
}

/// The map's walls, furniture and the doors it draws closed, and its landmarks. A door that is
/// opened later reads as unmapped space and one closed later as an unmapped obstacle: the
/// matcher's kernel discounts both, and without the closed doors a corridor of doorways looks
/// the same every few metres.
pub fn localization_map(map: &Map) -> Result<LocalizationMap, LocalizationError> {
    let landmarks = map
        .landmarks
        .iter()
        .map(|m| Landmark {
            id: m.id,
            pose: Pose2::new(m.position.x, m.position.y, m.facing_rad),
        })
        .collect();
    let mut segments = map.solid_segments();
    segments.extend(map.doors.iter().filter(|d| !d.open).map(|d| (d.a, d.b)));
    LocalizationMap::new(segments, landmarks, REACH_M)
}

/// The drive parameters of `spec` with the default motion model.
pub fn drive_params(spec: &ChairSpec) -> DiffDriveParams {
    DiffDriveParams {
        wheel_radius_m: spec.geometry.wheel_radius_m,
        track_m: spec.geometry.track_m,
        ticks_per_rev: spec.geometry.ticks_per_rev,
        ..DiffDriveParams::default()
    }
}

/// The localizer's motion model (Thrun's alphas): only the random part of the encoders' error: the systematic part (tyre
/// compression, mean slip) is in the filter's state ([`iw_vo::WheelBias::WHEELCHAIR`]). What is
/// left is the per-step slip, about 0.6 % of each wheel's travel (translation 2e-5 m²/m²,
/// heading 1.2e-4 rad²/m² per half turn), and the slip while the wheels accelerate into and out
/// of turns (rotation 0.002 rad²/rad²). With the plain model's larger alphas
/// ([`DiffDriveParams::default`]) the tracking NEES sat far under its interval (the covariance
/// was several times the error); with these it is consistent on the 30-minute drives
/// (docs/results/localization.md).
pub const LOCALIZER_ALPHA: [f64; 4] = [0.002, 0.00012, 0.00002, 0.0002];

/// The localizer's defaults for a chair built like `spec`: its laser (if fitted) and sonar ring,
/// and [`LOCALIZER_ALPHA`]. The matcher assumes the laser's own range noise per beam (the
/// simulator's walls are the map's, so the map adds no error of its own; where the residuals
/// spread wider the matcher scales its covariance up) and 15 cm per sonar echo (the 45 degree
/// cone).
pub fn localizer_config(spec: &ChairSpec) -> LocalizerConfig {
    let laser = spec.laser.map(|l| LaserGeometry {
        t_base_laser: pose2(&l.t_body_laser),
        fov_rad: l.fov_deg.to_radians(),
        max_range_m: l.max_range_m,
        sigma_m: l.noise_std_m,
    });
    let sonar = SonarGeometry {
        t_base_sonar: spec.sonars.iter().map(|s| pose2(&s.t_body_sonar)).collect(),
        max_range_m: spec.sonar.max_range_m,
        sigma_m: 0.15,
    };
    LocalizerConfig::new(laser, Some(sonar), LOCALIZER_ALPHA)
}
