//! The perception agent (thesis 3.3.2): reads one wheelchair body's sensors and publishes where
//! the chair is, with the uncertainty of the estimate, to the agents that subscribed.
//!
//! Organization:
//! - [`PerceptionConfig`]: the chair's name, drive geometry and motion noise, start pose,
//!   period; [`VisualConfig`]: an optional RGB-D camera (any [`CameraSource`]) and where it
//!   sits on the base.
//! - [`PerceptionAgent::new`] takes them and a `Box<dyn Body + Send>` to read. The composer
//!   gives it the same body the control agent drives (e.g. a shared handle to the simulator's
//!   virtual body): this agent only reads.
//! - [`PerceptionError`]: a configuration that cannot work.
//!
//! Estimation: each tick the encoder ticks give a wheel odometry step (probabilistic motion
//! model) that predicts an EKF ([`OdometryFusion`]); with a camera, a worker thread takes
//! frames through [`iw_vo::VisualOdometry`] and the tick fuses each planar motion between two
//! frames when it arrives, bridged to the filter's poses by the wheel odometry recorded at the
//! frames' capture times. A tick never waits for the camera or for visual odometry: it asks for
//! the next frame only when the worker is idle, so vision runs as fast as it can and the
//! control period stays the body's. Without a map the covariance only grows, which is what the cognitive agent watches
//! to route the chair past a landmark (thesis 3.8).
//!
//! With a map ([`PerceptionAgent::with_localizer`]) the estimate is an
//! [`iw_localization::Localizer`]'s instead: the same odometry and visual updates, plus the
//! laser and sonars matched to the map every tick, so the error stays bounded. A localizer
//! started without a pose searches while the chair is driven by hand; until it has found the
//! pose the published covariance is at least [`LOST_VARIANCE_M2`] in x and y, which the
//! cognitive agent reads as "not localized" and refuses goals.
//!
//! # Messages
//! - SUBSCRIBE (`fipa-subscribe`, ontology `IntellWheels-Wheelchair`), content
//!   `((at-pose ?agent ?pose))`: AGREE, then every [`PerceptionConfig::publish_every`] ticks an
//!   INFORM `((at-pose (agent-identifier :name CHAIR) (pose :x :y :theta :covariance (sequence
//!   c00 .. c22))))` in the subscription's conversation. A subscription whose content names
//!   `sensor-reading` also gets `((sensor-reading CHAIR (sonar-reading :ranges (sequence ...))))`
//!   (no echo reads as the sonar's maximum range, [`PerceptionConfig::sonar_max_m`]).
//! - With a map, whenever the localizer drops the laser or the sonar ring (silent, or garbage:
//!   see [`iw_localization::LocalizerConfig::drop_after`]) or takes it back, every subscriber
//!   gets an INFORM `((sensor-health (agent-identifier :name CHAIR) (sensor-state :sensor laser
//!   :use dropped :reason "silent: no readings")))` (`:sensor sonars` for the ring; `:use
//!   in-use` when it is back), and a new subscriber gets it at once while the sensor is dropped:
//!   a chair whose laser is dropped dead-reckons and should be routed past a landmark.
//! - CANCEL in the conversation of a subscription: ends it, INFORM `((done ...))` is not sent
//!   (FIPA allows silence); other performatives get NOT-UNDERSTOOD. Each subscription is its
//!   conversation's `iw_agent::Responder`: the notifications answer it, a CANCEL ends only it.
//!
//! Guarantees: a failed body read or camera frame skips that update and is logged, never
//! panics; the published covariance is the EKF's, symmetric.
#![warn(missing_docs)]

mod vision;

use std::time::Duration;

use iw_acl::{AclMessage, AgentId, Performative};
use iw_agent::{Agent, Context, Responder};
use iw_body::Body;
use iw_localization::{Localizer, Status};
use iw_ontology::wheelchair::{
    Fact, Pose, SensorReading, SensorState, SensorUse, Topic, WheelchairContent,
};
use iw_vo::{
    CameraSource, DiffDriveParams, OdometryFusion, OdometryStep, Pose2, VisualNoise, VoConfig,
    WheelBias, WheelOdometry, planar_motion,
};
use nalgebra::{Isometry3, Matrix3};
use vision::{VisionResult, VisionWorker, WheelHistory};

/// Position variance (m², in x and in y) published while the localizer searches for the pose:
/// the ontology's mark of a chair that does not know where it is.
pub use iw_ontology::wheelchair::NOT_LOCALIZED_VARIANCE_M2 as LOST_VARIANCE_M2;

