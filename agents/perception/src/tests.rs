//! Vision off the control period, measured by counting: periods sensed against frames asked
//! of the camera, never against the wall clock.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use iw_acl::AgentId;
use iw_body::{Body, BodyError, SensorFrame, WheelSpeeds};
use iw_features::DetectorKind;
use iw_vo::{CameraSource, DepthImage, Intrinsics, Pipeline, Pose2, RgbdFrame, VoConfig, VoError};
use nalgebra::Isometry3;

use crate::{PerceptionAgent, PerceptionConfig, VisualConfig};

const PERIOD_NS: u64 = 50_000_000;

/// A chair standing still; each read is one period later on a clock it shares with the camera.
struct Still {
    clock: Arc<AtomicU64>,
}

impl Body for Still {
    fn read(&mut self) -> Result<SensorFrame, BodyError> {
        let t = self.clock.fetch_add(PERIOD_NS, Ordering::SeqCst) + PERIOD_NS;
        Ok(SensorFrame::empty(t))
    }
    fn command(&mut self, _: WheelSpeeds) -> Result<(), BodyError> {
        Ok(())
    }
}

/// A camera facing a textured wall 2 m away, stamping each frame with the body's latest time.
/// With a gate it is a stuck driver: each frame waits for a permit (5 s at most, then an error).
struct Wall {
    intrinsics: Intrinsics,
    clock: Arc<AtomicU64>,
    calls: Arc<AtomicUsize>,
    gate: Option<Receiver<()>>,
    rgb: image::RgbImage,
    depth: DepthImage,
}

impl CameraSource for Wall {
    fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    fn next_frame(&mut self) -> Option<Result<RgbdFrame, VoError>> {
        self.calls.fetch_add(1, Ordering::SeqCst);
        if let Some(gate) = &self.gate
            && gate.recv_timeout(Duration::from_secs(5)).is_err()
        {
            return Some(Err(VoError::Image {
                path: "test camera".into(),
                reason: "no permit".into(),
            }));
        }
        Some(Ok(RgbdFrame {
            timestamp_s: self.clock.load(Ordering::SeqCst) as f64 * 1e-9,
            rgb: self.rgb.clone(),
            depth: self.depth.clone(),
            decode_ms: 0.0,
        }))
    }
}

/// A chair at (1, 2) with the wall camera; returns the agent, the camera's call count and the
/// body's clock.
fn agent(gate: Option<Receiver<()>>) -> (PerceptionAgent, Arc<AtomicUsize>, Arc<AtomicU64>) {
    let (w, h) = (320u32, 240u32);
    // 8-pixel blocks of pseudo-random grey: plenty of blobs for the detector
    let rgb = image::RgbImage::from_fn(w, h, |x, y| {
        let cell = u64::from(x / 8) * 7919 + u64::from(y / 8) * 104_729;
        let v = (cell.wrapping_mul(6_364_136_223_846_793_005) >> 56) as u8;
        image::Rgb([v, v, v])
    });
    let depth = DepthImage::from_pixel(w, h, image::Luma([10_000]));
    let intrinsics = Intrinsics {
        fx: 260.0,
        fy: 260.0,
        cx: 160.0,
        cy: 120.0,
        distortion: None,
        depth_units_per_m: 5000.0,
        min_depth_m: 0.3,
        max_depth_m: 6.0,
    };
    let clock = Arc::new(AtomicU64::new(0));
    let calls = Arc::new(AtomicUsize::new(0));
    let camera = Wall {
        intrinsics,
        clock: clock.clone(),
        calls: calls.clone(),
        gate,
        rgb,
        depth,
    };
    let mut vo = VoConfig::new(DetectorKind::Surf, Pipeline::Keyframe);
    vo.detector_config.upright = true;
    let visual = VisualConfig {
        source: Box::new(camera),
        vo,
        t_base_camera: Isometry3::identity(),
        motion_noise: iw_vo::VisualNoise {
            floor_m: 0.01,
            floor_rad: 0.01,
            per_metre: 0.0,
            rad_per_rad: 0.0,
            rad_per_metre: 0.0,
        },
    };
    let config = PerceptionConfig::prototype(AgentId::new("chair1"), Pose2::new(1.0, 2.0, 0.0));
    let body = Still {
        clock: clock.clone(),
    };
    let agent = PerceptionAgent::new(config, Box::new(body), Some(visual)).unwrap();
    (agent, calls, clock)
}

