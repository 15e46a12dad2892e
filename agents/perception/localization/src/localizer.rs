//! The localizer: an EKF over the base pose (iw-vo's [`OdometryFusion`]) predicted by wheel
//! odometry, updated by visual odometry, by scans matched to the map and by landmark sightings;
//! a multi-hypothesis search takes over while the pose is unknown (no start, or carried
//! elsewhere).

use std::sync::Arc;

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2, Vector3};

use crate::global::{GlobalConfig, GlobalLocalizer};
use crate::map::LocalizationMap;
use crate::matcher::{MatcherConfig, inlier_fraction, match_scan};
use crate::scan::{LaserGeometry, ReadingCount, ScanPoint, SonarGeometry};
use iw_vo::{AccelerationSlip, OdometryFusion, OdometryStep, Pose2, WheelBias, wrap_angle};

/// When a search may say it has found the pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Confidence {
    /// Rounds of hypothesis updates at least.
    pub min_updates: usize,
    /// The leading hypothesis's log-likelihood (as the search tempers it) exceeds every other
    /// one's by at least this: a likelihood ratio over the whole drive, not one scan.
    pub margin: f64,
    /// The full scan's match at the leader has this inlier fraction at least.
    pub min_inliers: f64,
}

/// How the localizer fuses and when it gives up.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalizerConfig {
    /// The laser, if the chair has one.
    pub laser: Option<LaserGeometry>,
    /// The sonar ring, if any.
    pub sonar: Option<SonarGeometry>,
    /// Scan matching.
    pub matcher: MatcherConfig,
    /// Global search.
    pub global: GlobalConfig,
    /// When the search is done.
    pub confidence: Confidence,
    /// A matched scan whose normalised innovation exceeds this is not fused (chi-square, 3
    /// degrees of freedom).
    pub gate_chi2: f64,
    /// A match with fewer inliers than this fraction is not fused.
    pub min_inliers: f64,
    /// After this many scans in a row that could not be fused the chair is lost, and searches.
    pub lost_after: u32,
    /// A sensor silent, garbled or contradicting the other this many scans in a row is
    /// dropped; it is taken back after as many good scans.
    pub drop_after: u32,
    /// Landmark sightings: range and bearing standard deviations (m, rad).
    pub landmark_sigma: (f64, f64),
    /// Motion model of the odometry (Thrun's alphas), as in [`iw_vo::DiffDriveParams`].
    pub alpha: [f64; 4],
    /// The slip that follows the wheels' acceleration, added to the alphas' noise (`None`:
    /// the alphas alone).
    pub acceleration_slip: Option<AccelerationSlip>,
    /// The wheels' systematic error, estimated in the filter while scans and landmarks observe
    /// it and held while they do not, so the covariance grows as fast as the error when the
    /// chair dead-reckons.
    pub wheel_bias: WheelBias,
    /// Prior standard deviation of visual odometry's scale error, estimated in the filter (see
    /// [`OdometryFusion::with_visual_scale`]): until walls or landmarks have measured it, visual
    /// odometry cannot tell the wheels' scale, and with it the place along a blank corridor.
    pub visual_scale_sigma: f64,
}

impl LocalizerConfig {
    /// Defaults for a chair with these sensors and motion model.
    pub fn new(
        laser: Option<LaserGeometry>,
        sonar: Option<SonarGeometry>,
        alpha: [f64; 4],
    ) -> Self {
        LocalizerConfig {
            laser,
            sonar,
            matcher: MatcherConfig::default(),
            global: GlobalConfig::default(),
            confidence: Confidence {
                min_updates: 5,
                margin: 12.0,
                min_inliers: 0.8,
            },
            gate_chi2: 16.27,
            min_inliers: 0.5,
            lost_after: 40,
            drop_after: 10,
            landmark_sigma: (0.05, 1f64.to_radians()),
            alpha,
            acceleration_slip: None,
            wheel_bias: WheelBias::WHEELCHAIR,
            visual_scale_sigma: 0.03,
        }
    }
}