/// A configuration that cannot work.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PerceptionError {
    /// A parameter that must be positive and finite is not.
    #[error("perception parameter `{name}` must be positive and finite, got {value}")]
    BadParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The vision worker thread could not be started.
    #[error("cannot start the vision worker: {source}")]
    Vision {
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
}

/// An RGB-D camera on the chair.
pub struct VisualConfig {
    /// Where frames come from (a live camera, the simulator's renderer). Its frames' timestamps
    /// must be on the body's clock ([`iw_body::SensorFrame::time_ns`]): a visual motion is
    /// fused only when both its frames' times match a tick's body reading within half a period.
    pub source: Box<dyn CameraSource + Send>,
    /// Visual odometry settings.
    pub vo: VoConfig,
    /// Maps camera coordinates into the base frame.
    pub t_base_camera: Isometry3<f64>,
    /// The noise of one frame-to-frame planar motion (x, y, theta), growing with the motion.
    pub motion_noise: VisualNoise,
}

/// Who the perception agent is and how it estimates.
#[derive(Debug, Clone)]
pub struct PerceptionConfig {
    /// The chair (its agents' common name) the poses are about, e.g. `chair1`.
    pub chair: AgentId,
    /// Drive geometry and motion-model noise.
    pub drive: DiffDriveParams,
    /// The wheels' systematic error, estimated by the odometry filter (without a map) while
    /// visual odometry observes the motion.
    pub wheel_bias: WheelBias,
    /// Where the chair starts in the map frame.
    pub start: Pose2,
    /// Covariance of the start pose.
    pub start_covariance: Matrix3<f64>,
    /// Sensor period.
    pub period: Duration,
    /// Publish every this many ticks (at least 1).
    pub publish_every: u32,
    /// Sonar range reported when nothing echoed, m.
    pub sonar_max_m: f64,
}

impl PerceptionConfig {
    /// The prototype's drive, 20 Hz sensing, publishing at 10 Hz, starting at `start` known to 1 cm.
    pub fn prototype(chair: AgentId, start: Pose2) -> Self {
        PerceptionConfig {
            chair,
            drive: DiffDriveParams::default(),
            wheel_bias: WheelBias::WHEELCHAIR,
            start,
            start_covariance: Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, 1e-4)),
            period: Duration::from_millis(50),
            publish_every: 2,
            sonar_max_m: 3.0,
        }
    }
}

struct Subscription {
    /// The subscription's conversation: its notifications answer it, a CANCEL ends it.
    responder: Responder,
    readings: bool,
}

struct Visual {
    worker: VisionWorker,
    t_base_camera: Isometry3<f64>,
    motion_noise: VisualNoise,
    /// Wheel odometry pose when the filters last took a visual motion (their clone).
    wheel_at_clone: Pose2,
    /// Results fused and not fused (frames that failed or could not be placed in time).
    fused: u64,
    unused: u64,
    /// Landmark sightings fused.
    landmarks: u64,
}

/// The perception agent of one wheelchair.
pub struct PerceptionAgent {
    config: PerceptionConfig,
    body: Box<dyn Body + Send>,
    wheels: WheelOdometry,
    fusion: OdometryFusion,
    visual: Option<Visual>,
    subscribers: Vec<Subscription>,
    ticks: u64,
    last_sonar_m: Vec<f64>,
    localizer: Option<Localizer>,
    history: WheelHistory,
    /// The body time of the last range readings given to the localizer.
    last_ranges_ns: Option<u64>,
    /// The body's clock of the last encoder ticks ([`iw_body::SensorFrame::ticks_time_ns`]).
    last_ticks_ns: Option<u64>,
    /// The laser's and the sonar ring's use, as last told to the subscribers.
    ranges: [RangeSensor; 2],
}

/// Range readings this far behind the last ones (body time, ns) come from a body clock that
/// started again (a restarted board), not from the past.
const CLOCK_RESTART_NS: u64 = 1_000_000_000;

/// A range sensor the localizer may drop, as the subscribers were told of it.
#[derive(Debug)]
struct RangeSensor {
    /// Its name in `sensor-state`: `laser` or `sonars`.
    name: &'static str,
    /// Why the localizer dropped it (`None`: in use).
    dropped: Option<&'static str>,
    /// Its use changed since the subscribers were last told.
    news: bool,
}

