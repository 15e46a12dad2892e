//! The map and a chair's range sensors as [`iw_localization`] takes them: what the perception
//! agent's localizer is given when a chair runs on this map.

use iw_localization::{
    Landmark, LaserGeometry, LocalizationError, LocalizationMap, LocalizerConfig, SonarGeometry,
};
use iw_vo::{AccelerationSlip, DiffDriveParams, Pose2};
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

/// The localizer's motion model (Thrun's alphas): the random part of the simulator's slip
/// alone. `World::drive` loses |N(0,1)| × [`crate::EncoderModel::slip_std`] (1 %) of each
/// wheel's travel per tick (one tick per 50 ms period). Its mean (0.80 %) is a scale error, which
/// the filter's wheel-scale state absorbs ([`iw_vo::WheelBias::WHEELCHAIR`]); what is left is
/// its variance, σ² = (1 − 2/π) × 1e-4 = 3.63e-5 per wheel. Through Thrun's model with the turn
/// split in two halves, track T = 0.56 m: a1 = σ² (a turn on the spot), a2 = σ² / T² (heading
/// from travel), a3 = σ² / 2 (travel from travel), a4 = σ² T² / 4 (travel from a turn). The slip
/// with the wheels' acceleration is the other term ([`localizer_config`]).
pub const LOCALIZER_ALPHA: [f64; 4] = [3.63e-5, 1.16e-4, 1.82e-5, 2.85e-6];

/// Time between the wheel odometry steps the localizer is given, s: one per control period.
pub const ODOMETRY_PERIOD_S: f64 = 0.05;

/// The localizer's defaults for a chair built like `spec`: its laser (if fitted) and sonar ring,
/// [`LOCALIZER_ALPHA`], and the slip with the wheels' acceleration as `spec`'s encoder model has
/// it ([`crate::EncoderModel::slip_per_mps2`], 2 % per m/s²), one odometry step per
/// [`ODOMETRY_PERIOD_S`]. The matcher assumes the laser's own range noise per beam (the
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
    LocalizerConfig {
        acceleration_slip: Some(AccelerationSlip {
            per_mps2: spec.encoder.slip_per_mps2,
            period_s: ODOMETRY_PERIOD_S,
            track_m: spec.geometry.track_m,
        }),
        ..LocalizerConfig::new(laser, Some(sonar), LOCALIZER_ALPHA)
    }
}