/// Whether the localizer knows where the chair is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The pose is tracked on the map.
    Tracking,
    /// The pose is unknown (no start, or the scans stopped fitting): a search runs.
    Searching,
}

/// What one scan did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScanOutcome {
    /// Matched and fused; the match's normalised innovation squared.
    Fused {
        /// Normalised innovation squared.
        nis: f64,
    },
    /// Not fused (too few points, too few inliers, or outside the gate).
    Rejected,
    /// Weighed by the search (or skipped because the chair had not moved enough).
    Searched,
    /// The search found the pose: tracking again.
    Localized,
    /// No laser points this period (none fitted, silent or dropped): nothing is matched and the
    /// pose is predicted only. Sonars alone do not localize: their 45 degree cones, matched
    /// without a laser, left the estimate 6.4 m RMSE off on the sample building's tour (wheels
    /// alone: 0.5 m); with a laser they add points and vet it.
    Unused,
}

/// Health of one range sensor.
#[derive(Debug, Clone, Default)]
struct Health {
    bad_in_row: u32,
    good_in_row: u32,
    dropped: bool,
    /// Why it was dropped, while it is.
    reason: Option<&'static str>,
}

impl Health {
    /// Records one scan; returns whether the sensor may be used for it.
    fn observe(&mut self, name: &str, problem: Option<&'static str>, drop_after: u32) -> bool {
        match problem {
            Some(why) => {
                self.good_in_row = 0;
                self.bad_in_row = self.bad_in_row.saturating_add(1);
                if !self.dropped && self.bad_in_row >= drop_after {
                    self.dropped = true;
                    self.reason = Some(why);
                    tracing::warn!(
                        sensor = name,
                        reason = why,
                        "range sensor dropped from localization"
                    );
                }
                false
            }
            None => {
                self.bad_in_row = 0;
                self.good_in_row = self.good_in_row.saturating_add(1);
                if self.dropped && self.good_in_row >= drop_after {
                    self.dropped = false;
                    self.reason = None;
                    tracing::warn!(sensor = name, "range sensor back in localization");
                }
                !self.dropped
            }
        }
    }
}

/// Whether readings are unusable as such: silent, or half garbage.
fn reading_problem(count: &ReadingCount) -> Option<&'static str> {
    if count.total == 0 {
        Some("silent: no readings")
    } else if count.invalid * 2 > count.total {
        Some("garbage: most readings are not ranges")
    } else {
        None
    }
}

/// The localizer of one chair.
#[derive(Debug, Clone)]
pub struct Localizer {
    map: Arc<LocalizationMap>,
    config: LocalizerConfig,
    fusion: OdometryFusion,
    status: Status,
    search: Option<GlobalLocalizer>,
    searches: u64,
    rejected_in_row: u32,
    laser: Health,
    sonar: Health,
    laser_points: Vec<ScanPoint>,
    sonar_points: Vec<ScanPoint>,
}

/// Below this inlier fraction at the predicted pose a sensor contradicts the map.
const DISAGREE_INLIERS: f64 = 0.2;
/// Pose reported while searching before the search has a scan.
const UNKNOWN_VAR: f64 = 1e6;

impl Localizer {
    /// A localizer at `start` (pose and covariance), or searching when `None`.
    pub fn new(
        map: Arc<LocalizationMap>,
        config: LocalizerConfig,
        start: Option<(Pose2, Matrix3<f64>)>,
    ) -> Self {
        let (pose, covariance) =
            start.unwrap_or((Pose2::default(), Matrix3::identity() * UNKNOWN_VAR));
        let mut fusion = OdometryFusion::new(pose, covariance, config.alpha)
            .with_bias(config.wheel_bias)
            .with_visual_scale(config.visual_scale_sigma);
        if let Some(slip) = config.acceleration_slip {
            fusion = fusion.with_acceleration_slip(slip);
        }
        Localizer {
            map,
            fusion,
            status: if start.is_some() {
                Status::Tracking
            } else {
                Status::Searching
            },
            config,
            search: None,
            searches: 0,
            rejected_in_row: 0,
            laser: Health::default(),
            sonar: Health::default(),
            laser_points: Vec::new(),
            sonar_points: Vec::new(),
        }
    }