#[test]
fn a_stuck_camera_does_not_hold_up_the_control_period() {
    let (permits, gate) = channel();
    let (mut agent, calls, clock) = agent(Some(gate));
    for _ in 0..40 {
        agent.sense();
    }
    // 40 periods sensed while the one frame asked for is stuck in the driver (inside the tick
    // each period would have waited for a frame: 40 calls, 200 s)
    assert_eq!(clock.load(Ordering::SeqCst), 40 * PERIOD_NS);
    assert!(calls.load(Ordering::SeqCst) <= 1, "{calls:?}");
    assert_eq!(agent.visual_results(), (0, 0));
    // released, frames flow and results arrive in later periods
    let deadline = Instant::now() + Duration::from_secs(120);
    let mut periods = 40u64;
    while agent.visual_results().0 < 2 {
        assert!(
            Instant::now() < deadline,
            "no visual results: {:?}",
            agent.visual_results()
        );
        let _ = permits.send(());
        agent.sense();
        periods += 1;
        std::thread::sleep(Duration::from_millis(2));
    }
    // one frame in flight at a time: never more frames asked than periods sensed, plus one
    assert!(calls.load(Ordering::SeqCst) as u64 <= periods + 1);
    assert_eq!(clock.load(Ordering::SeqCst), periods * PERIOD_NS);
}

#[test]
fn visual_motions_are_fused_when_they_arrive() {
    let (mut agent, _calls, _clock) = agent(None);
    let before = agent.pose().covariance;
    let deadline = Instant::now() + Duration::from_secs(120);
    while agent.visual_results().0 < 3 {
        assert!(
            Instant::now() < deadline,
            "no visual results: {:?}",
            agent.visual_results()
        );
        agent.sense();
        std::thread::sleep(Duration::from_millis(2));
    }
    assert_eq!(
        agent.visual_results().1,
        0,
        "every frame placed and tracked"
    );
    // a still chair and a still wall: the estimate stays at the start, no less certain
    let pose = agent.pose();
    assert!(
        (pose.x_m - 1.0).abs() < 1e-3 && (pose.y_m - 2.0).abs() < 1e-3,
        "{pose:?}"
    );
    assert!(pose.covariance[(0, 0)] <= before[(0, 0)] + 1e-9);
}

/// Where a scan was taken, from the times the body gives: readings that trail the encoders
/// are carried by the wheels' motion since, a scan given again is no new scan.
#[test]
fn range_readings_are_placed_at_their_own_time_and_not_taken_twice() {
    let config = PerceptionConfig::prototype(AgentId::new("chair1"), Pose2::default());
    let body = Still {
        clock: Arc::new(AtomicU64::new(0)),
    };
    let mut agent = PerceptionAgent::new(config, Box::new(body), None).unwrap();
    // straight ahead, 1000 ticks a period on both wheels, from 2 s on the body's clock
    let at = |periods: u64| 2_000_000_000 + periods * PERIOD_NS / 2;
    let mut x_at = Vec::new();
    for k in 0..=4i64 {
        agent.wheels.update(1000 * k, 1000 * k);
        agent.history.record(at(2 * k as u64), agent.wheels.pose());
        x_at.push(agent.wheels.pose().x);
    }
    let mut frame = SensorFrame::empty(at(8));
    // taken two periods before the encoders were read
    frame.ranges_time_ns = at(4);
    let since = agent.ranges_since(&frame).unwrap();
    assert!((since.x - (x_at[4] - x_at[2])).abs() < 1e-12, "{since:?}");
    assert!(since.y.abs() < 1e-12 && since.theta.abs() < 1e-12);
    // the same readings again (a ghost whose world is late) are not new
    assert!(agent.ranges_since(&frame).is_none());
    // taken between two of this agent's reads
    frame.ranges_time_ns = at(5);
    let since = agent.ranges_since(&frame).unwrap();
    assert!((since.x - (x_at[4] - (x_at[2] + x_at[3]) / 2.0)).abs() < 1e-12);
    // a time ahead of the encoders' is taken as now
    frame.ranges_time_ns = at(18);
    assert_eq!(agent.ranges_since(&frame), Some(Pose2::default()));
    // a body clock that started again: new readings, not old ones
    let restarted = SensorFrame::empty(PERIOD_NS);
    assert_eq!(agent.ranges_since(&restarted), Some(Pose2::default()));
}
