//! The localizer: an EKF over the base pose (iw-vo's [`OdometryFusion`]) predicted by wheel
//! odometry, updated by visual odometry, by scans matched to the map and by landmark sightings;
//! a multi-hypothesis search takes over while the pose is unknown (no start, or carried
//! elsewhere).

use std::collections::VecDeque;
use std::sync::Arc;

use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2, Vector3};

use crate::global::{GlobalConfig, GlobalLocalizer};
use crate::map::LocalizationMap;
use crate::matcher::{MatcherConfig, inlier_fraction, match_scan};
use crate::scan::{LaserGeometry, ReadingCount, ScanPoint, SonarGeometry};
use iw_vo::{OdometryFusion, OdometryStep, Pose2, WheelBias, wrap_angle};

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
    /// The wheels' systematic error, estimated in the filter while scans and landmarks observe
    /// it and held while they do not, so the covariance grows as fast as the error when the
    /// chair dead-reckons.
    pub wheel_bias: WheelBias,
    /// Each matched scan is fused as this many times less certain than its match says, along
    /// the chair's heading, across it and in heading: a match's covariance is honest for one
    /// scan (the match's Laplace approximation), but consecutive scans see the same walls from
    /// nearly the same place and start from the filter's own prediction, so their errors are
    /// correlated and twenty a second are not twenty independent measurements. The factors
    /// are the integrated autocorrelation times of the match error (1 + 2 Σ ρ_k over 20 to 60
    /// scans) on the sample building's tour: 3.4-3.5 along the chair's path, 1.6-1.9 across
    /// it, 2.2-2.9 in heading. One factor for all three (3) over-covered the across and heading
    /// errors and under-covered the along errors: NEES misses on both sides.
    pub correlated_scans: CorrelatedScans,
}

/// How many scans' worth of correlated error one matched scan carries, per direction of the
/// chair's frame (see [`LocalizerConfig::correlated_scans`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrelatedScans {
    /// Along the chair's heading.
    pub along: f64,
    /// Across it.
    pub across: f64,
    /// In heading.
    pub heading: f64,
}

impl CorrelatedScans {
    /// `covariance` (map x, y, heading) of a match at heading `theta`, scaled by the factors in
    /// the chair's frame.
    fn inflate(&self, covariance: &Matrix3<f64>, theta: f64) -> Matrix3<f64> {
        let (s, c) = theta.sin_cos();
        // map to chair frame, then each axis by the square root of its factor, then back
        let to_chair = Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
        let scale = Matrix3::from_diagonal(&Vector3::new(
            self.along.sqrt(),
            self.across.sqrt(),
            self.heading.sqrt(),
        ));
        let m = to_chair.transpose() * scale * to_chair;
        m * covariance * m.transpose()
    }
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
            wheel_bias: WheelBias::WHEELCHAIR,
            correlated_scans: CorrelatedScans {
                along: 3.5,
                across: 1.8,
                heading: 2.5,
            },
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
    /// Taken no later than the last scan (the same frame read again, as when a world process
    /// has not sent the next one yet): already used, not fused again.
    Stale,
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
    /// The filter's recent past, while wheel steps come with their times.
    history: Option<History>,
    /// When the last scan with a time was taken.
    last_scan_ns: Option<u64>,
}

/// Something the filter did after its last fused scan, kept to be done again when a scan taken
/// before it is fused at its own time.
#[derive(Debug, Clone)]
enum Replay {
    /// A wheel step that ended at this time.
    Predict { time_ns: u64, step: OdometryStep },
    /// A visual odometry motion (see [`OdometryFusion::update_visual`]).
    Visual { motion: Pose2, noise: Matrix3<f64> },
    /// A landmark sighting (see [`Localizer::update_landmark`]).
    Landmark {
        id: u32,
        range_m: f64,
        bearing_rad: f64,
    },
}

/// Lag compensation: the filter as it was after the last fused scan (or as far back as is
/// kept), and everything it did since. A scan taken at time `t` (a mixed chair's ghost answers
/// a period or more late) is matched and fused against the state after the last wheel step
/// that ended by `t`, and what came after is done again on top, so the wheels' motion since the
/// scan is not mistaken for an error of the scan, nor learned as a wheel bias. The re-run is
/// the exact EKF answer for a measurement in the past (its cross-covariance with the current
/// state is carried by the predictions replayed after it).
#[derive(Debug, Clone)]
struct History {
    base: OdometryFusion,
    since: VecDeque<Replay>,
}

/// A scan may be fused this far in the past (ns); older ones are fused at the oldest state kept.
const MAX_LAG_NS: u64 = 1_000_000_000;
/// At most this many things done are kept (a bound when the wheel steps' time stands still).
const MAX_REPLAY: usize = 128;

impl History {
    /// When the latest wheel step kept ended.
    fn latest_ns(&self) -> Option<u64> {
        self.since.iter().rev().find_map(Replay::time_ns)
    }
}