impl RangeSensor {
    const fn new(name: &'static str) -> Self {
        RangeSensor {
            name,
            dropped: None,
            news: false,
        }
    }

    /// Takes the localizer's word on it; notes news when its use changed.
    fn observe(&mut self, dropped: Option<&'static str>) {
        if dropped != self.dropped {
            self.dropped = dropped;
            self.news = true;
        }
    }

    /// Its use as the ontology says it.
    fn state(&self, chair: &AgentId) -> WheelchairContent {
        WheelchairContent::Inform(Fact::Sensor {
            agent: chair.clone(),
            state: SensorState {
                sensor: self.name.into(),
                usage: match self.dropped {
                    Some(_) => SensorUse::Dropped,
                    None => SensorUse::InUse,
                },
                reason: self.dropped.unwrap_or_default().into(),
            },
        })
    }
}

impl PerceptionAgent {
    /// A perception agent reading `body`, fusing `visual` when given.
    pub fn new(
        config: PerceptionConfig,
        body: Box<dyn Body + Send>,
        visual: Option<VisualConfig>,
    ) -> Result<Self, PerceptionError> {
        for (name, value) in [
            ("wheel_radius_m", config.drive.wheel_radius_m),
            ("track_m", config.drive.track_m),
            ("ticks_per_rev", config.drive.ticks_per_rev),
            ("sonar_max_m", config.sonar_max_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(PerceptionError::BadParameter { name, value });
            }
        }
        let visual = visual
            .map(|v| {
                Ok::<_, PerceptionError>(Visual {
                    worker: VisionWorker::start(
                        &config.chair.name,
                        v.source,
                        v.vo,
                        v.t_base_camera,
                    )
                    .map_err(|source| PerceptionError::Vision { source })?,
                    t_base_camera: v.t_base_camera,
                    motion_noise: v.motion_noise,
                    wheel_at_clone: config.start,
                    fused: 0,
                    unused: 0,
                    landmarks: 0,
                })
            })
            .transpose()?;
        Ok(PerceptionAgent {
            wheels: WheelOdometry::new(config.drive, config.start),
            fusion: OdometryFusion::new(config.start, config.start_covariance, config.drive.alpha)
                .with_bias(config.wheel_bias),
            config,
            body,
            visual,
            subscribers: Vec::new(),
            ticks: 0,
            last_sonar_m: Vec::new(),
            localizer: None,
            history: WheelHistory::default(),
            last_ranges_ns: None,
            last_ticks_ns: None,
            ranges: [RangeSensor::new("laser"), RangeSensor::new("sonars")],
        })
    }

    /// Estimates with `localizer` (which holds the map and the chair's range sensors) instead
    /// of odometry alone; its start pose, or its search when it has none, replaces
    /// [`PerceptionConfig::start`].
    pub fn with_localizer(mut self, localizer: Localizer) -> Self {
        self.localizer = Some(localizer);
        self
    }

    /// Whether the chair knows where it is: always with odometry alone (it trusts its start),
    /// with a localizer only while it tracks.
    pub fn localized(&self) -> bool {
        self.localizer
            .as_ref()
            .is_none_or(|l| l.status() == Status::Tracking)
    }

    /// Visual results that arrived so far: given to the filters (which may still gate a motion
    /// out), and not (the frame failed, or its capture time fell outside the recorded ticks).
    /// Both zero without a camera.
    pub fn visual_results(&self) -> (u64, u64) {
        self.visual.as_ref().map_or((0, 0), |v| (v.fused, v.unused))
    }

    /// Landmark sightings fused into the localizer so far (none without a camera or a map).
    pub fn landmarks_fused(&self) -> u64 {
        self.visual.as_ref().map_or(0, |v| v.landmarks)
    }

    /// The current estimate as the ontology's pose.
    pub fn pose(&self) -> Pose {
        let (p, mut c) = match &self.localizer {
            Some(l) => (l.pose(), l.covariance()),
            None => (self.fusion.pose(), self.fusion.covariance()),
        };
        if !self.localized() {
            c[(0, 0)] = c[(0, 0)].max(LOST_VARIANCE_M2);
            c[(1, 1)] = c[(1, 1)].max(LOST_VARIANCE_M2);
        }
        Pose {
            x_m: p.x,
            y_m: p.y,
            theta_rad: p.theta,
            covariance: (c + c.transpose()) * 0.5,
        }
    }