    /// Whether the pose is tracked.
    pub fn status(&self) -> Status {
        self.status
    }

    /// The pose estimate: the EKF's while tracking, the hypotheses' (weighed by likelihood) while searching.
    pub fn pose(&self) -> Pose2 {
        self.estimate().0
    }

    /// Covariance of [`Self::pose`] (x, y, theta), symmetric.
    pub fn covariance(&self) -> Matrix3<f64> {
        self.estimate().1
    }

    fn estimate(&self) -> (Pose2, Matrix3<f64>) {
        match (&self.status, &self.search) {
            (Status::Tracking, _) => {
                let c = self.fusion.covariance();
                (self.fusion.pose(), (c + c.transpose()) * 0.5)
            }
            (Status::Searching, search) => match search.as_ref().and_then(|s| s.estimate()) {
                // never less certain than dead reckoning would say, never overconfident
                Some((pose, c)) => (
                    pose,
                    c + Matrix3::from_diagonal(&Vector3::new(0.01, 0.01, 0.003)),
                ),
                None => (self.fusion.pose(), Matrix3::identity() * UNKNOWN_VAR),
            },
        }
    }

    /// Searches started so far (a start without a pose counts, and every time the chair got lost).
    pub fn searches(&self) -> u64 {
        self.searches
    }

    /// The estimated wheel bias (scale error, heading drift in rad/m) and their standard
    /// deviations.
    pub fn wheel_bias(&self) -> ([f64; 2], [f64; 2]) {
        self.fusion.bias()
    }

    /// Whether the laser and the sonars are currently dropped.
    pub fn dropped(&self) -> (bool, bool) {
        (self.laser.dropped, self.sonar.dropped)
    }