impl Replay {
    /// When a wheel step ended.
    fn time_ns(&self) -> Option<u64> {
        match self {
            Replay::Predict { time_ns, .. } => Some(*time_ns),
            _ => None,
        }
    }

    /// Does it again on `fusion`.
    fn apply(&self, fusion: &mut OdometryFusion, map: &LocalizationMap, sigma: (f64, f64)) {
        match self {
            Replay::Predict { step, .. } => fusion.predict(step),
            Replay::Visual { motion, noise } => {
                fusion.update_visual(motion, noise);
            }
            Replay::Landmark {
                id,
                range_m,
                bearing_rad,
            } => {
                fuse_landmark(fusion, map, sigma, *id, *range_m, *bearing_rad);
            }
        }
    }
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
        Localizer {
            map,
            fusion: OdometryFusion::new(pose, covariance, config.alpha)
                .with_bias(config.wheel_bias),
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
            history: None,
            last_scan_ns: None,
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

    /// Predicts with one wheel odometry step whose time is not known: scans are then fused
    /// at the latest state ([`Self::update_ranges`]), and no past is kept.
    pub fn predict(&mut self, step: &OdometryStep) {
        self.history = None;
        self.advance(step);
    }

    /// Predicts with one wheel odometry step that ended at `time_ns` (the body's clock, the
    /// one of [`Self::update_ranges_at`]); the recent past is kept so that a scan taken before
    /// the latest step is fused at its own time.
    pub fn predict_at(&mut self, time_ns: u64, step: &OdometryStep) {
        if self.history.as_ref().and_then(History::latest_ns) > Some(time_ns) {
            // the body's clock started again (a board that restarted): its past is another
            self.history = None;
        }
        if self.status == Status::Tracking {
            let base = &self.fusion;
            let history = self.history.get_or_insert_with(|| History {
                base: base.clone(),
                since: VecDeque::new(),
            });
            history.since.push_back(Replay::Predict {
                time_ns,
                step: *step,
            });
            self.forget();
        }
        self.advance(step);
    }

    fn advance(&mut self, step: &OdometryStep) {
        self.fusion.predict(step);
        if let Some(search) = self.search.as_mut() {
            search.predict(step);
        }
    }

    /// Keeps the past to [`MAX_LAG_NS`] of wheel steps and [`MAX_REPLAY`] things done: the
    /// oldest are done on the kept base for good.
    fn forget(&mut self) {
        let Some(history) = self.history.as_mut() else {
            return;
        };
        let latest = history.latest_ns();
        while let Some(first) = history.since.front() {
            let old = matches!((first.time_ns(), latest), (Some(t), Some(l)) if l.saturating_sub(t) > MAX_LAG_NS);
            if !(old || history.since.len() > MAX_REPLAY) {
                break;
            }
            if let Some(done) = history.since.pop_front() {
                done.apply(&mut history.base, &self.map, self.config.landmark_sigma);
            }
        }
    }

    /// Keeps `replay`, done at the latest state, for a scan fused before it later.
    fn remember(&mut self, replay: Replay) {
        if let Some(history) = self.history.as_mut() {
            history.since.push_back(replay);
            self.forget();
        }
    }

    /// Updates with visual odometry's motion since its previous frame (see
    /// [`OdometryFusion::update_visual`]).
    pub fn update_visual(&mut self, motion: &Pose2, noise: &Matrix3<f64>) -> bool {
        self.remember(Replay::Visual {
            motion: *motion,
            noise: *noise,
        });
        self.fusion.update_visual(motion, noise)
    }

    /// Updates with the latest laser ranges (empty: no laser reading this period) and sonar
    /// ranges (`None`: no echo), taken at the latest state.
    pub fn update_ranges(&mut self, laser_m: &[f64], sonar_m: &[Option<f64>]) -> ScanOutcome {
        self.ranges(None, laser_m, sonar_m)
    }

    /// Updates with ranges taken at `time_ns` (see [`Self::predict_at`]): matched against the
    /// pose the chair had then and fused there. A scan taken no later than the last one is
    /// [`ScanOutcome::Stale`].
    pub fn update_ranges_at(
        &mut self,
        time_ns: u64,
        laser_m: &[f64],
        sonar_m: &[Option<f64>],
    ) -> ScanOutcome {
        match self.last_scan_ns {
            // the body's clock started again: no scan before is comparable
            Some(last) if time_ns.saturating_add(MAX_LAG_NS) < last => {}
            Some(last) if time_ns <= last => return ScanOutcome::Stale,
            _ => {}
        }
        self.last_scan_ns = Some(time_ns);
        self.ranges(Some(time_ns), laser_m, sonar_m)
    }

    /// The filter as it was at `time_ns` (after the last wheel step that ended by then), and
    /// how many of the things kept were done before that; the latest state without a time.
    fn state_at(&self, time_ns: Option<u64>) -> (OdometryFusion, usize) {
        let (Some(t), Some(history)) = (time_ns, self.history.as_ref()) else {
            return (self.fusion.clone(), 0);
        };
        let before = history
            .since
            .iter()
            .position(|r| matches!(r, Replay::Predict { time_ns, .. } if *time_ns > t))
            .unwrap_or(history.since.len());
        if before == history.since.len() {
            return (self.fusion.clone(), before);
        }
        let mut at = history.base.clone();
        for r in history.since.range(..before) {
            r.apply(&mut at, &self.map, self.config.landmark_sigma);
        }
        (at, before)
    }

    /// Takes `at`, updated at the state after `before` of the things kept, as the past, and
    /// does what came after again on it.
    fn commit(&mut self, at: OdometryFusion, before: usize) {
        match self.history.as_mut() {
            Some(history) => {
                history.since.drain(..before.min(history.since.len()));
                let mut now = at.clone();
                for r in &history.since {
                    r.apply(&mut now, &self.map, self.config.landmark_sigma);
                }
                history.base = at;
                self.fusion = now;
            }
            None => self.fusion = at,
        }
    }

    fn ranges(
        &mut self,
        time_ns: Option<u64>,
        laser_m: &[f64],
        sonar_m: &[Option<f64>],
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
        let at = (self.status == Status::Tracking).then(|| self.state_at(time_ns));
        if let Some((at, _)) = &at {
            // a sensor that contradicts the map while the other agrees is what is wrong
            let pose = at.pose();
            let fit = |points: &[ScanPoint]| {
                (points.len() >= 5)
                    .then(|| inlier_fraction(&self.map, points, &pose, &self.config.matcher))
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
        match at {
            Some((at, before)) => self.track(at, before, &points),
            None => self.search(&points),
        }
    }

    /// Matches `points` against the map from `at` (the state when they were taken, after
    /// `before` of the things kept) and fuses the match there.
    fn track(
        &mut self,
        mut at: OdometryFusion,
        before: usize,
        points: &[ScanPoint],
    ) -> ScanOutcome {
        let predicted = at.pose();
        let fused = match_scan(&self.map, points, &predicted, &self.config.matcher)
            .filter(|m| m.inlier_fraction >= self.config.min_inliers)
            .and_then(|m| {
                let innovation = Vector3::new(
                    m.pose.x - predicted.x,
                    m.pose.y - predicted.y,
                    wrap_angle(m.pose.theta - predicted.theta),
                );
                at.update_current(
                    &innovation,
                    &Matrix3::identity(),
                    &self
                        .config
                        .correlated_scans
                        .inflate(&m.covariance, predicted.theta),
                    self.config.gate_chi2,
                )
            });
        match fused {
            Some((nis, true)) => {
                self.rejected_in_row = 0;
                self.commit(at, before);
                ScanOutcome::Fused { nis }
            }
            _ => {
                self.rejected_in_row = self.rejected_in_row.saturating_add(1);
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
        self.history = None;
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
        if self.status != Status::Tracking {
            return false;
        }
        self.remember(Replay::Landmark {
            id,
            range_m,
            bearing_rad,
        });
        fuse_landmark(
            &mut self.fusion,
            &self.map,
            self.config.landmark_sigma,
            id,
            range_m,
            bearing_rad,
        )
    }
}

/// Fuses a landmark sighting into `fusion` (see [`Localizer::update_landmark`]); `sigma`:
/// range and bearing standard deviations.
fn fuse_landmark(
    fusion: &mut OdometryFusion,
    map: &LocalizationMap,
    sigma: (f64, f64),
    id: u32,
    range_m: f64,
    bearing_rad: f64,
) -> bool {
    if !(range_m.is_finite() && bearing_rad.is_finite()) {
        return false;
    }
    let Some(landmark) = map.landmarks().iter().find(|l| l.id == id) else {
        return false;
    };
    let pose = fusion.pose();
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
    let (sr, sb) = sigma;
    let noise = Matrix2::new(sr * sr, 0.0, 0.0, sb * sb);
    matches!(
        fusion.update_current(&innovation, &h, &noise, 13.82),
        Some((_, true))
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correlated_scans_inflate_along_and_across_the_chair() {
        let factors = CorrelatedScans {
            along: 4.0,
            across: 2.0,
            heading: 3.0,
        };
        let round = Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 1e-5));
        let east = factors.inflate(&round, 0.0);
        assert!(
            (east - Matrix3::from_diagonal(&Vector3::new(4e-4, 2e-4, 3e-5)))
                .abs()
                .max()
                < 1e-15
        );
        // facing north, the map's x is across the chair
        let north = factors.inflate(&round, std::f64::consts::FRAC_PI_2);
        assert!(
            (north - Matrix3::from_diagonal(&Vector3::new(2e-4, 4e-4, 3e-5)))
                .abs()
                .max()
                < 1e-15
        );
    }
}
