//! Vision off the control period: a worker thread takes the camera's frames, runs visual
//! odometry on them and finds the landmarks' markers in them, so that a tick of the perception agent never waits for a camera or for
//! feature extraction. The tick asks for a frame only when the worker is idle and fuses each
//! result when it arrives, carried from the frames' capture times to the present by the wheel
//! odometry recorded at every tick ([`WheelHistory`]).

use std::collections::VecDeque;
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError, sync_channel};

use iw_localization::markers_in;
use iw_vo::{CameraSource, Pose2, VisualOdometry, VoConfig, VoError, wrap_angle};
use nalgebra::{Isometry3, Point2};

/// What the worker made of one requested frame.
#[derive(Debug)]
pub(crate) enum VisionResult {
    /// A frame, captured at `time_ns`.
    Frame {
        time_ns: u64,
        /// Visual odometry: the previous tracked frame's capture time (ns) and the camera's
        /// motion from it to this one (none for the first frame), or why it failed.
        motion: Result<Option<(u64, Isometry3<f64>)>, VoError>,
        /// Markers seen: id, and the marker's centre in the base frame at capture, m.
        markers: Vec<(u8, Point2<f64>)>,
    },
    /// The camera gave no frame: what it said.
    Failed(VoError),
    /// The source has no more frames (a replay's end): no more requests.
    Ended,
}

/// The worker thread and the two channels to it: requests (at most one in flight) and results.
pub(crate) struct VisionWorker {
    requests: SyncSender<()>,
    results: Receiver<VisionResult>,
    busy: bool,
    ended: bool,
}

impl VisionWorker {
    /// Starts the worker on `source` mounted at `t_base_camera`, with visual odometry `config`;
    /// `name` names the thread.
    pub(crate) fn start(
        name: &str,
        mut source: Box<dyn CameraSource + Send>,
        config: VoConfig,
        t_base_camera: Isometry3<f64>,
    ) -> std::io::Result<Self> {
        let (requests, requested) = sync_channel::<()>(1);
        let (answer, results) = sync_channel::<VisionResult>(1);
        let intrinsics = *source.intrinsics();
        let mut vo = VisualOdometry::new(config, intrinsics);
        std::thread::Builder::new()
            .name(format!("vision-{name}"))
            .spawn(move || {
                let mut last: Option<(u64, Isometry3<f64>)> = None;
                // ends when the agent (the requests' sender) is gone
                while requested.recv().is_ok() {
                    let result = match source.next_frame() {
                        None => VisionResult::Ended,
                        Some(Err(err)) => VisionResult::Failed(err),
                        Some(Ok(frame)) => {
                            let time_ns = (frame.timestamp_s.max(0.0) * 1e9).round() as u64;
                            let motion = vo.process(&frame).map(|(stamped, _)| {
                                let motion = last
                                    .map(|(t, pose)| (t, pose.inverse() * stamped.t_world_camera));
                                last = Some((time_ns, stamped.t_world_camera));
                                motion
                            });
                            VisionResult::Frame {
                                time_ns,
                                motion,
                                markers: markers_in(&frame, &intrinsics, &t_base_camera),
                            }
                        }
                    };
                    let ended = matches!(result, VisionResult::Ended);
                    if answer.send(result).is_err() || ended {
                        break;
                    }
                }
            })?;
        Ok(VisionWorker {
            requests,
            results,
            busy: false,
            ended: false,
        })
    }

    /// Results that have arrived since the last call, without waiting.
    pub(crate) fn arrived(&mut self) -> Vec<VisionResult> {
        let mut out = Vec::new();
        loop {
            match self.results.try_recv() {
                Ok(result) => {
                    self.busy = false;
                    self.ended |= matches!(result, VisionResult::Ended);
                    out.push(result);
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    if !self.ended {
                        tracing::warn!("the vision worker stopped; no more visual updates");
                    }
                    self.ended = true;
                    self.busy = false;
                    break;
                }
            }
        }
        out
    }

    /// Asks for the next frame if the worker is idle; never waits.
    pub(crate) fn request(&mut self) {
        if self.busy || self.ended {
            return;
        }
        match self.requests.try_send(()) {
            Ok(()) => self.busy = true,
            Err(TrySendError::Full(())) => {}
            Err(TrySendError::Disconnected(())) => self.ended = true,
        }
    }
}

/// The wheel odometry pose at each recent tick, by body time, to carry a visual motion measured
/// between two past frames to the filter's clone and current poses.
#[derive(Debug, Default)]
pub(crate) struct WheelHistory {
    poses: VecDeque<(u64, Pose2)>,
}

/// Ticks of wheel poses kept: 30 s at 20 Hz, longer than any frame should take.
const HISTORY_LEN: usize = 600;

