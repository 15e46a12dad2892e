//! Mixed reality (thesis 3.5): a real body's readings combined with what a virtual body, placed
//! at the real chair's pose in the simulator, senses (virtual chairs, doors, obstacles).

use nalgebra::Isometry2;

use crate::{Body, BodyError, Odometry, SensorFrame, WheelSpeeds};

/// Something that senses a virtual world from a given pose: the simulator places the chair's
/// virtual body at `t_world_body` and returns its virtual sonar and laser readings.
pub trait VirtualSensors {
    /// Virtual readings of a body at `t_world_body` at `time_ns` (ticks are ignored by the merge).
    /// The frame's times are in the clock of `time_ns`: its `ranges_time_ns` is `time_ns` when
    /// the readings are sensed at once, earlier when they were sensed where the body was
    /// placed before (a world in another process answers with its last frame).
    fn sense_at(
        &mut self,
        t_world_body: Isometry2<f64>,
        time_ns: u64,
    ) -> Result<SensorFrame, BodyError>;
}

/// Per sonar and per laser beam, the nearer of the two readings wins (an echo beats no echo).
/// Encoders and time come from `real`. Laser beams are merged only when both have the same count;
/// otherwise the one that has beams is kept (the real one if both do). The ranges are taken to
/// be as old as the older of the two (both frames in one clock, see [`VirtualSensors`]): a
/// virtual laser from where the chair was a period ago is matched where the chair was then.
pub fn merge_nearest(real: &SensorFrame, virtual_frame: &SensorFrame) -> SensorFrame {
    let mut out = real.clone();
    out.ranges_time_ns = real.ranges_time_ns.min(virtual_frame.ranges_time_ns);
    for (o, v) in out.sonar_m.iter_mut().zip(virtual_frame.sonar_m.iter()) {
        *o = match (*o, *v) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
    }
    if out.laser_m.is_empty() {
        out.laser_m = virtual_frame.laser_m.clone();
    } else if out.laser_m.len() == virtual_frame.laser_m.len() {
        for (o, v) in out.laser_m.iter_mut().zip(&virtual_frame.laser_m) {
            *o = o.min(*v);
        }
    }
    out
}

/// A real body whose readings are completed by a virtual one. Commands go to the real body only;
/// the pose sent to the simulator is dead-reckoned from the real encoders.
pub struct MixedBody<R, V> {
    real: R,
    virtual_sensors: V,
    odometry: Odometry,
}

impl<R: Body, V: VirtualSensors> MixedBody<R, V> {
    /// Combines `real` with `virtual_sensors`, dead-reckoning with `odometry` (which holds the
    /// chair's starting pose in the virtual world).
    pub fn new(real: R, virtual_sensors: V, odometry: Odometry) -> Self {
        Self {
            real,
            virtual_sensors,
            odometry,
        }
    }

    /// The pose last sent to the simulator.
    pub fn t_world_body(&self) -> Isometry2<f64> {
        self.odometry.t_world_body()
    }

    /// The parts, e.g. to shut the real link down.
    pub fn into_parts(self) -> (R, V) {
        (self.real, self.virtual_sensors)
    }
}

impl<R: Body, V: VirtualSensors> Body for MixedBody<R, V> {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        let real = self.real.read()?;
        let t_world_body = self.odometry.update(&real);
        let virtual_frame = self.virtual_sensors.sense_at(t_world_body, real.time_ns)?;
        Ok(merge_nearest(&real, &virtual_frame))
    }

    fn command(&mut self, speeds: WheelSpeeds) -> Result<(), BodyError> {
        self.real.command(speeds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_wins_per_sonar() {
        let mut real = SensorFrame::empty(5);
        let mut virt = SensorFrame::empty(9);
        real.sonar_m[0] = Some(1.0);
        virt.sonar_m[0] = Some(0.5);
        real.sonar_m[1] = Some(0.3);
        virt.sonar_m[1] = Some(2.0);
        virt.sonar_m[2] = Some(0.8);
        real.sonar_m[3] = Some(0.9);
        virt.laser_m = vec![1.0, 2.0];
        let m = merge_nearest(&real, &virt);
        assert_eq!(
            &m.sonar_m[..5],
            &[Some(0.5), Some(0.3), Some(0.8), Some(0.9), None]
        );
        assert_eq!(m.time_ns, 5);
        assert_eq!(m.laser_m, vec![1.0, 2.0]);
    }

    #[test]
    fn merged_ranges_are_as_old_as_the_older_frame() {
        let real = SensorFrame::empty(50);
        let mut virt = SensorFrame::empty(50);
        virt.ranges_time_ns = 30;
        virt.laser_m = vec![1.0];
        let m = merge_nearest(&real, &virt);
        assert_eq!((m.time_ns, m.ranges_time_ns), (50, 30));
        assert_eq!(merge_nearest(&virt, &real).ranges_time_ns, 30);
    }
}