    fn sense(&mut self) {
        match self.body.read() {
            Ok(frame) => {
                let last_ticks_ns = self.last_ticks_ns.replace(frame.ticks_time_ns);
                if let Some(step) = self.wheels.update(frame.left_ticks, frame.right_ticks) {
                    self.fusion.predict(&step);
                    if let Some(l) = self.localizer.as_mut() {
                        // the slip model's speeds are the step's travel over the time it took
                        match last_ticks_ns.map(|last| frame.ticks_time_ns.checked_sub(last)) {
                            // the same ticks read again: no motion and no time to measure
                            Some(Some(0)) if step == OdometryStep::default() => {}
                            Some(Some(ns)) if ns > 0 => l.predict_over(&step, ns as f64 * 1e-9),
                            // the first ticks, or the body's clock started again: one period
                            _ => l.predict(&step),
                        }
                    }
                }
                self.history.record(frame.time_ns, self.wheels.pose());
                let since = self.ranges_since(&frame);
                if let (Some(l), Some(since)) = (self.localizer.as_mut(), since) {
                    let before = l.status();
                    l.update_ranges_since(&frame.laser_m, &frame.sonar_m, &since);
                    if l.status() != before {
                        tracing::info!(chair = %self.config.chair.name, status = ?l.status(), "localization status changed");
                    }
                    self.ranges[0].observe(l.laser_dropped());
                    self.ranges[1].observe(l.sonar_dropped());
                }
                self.last_sonar_m = frame
                    .sonar_m
                    .iter()
                    .map(|r| r.unwrap_or(self.config.sonar_max_m))
                    .collect();
            }
            Err(err) => {
                tracing::warn!(chair = %self.config.chair.name, error = %err, "body read failed; pose not updated")
            }
        }
        self.vision();
    }

    /// The wheels' motion from when `frame`'s ranges were taken to now (base frame at the
    /// ranges' time), or `None` when they are not new: readings already given to the
    /// localizer (a body that returns its last readings again, as a mixed chair's ghost does
    /// while the world process is late) are no new scan, and are neither matched again nor
    /// counted as a scan that did not fit.
    fn ranges_since(&mut self, frame: &iw_body::SensorFrame) -> Option<Pose2> {
        // a time ahead of the encoders' cannot be: taken as now
        let taken = frame.ranges_time_ns.min(frame.time_ns);
        if let Some(last) = self.last_ranges_ns
            && taken <= last
            && last - taken <= CLOCK_RESTART_NS
        {
            tracing::trace!(chair = %self.config.chair.name, taken, last, "range readings not new: not matched");
            return None;
        }
        self.last_ranges_ns = Some(taken);
        if taken == frame.time_ns {
            return Some(Pose2::default());
        }
        let now = self.wheels.pose();
        // Assumption: ranges older than the recorded ticks (the first read) are taken as read
        // now.
        let at_ranges = self.history.interpolated(taken).unwrap_or(now);
        Some(at_ranges.between(&now))
    }

    /// Fuses the visual results that have arrived and asks for the next frame; never waits.
    fn vision(&mut self) {
        let Some(visual) = self.visual.as_mut() else {
            return;
        };
        let tolerance_ns = (self.config.period.as_nanos() / 2) as u64;
        for result in visual.worker.arrived() {
            let (time_ns, motion, markers) = match result {
                VisionResult::Frame {
                    time_ns,
                    motion,
                    markers,
                } => (time_ns, motion, markers),
                VisionResult::Failed(error) => {
                    visual.unused += 1;
                    tracing::warn!(chair = %self.config.chair.name, %error, "no visual update: camera frame unavailable");
                    continue;
                }
                VisionResult::Ended => {
                    tracing::info!(chair = %self.config.chair.name, "the camera has no more frames");
                    continue;
                }
            };
            let now = self.wheels.pose();
            let at_frame = self.history.at(time_ns, tolerance_ns);
            if let (Some(at_frame), Some(l)) = (at_frame, self.localizer.as_mut()) {
                // where each marker is from the base now, carried by the wheels since capture
                let since = at_frame.between(&now);
                for (id, p) in markers {
                    let (s, c) = since.theta.sin_cos();
                    let (dx, dy) = (p.x - since.x, p.y - since.y);
                    let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
                    if l.update_landmark(u32::from(id), x.hypot(y), y.atan2(x)) {
                        visual.landmarks += 1;
                    }
                }
            }
            let (previous_ns, t_previous_current) = match motion {
                Ok(Some(m)) => m,
                Ok(None) => continue,
                Err(error) => {
                    visual.unused += 1;
                    tracing::warn!(chair = %self.config.chair.name, %error, "no visual update: visual odometry failed on a frame");
                    continue;
                }
            };
            let (Some(at_previous), Some(at_current)) =
                (self.history.at(previous_ns, tolerance_ns), at_frame)
            else {
                visual.unused += 1;
                tracing::debug!(chair = %self.config.chair.name, "frame times not among the recorded ticks: not fused");
                continue;
            };
            let measured = planar_motion(&visual.t_base_camera, &t_previous_current);
            let motion = vision::bridged(
                &visual.wheel_at_clone,
                &at_previous,
                &measured,
                &at_current,
                &now,
            );
            let noise = visual.motion_noise.covariance(&motion);
            if !self.fusion.update_visual(&motion, &noise) {
                tracing::debug!(chair = %self.config.chair.name, "visual motion outside the gate: not fused");
            }
            if let Some(l) = self.localizer.as_mut() {
                l.update_visual(&motion, &noise);
            }
            visual.wheel_at_clone = now;
            visual.fused += 1;
        }
        visual.worker.request();
    }

