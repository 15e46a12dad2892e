//! Wheel geometry and dead reckoning from encoder ticks (thesis 3.3.2).

use nalgebra::{Isometry2, Vector2};

use crate::SensorFrame;

/// Distance between the prototype's drive wheels' contact points, m: the one value every model
/// of the chair's drive (odometry, the VO wheel model, shared control) starts from.
pub const TRACK_M: f64 = 0.56;

/// The drive geometry the encoders are read against (nominal values: the real tyre differs).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WheelGeometry {
    /// Distance between the drive wheels' contact points, m.
    pub track_m: f64,
    /// Nominal drive wheel radius, m.
    pub wheel_radius_m: f64,
    /// Encoder ticks per wheel revolution (after the gearbox).
    pub ticks_per_rev: f64,
}

impl Default for WheelGeometry {
    /// A typical powered wheelchair: 14" drive wheels [`TRACK_M`] apart, a 512-line quadrature encoder
    /// on the motor shaft behind an 18:1 gearbox.
    fn default() -> Self {
        Self {
            track_m: TRACK_M,
            wheel_radius_m: 0.175,
            ticks_per_rev: 4.0 * 512.0 * 18.0,
        }
    }
}

impl WheelGeometry {
    /// Metres at the tyre per encoder tick, nominal.
    pub fn m_per_tick(&self) -> f64 {
        std::f64::consts::TAU * self.wheel_radius_m / self.ticks_per_rev
    }
}

/// How far each drive wheel rolled between two readings, m (nominal geometry).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WheelTravel {
    /// Left wheel, m (negative backwards).
    pub left_m: f64,
    /// Right wheel, m (negative backwards).
    pub right_m: f64,
}

/// Dead reckoning of `t_world_body` from cumulative encoder ticks: the one implementation the
/// mixed body and the perception agent's probabilistic wheel odometry (`iw_vo::WheelOdometry`)
/// both integrate with.
#[derive(Debug, Clone)]
pub struct Odometry {
    geometry: WheelGeometry,
    last_ticks: Option<(i64, i64)>,
    t_world_body: Isometry2<f64>,
}

impl Odometry {
    /// Starts at `t_world_body`; the first frame only sets the tick reference.
    pub fn new(geometry: WheelGeometry, t_world_body: Isometry2<f64>) -> Self {
        Self {
            geometry,
            last_ticks: None,
            t_world_body,
        }
    }

    /// The current pose estimate.
    pub fn t_world_body(&self) -> Isometry2<f64> {
        self.t_world_body
    }

    /// The geometry the ticks are read against.
    pub fn geometry(&self) -> &WheelGeometry {
        &self.geometry
    }

    /// Integrates the tick increments since the previous frame (midpoint rule) and returns the
    /// new pose estimate.
    pub fn update(&mut self, frame: &SensorFrame) -> Isometry2<f64> {
        self.advance(frame.left_ticks, frame.right_ticks);
        self.t_world_body
    }

    /// Integrates cumulative tick counts (midpoint rule: half the turn before the straight part,
    /// half after) and returns each wheel's travel since the previous call; `None` on the first
    /// call, which only latches the counters. Counters may wrap.
    pub fn advance(&mut self, left_ticks: i64, right_ticks: i64) -> Option<WheelTravel> {
        let (l0, r0) = self.last_ticks.replace((left_ticks, right_ticks))?;
        let k = self.geometry.m_per_tick();
        let travel = WheelTravel {
            left_m: left_ticks.wrapping_sub(l0) as f64 * k,
            right_m: right_ticks.wrapping_sub(r0) as f64 * k,
        };
        let ds = (travel.left_m + travel.right_m) / 2.0;
        let dtheta = (travel.right_m - travel.left_m) / self.geometry.track_m;
        let t_prev_curr = Isometry2::new(
            Vector2::new(ds * (dtheta / 2.0).cos(), ds * (dtheta / 2.0).sin()),
            dtheta,
        );
        self.t_world_body *= t_prev_curr;
        Some(travel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_and_spin() {
        let g = WheelGeometry::default();
        let mut odo = Odometry::new(g, Isometry2::identity());
        let mut f = SensorFrame::empty(0);
        odo.update(&f);
        let one_m = (1.0 / g.m_per_tick()).round() as i64;
        f.left_ticks = one_m;
        f.right_ticks = one_m;
        let p = odo.update(&f);
        assert!((p.translation.x - 1.0).abs() < 1e-3 && p.translation.y.abs() < 1e-9);
        // spin in place by pi/2: each wheel travels track * pi/4
        let quarter = (g.track_m * std::f64::consts::FRAC_PI_4 / g.m_per_tick()).round() as i64;
        f.left_ticks -= quarter;
        f.right_ticks += quarter;
        let p = odo.update(&f);
        assert!((p.rotation.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-3);
    }
}