impl WheelHistory {
    /// Records the wheel pose at body time `time_ns`.
    pub(crate) fn record(&mut self, time_ns: u64, pose: Pose2) {
        if self.poses.len() == HISTORY_LEN {
            self.poses.pop_front();
        }
        self.poses.push_back((time_ns, pose));
    }

    /// The recorded pose nearest in time to `time_ns`, if one lies within `tolerance_ns`.
    pub(crate) fn at(&self, time_ns: u64, tolerance_ns: u64) -> Option<Pose2> {
        let i = self.poses.partition_point(|(t, _)| *t < time_ns);
        [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter_map(|j| self.poses.get(j))
            .filter(|(t, _)| t.abs_diff(time_ns) <= tolerance_ns)
            .min_by_key(|(t, _)| t.abs_diff(time_ns))
            .map(|(_, p)| *p)
    }

    /// The wheel pose at body time `time_ns`, interpolated between the recorded ticks around
    /// it (a time between two of this agent's reads, e.g. a read by the control agent); `None`
    /// outside the recorded times.
    pub(crate) fn interpolated(&self, time_ns: u64) -> Option<Pose2> {
        let i = self.poses.partition_point(|(t, _)| *t < time_ns);
        let &(t1, p1) = self.poses.get(i)?;
        if t1 == time_ns {
            return Some(p1);
        }
        let &(t0, p0) = self.poses.get(i.checked_sub(1)?)?;
        let f = (time_ns - t0) as f64 / (t1 - t0) as f64;
        Some(Pose2::new(
            p0.x + f * (p1.x - p0.x),
            p0.y + f * (p1.y - p0.y),
            p0.theta + f * wrap_angle(p1.theta - p0.theta),
        ))
    }
}

/// The base motion from the filter's clone to its current pose, given the base motion
/// `measured` between two frames and the wheel poses at the clone (`at_clone`), at the two
/// frames (`at_previous`, `at_current`) and now: wheel odometry bridges the gaps on either side.
pub(crate) fn bridged(
    at_clone: &Pose2,
    at_previous: &Pose2,
    measured: &Pose2,
    at_current: &Pose2,
    now: &Pose2,
) -> Pose2 {
    at_clone
        .between(at_previous)
        .compose(measured)
        .compose(&at_current.between(now))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_finds_the_nearest_pose_within_tolerance() {
        let mut h = WheelHistory::default();
        for k in 0..700u64 {
            h.record(k * 50, Pose2::new(k as f64, 0.0, 0.0));
        }
        // the first 100 fell out
        assert_eq!(h.at(0, 10), None);
        assert_eq!(h.at(5000, 10).map(|p| p.x), Some(100.0));
        assert_eq!(h.at(5030, 25).map(|p| p.x), Some(101.0));
        assert_eq!(h.at(5025, 30).map(|p| p.x), Some(100.0));
        assert_eq!(h.at(5025, 10), None);
        assert_eq!(h.at(1_000_000, 10), None);
    }

    #[test]
    fn history_interpolates_between_ticks_across_the_heading_wrap() {
        let mut h = WheelHistory::default();
        h.record(100, Pose2::new(0.0, 0.0, 3.1));
        h.record(200, Pose2::new(1.0, 2.0, -3.1));
        let p = h.interpolated(150).unwrap();
        assert!((p.x - 0.5).abs() < 1e-12 && (p.y - 1.0).abs() < 1e-12);
        // halfway from 3.1 to -3.1 the short way round is pi, not 0
        assert!((p.theta.abs() - std::f64::consts::PI).abs() < 1e-9);
        assert_eq!(h.interpolated(200), Some(Pose2::new(1.0, 2.0, -3.1)));
        assert_eq!(h.interpolated(99), None);
        assert_eq!(h.interpolated(201), None);
    }

    #[test]
    fn bridging_adds_the_wheel_motion_around_the_frames() {
        // clone at x=0, frames at x=1 and x=3 (measured 2 m), now at x=4: 4 m in all
        let p = |x: f64| Pose2::new(x, 0.0, 0.0);
        let m = bridged(&p(0.0), &p(1.0), &p(2.0), &p(3.0), &p(4.0));
        assert!((m.x - 4.0).abs() < 1e-12 && m.y.abs() < 1e-12 && m.theta.abs() < 1e-12);
        // no gaps: the measurement itself
        let turn = Pose2::new(0.5, 0.1, 0.2);
        let q = Pose2::new(2.0, 1.0, 0.7);
        let m = bridged(&q, &q, &turn, &q.compose(&turn), &q.compose(&turn));
        assert!((m.x - turn.x).abs() < 1e-12 && (m.y - turn.y).abs() < 1e-12);
        assert!((m.theta - turn.theta).abs() < 1e-12);
    }
}