    /// Tells every subscriber of each range sensor that was dropped or taken back.
    fn tell_ranges(&mut self, ctx: &mut Context<'_>) {
        for sensor in self.ranges.iter_mut().filter(|s| s.news) {
            sensor.news = false;
            let state = sensor.state(&self.config.chair);
            for sub in &mut self.subscribers {
                let _ = ctx.answer(&mut sub.responder, Performative::Inform, &state);
            }
        }
    }

    fn publish(&mut self, ctx: &mut Context<'_>) {
        let pose = WheelchairContent::Inform(Fact::AtPose {
            agent: self.config.chair.clone(),
            pose: self.pose(),
        });
        let sonar = WheelchairContent::Inform(Fact::Reading {
            agent: self.config.chair.clone(),
            reading: SensorReading::Sonar {
                ranges_m: self.last_sonar_m.clone(),
            },
        });
        for sub in &mut self.subscribers {
            let _ = ctx.answer(&mut sub.responder, Performative::Inform, &pose);
            if sub.readings && !self.last_sonar_m.is_empty() {
                let _ = ctx.answer(&mut sub.responder, Performative::Inform, &sonar);
            }
        }
    }
}

impl Agent for PerceptionAgent {
    fn handle(&mut self, ctx: &mut Context<'_>, message: AclMessage) {
        match message.performative {
            Performative::Subscribe => {
                let Some(readings) = ctx.understand(
                    &message,
                    "subscribe to ((at-pose ?agent ?pose)) or sensor-reading",
                    |s: iw_ontology::wheelchair::Subscription| {
                        (s.wants(Topic::AtPose) || s.wants(Topic::SensorReading))
                            .then_some(s.wants(Topic::SensorReading))
                    },
                ) else {
                    return;
                };
                let Some(mut responder) = ctx.accept(&message) else {
                    return;
                };
                if ctx
                    .acknowledge(&mut responder, Performative::Agree)
                    .is_err()
                {
                    return;
                }
                // One subscription per (subscriber, conversation): a repeated subscribe replaces it.
                self.subscribers.retain(|s| {
                    s.responder.conversation_id() != responder.conversation_id()
                        || s.responder.initiator() != responder.initiator()
                });
                for sensor in self.ranges.iter().filter(|s| s.dropped.is_some()) {
                    let state = sensor.state(&self.config.chair);
                    let _ = ctx.answer(&mut responder, Performative::Inform, &state);
                }
                self.subscribers.push(Subscription {
                    responder,
                    readings,
                });
            }
            Performative::Cancel => {
                self.subscribers
                    .retain_mut(|s| !ctx.continues(&mut s.responder, &message));
            }
            _ => {
                let _ =
                    ctx.not_understood(&message, "the perception agent takes subscribe and cancel");
            }
        }
    }

    fn tick_period(&self) -> Option<Duration> {
        Some(self.config.period)
    }

    fn tick(&mut self, ctx: &mut Context<'_>) {
        self.sense();
        self.tell_ranges(ctx);
        self.ticks += 1;
        if self
            .ticks
            .is_multiple_of(u64::from(self.config.publish_every.max(1)))
        {
            self.publish(ctx);
        }
    }
}

#[cfg(test)]
mod tests;