    /// Why the laser is dropped, while it is (see [`LocalizerConfig::drop_after`]).
    pub fn laser_dropped(&self) -> Option<&'static str> {
        self.laser.reason
    }

    /// Why the sonar ring is dropped, while it is (see [`LocalizerConfig::drop_after`]).
    pub fn sonar_dropped(&self) -> Option<&'static str> {
        self.sonar.reason
    }

    /// Predicts with one wheel odometry step of the nominal period.
    pub fn predict(&mut self, step: &OdometryStep) {
        self.predict_timed(step, None);
    }

    /// Predicts with one wheel odometry step that took `duration_s` (see
    /// [`OdometryFusion::predict_over`]).
    pub fn predict_over(&mut self, step: &OdometryStep, duration_s: f64) {
        self.predict_timed(step, Some(duration_s));
    }

    fn predict_timed(&mut self, step: &OdometryStep, duration_s: Option<f64>) {
        match duration_s {
            Some(took_s) => self.fusion.predict_over(step, took_s),
            None => self.fusion.predict(step),
        }
        if let Some(search) = self.search.as_mut() {
            search.predict(step);
        }
    }

    /// Updates with visual odometry's motion since its previous frame (see
    /// [`OdometryFusion::update_visual`]).
    pub fn update_visual(&mut self, motion: &Pose2, noise: &Matrix3<f64>) -> bool {
        self.fusion.update_visual(motion, noise)
    }

    /// Updates with the latest laser ranges (empty: no laser reading this period) and sonar
    /// ranges (`None`: no echo), taken with the last odometry step.
    pub fn update_ranges(&mut self, laser_m: &[f64], sonar_m: &[Option<f64>]) -> ScanOutcome {
        self.update_ranges_since(laser_m, sonar_m, &Pose2::default())
    }

    /// Updates with ranges taken earlier, where the base was before it moved by `since` (the
    /// wheel odometry's motion from the ranges' time to the last odometry step, in the base
    /// frame at the ranges' time): the scan is matched from the estimate carried back by
    /// `since`, and its pose carried forward by it is fused as a measurement of the current
    /// pose.
    ///
    /// Ranges a period or two old (a mixed chair's ghost in a world process) matched as if
    /// taken now were off by the motion in between: up to 6 cm and 0.03 rad while turning,
    /// about 2 standard deviations of a match, so a loaded host's longer lag had every scan
    /// gated out and the chair taken for lost.
    /// Assumption: the odometry's error over `since` (a few centimetres) is negligible beside
    /// the match's, so it is neither added to the measurement's noise nor correlated with the
    /// prediction's.
    pub fn update_ranges_since(
        &mut self,
        laser_m: &[f64],
        sonar_m: &[Option<f64>],
        since: &Pose2,
    ) -> ScanOutcome {
        self.laser_points.clear();
        self.sonar_points.clear();
        let laser_count = self
            .config
            .laser
            .as_ref()
            .map(|g| g.points(laser_m, &mut self.laser_points));
        let sonar_count = self
            .config
            .sonar
            .as_ref()
            .map(|g| g.points(sonar_m, &mut self.sonar_points));
        let mut laser_problem = laser_count.as_ref().and_then(reading_problem);
        let mut sonar_problem = sonar_count.as_ref().and_then(reading_problem);
        // where the estimate puts the base when the ranges were taken
        let at_scan = self.fusion.pose().compose(&since.inverse());
        if self.status == Status::Tracking {
            // a sensor that contradicts the map while the other agrees is what is wrong
            let fit = |points: &[ScanPoint]| {
                (points.len() >= 5)
                    .then(|| inlier_fraction(&self.map, points, &at_scan, &self.config.matcher))
            };
            let (lf, sf) = (fit(&self.laser_points), fit(&self.sonar_points));
            if let (Some(lf), Some(sf)) = (lf, sf) {
                if lf < DISAGREE_INLIERS && sf >= 0.5 {
                    laser_problem = laser_problem.or(Some("contradicts the map and the sonars"));
                }
                if sf < DISAGREE_INLIERS && lf >= 0.5 {
                    sonar_problem = sonar_problem.or(Some("contradicts the map and the laser"));
                }
            }
        }
        let drop_after = self.config.drop_after;
        let use_laser =
            laser_count.is_some() && self.laser.observe("laser", laser_problem, drop_after);
        let use_sonar =
            sonar_count.is_some() && self.sonar.observe("sonar", sonar_problem, drop_after);
        if !use_laser {
            return ScanOutcome::Unused;
        }
        let mut points = Vec::with_capacity(self.laser_points.len() + self.sonar_points.len());
        points.extend_from_slice(&self.laser_points);
        if use_sonar {
            points.extend_from_slice(&self.sonar_points);
        }
        match self.status {
            Status::Tracking => self.track(&points, since, &at_scan),
            // the search's hypotheses are spread far wider than a few periods' motion
            Status::Searching => self.search(&points),
        }
    }

    /// Matches `points` from `at_scan` (the estimate carried back by `since`) and fuses the
    /// match carried forward by `since`.
    fn track(&mut self, points: &[ScanPoint], since: &Pose2, at_scan: &Pose2) -> ScanOutcome {
        let predicted = self.fusion.pose();
        let fused = match match_scan(&self.map, points, at_scan, &self.config.matcher) {
            None => Err("no match"),
            Some(m) if m.inlier_fraction < self.config.min_inliers => Err("too few inliers"),
            Some(m) => {
                let measured = m.pose.compose(since);
                let innovation = Vector3::new(
                    measured.x - predicted.x,
                    measured.y - predicted.y,
                    wrap_angle(measured.theta - predicted.theta),
                );
                // the match's covariance carried forward: d(m ⊕ since)/dm
                let (s, c) = m.pose.theta.sin_cos();
                let carry = Matrix3::new(
                    1.0,
                    0.0,
                    -(s * since.x + c * since.y),
                    0.0,
                    1.0,
                    c * since.x - s * since.y,
                    0.0,
                    0.0,
                    1.0,
                );
                match self.fusion.update_current(
                    &innovation,
                    &Matrix3::identity(),
                    &(carry * m.covariance * carry.transpose()),
                    self.config.gate_chi2,
                ) {
                    Some((nis, true)) => Ok(nis),
                    Some((nis, false)) => {
                        tracing::debug!(
                            nis,
                            dx = innovation.x,
                            dy = innovation.y,
                            dtheta = innovation.z,
                            "scan outside the gate"
                        );
                        Err("outside the gate")
                    }
                    None => Err("singular innovation covariance"),
                }
            }
        };
        match fused {
            Ok(nis) => {
                self.rejected_in_row = 0;
                ScanOutcome::Fused { nis }
            }
            Err(why) => {
                self.rejected_in_row = self.rejected_in_row.saturating_add(1);
                tracing::debug!(why, in_row = self.rejected_in_row, "scan not fused");
                if self.rejected_in_row >= self.config.lost_after && points.len() >= 12 {
                    tracing::warn!(
                        scans = self.rejected_in_row,
                        "the scans stopped fitting the map around the estimate: searching"
                    );
                    self.start_search(points);
                }
                ScanOutcome::Rejected
            }
        }
    }

    fn start_search(&mut self, points: &[ScanPoint]) {
        self.status = Status::Searching;
        self.rejected_in_row = 0;
        self.searches += 1;
        self.search = Some(GlobalLocalizer::start(
            &self.map,
            points,
            self.config.global,
            self.config.matcher,
        ));
    }

    fn search(&mut self, points: &[ScanPoint]) -> ScanOutcome {
        let Some(search) = self.search.as_mut() else {
            if points.len() >= 12 {
                self.start_search(points);
                self.searches = self.searches.max(1);
            }
            return ScanOutcome::Searched;
        };
        if !search.step(&self.map, points) {
            return ScanOutcome::Searched;
        }
        let confidence = self.config.confidence;
        let Some((leader, lead)) = search.leader() else {
            return ScanOutcome::Searched;
        };
        if search.updates() < confidence.min_updates || lead < confidence.margin {
            return ScanOutcome::Searched;
        }
        let Some(m) = match_scan(&self.map, points, &leader, &self.config.matcher) else {
            return ScanOutcome::Searched;
        };
        let moved = (m.pose.x - leader.x).hypot(m.pose.y - leader.y);
        if m.observed < 3 || m.inlier_fraction < confidence.min_inliers || moved > 0.1 {
            return ScanOutcome::Searched;
        }
        let spread = search.estimate().map_or(Matrix3::zeros(), |(_, c)| c);
        tracing::info!(
            x = m.pose.x,
            y = m.pose.y,
            theta = m.pose.theta,
            "pose found on the map"
        );
        self.fusion.reset(m.pose, m.covariance + spread);
        self.search = None;
        self.status = Status::Tracking;
        ScanOutcome::Localized
    }

    /// Updates with a landmark sighting: landmark `id` seen at `range_m` and `bearing_rad` from
    /// the base origin (base frame). Unknown ids, sightings while searching and sightings
    /// outside the 99.9 % gate are not fused; returns whether it was.
    pub fn update_landmark(&mut self, id: u32, range_m: f64, bearing_rad: f64) -> bool {
        if self.status != Status::Tracking || !(range_m.is_finite() && bearing_rad.is_finite()) {
            return false;
        }
        let Some(landmark) = self.map.landmarks().iter().find(|l| l.id == id) else {
            return false;
        };
        let pose = self.fusion.pose();
        let d = Vector2::new(landmark.pose.x - pose.x, landmark.pose.y - pose.y);
        let q = d.norm_squared();
        if q < 1e-6 {
            return false;
        }
        let r = q.sqrt();
        let innovation = Vector2::new(
            range_m - r,
            wrap_angle(bearing_rad - (d.y.atan2(d.x) - pose.theta)),
        );
        let h = Matrix2x3::new(-d.x / r, -d.y / r, 0.0, d.y / q, -d.x / q, -1.0);
        let (sr, sb) = self.config.landmark_sigma;
        let noise = Matrix2::new(sr * sr, 0.0, 0.0, sb * sb);
        matches!(
            self.fusion.update_current(&innovation, &h, &noise, 13.82),
            Some((_, true))
        )
    }
}
