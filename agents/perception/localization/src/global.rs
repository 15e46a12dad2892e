//! Global localization from an unknown start: multi-hypothesis tracking.
//!
//! A correlative search of the free space (a grid of positions times headings, scored on the
//! map's likelihood field) proposes the distinct poses that explain the first scan. Each of
//! them is then tracked while the chair drives: moved by odometry, pulled onto the map by scan
//! matching, and credited with every scan's log-likelihood. A hypothesis that falls far behind
//! the best is dropped; two that converge on one pose become one. The search is done when one
//! hypothesis leads every other by a likelihood ratio, so the ambiguity test weighs the whole
//! drive, not one scan: two near-identical rooms both stay candidates until a scan tells them
//! apart, and the right pose is not thrown away because the current scan alone fits a twin
//! (that is what kept the earlier particle filter searching, and what let it settle outside
//! the building with no way back).
//!
//! The work is bounded per call ([`GlobalConfig::work_per_step`] point evaluations): the grid
//! search and each round of hypothesis updates are spread over control periods, each on the
//! scan it started with, carried to the present by the odometry since.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use nalgebra::{Matrix3, Point2, Vector3};

use crate::map::LocalizationMap;
use crate::matcher::{MatcherConfig, match_scan};
use crate::scan::ScanPoint;
use iw_vo::{OdometryStep, Pose2, wrap_angle};

/// How the search proposes, tracks and drops hypotheses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalConfig {
    /// Spacing of the search grid, m, rounded to a whole number of the map's distance-grid
    /// cells (0.1 m): the grid's positions lie on the cells' corners.
    pub grid_step_m: f64,
    /// Headings tried at each grid point.
    pub headings: usize,
    /// Poses closer than this to the map are not where a chair can stand, m.
    pub clearance_m: f64,
    /// Scan points used per evaluation (evenly subsampled).
    pub points: usize,
    /// Likelihood field width, m.
    pub sigma_m: f64,
    /// Each point's log-likelihood counts this much (neighbouring beams are not independent).
    pub tempering: f64,
    /// Hypotheses taken from the grid search at most (its best poses, pairwise distinct).
    pub hypotheses: usize,
    /// Two grid poses closer than this in position (m) and heading (rad) are one hypothesis.
    pub separation: (f64, f64),
    /// Two tracked hypotheses that converged this close (m, rad) are merged.
    pub merge: (f64, f64),
    /// Scan-matching iterations per hypothesis and update.
    pub refine_iterations: usize,
    /// A hypothesis whose log-likelihood falls this far behind the best is dropped.
    pub prune_margin: f64,
    /// Update after this much travel, m, or this much turn, rad.
    pub update_every: (f64, f64),
    /// The best hypothesis explains fewer than this share of the scan points ...
    pub poor_fit: f64,
    /// ... this many updates in a row: none is right, the search starts afresh.
    pub poor_after: usize,
    /// Point evaluations on the likelihood field (one point of one matching iteration counts as
    /// several) per call of [`GlobalLocalizer::step`]: the search's share of a control period.
    pub work_per_step: usize,
}

impl Default for GlobalConfig {
    fn default() -> Self {
        GlobalConfig {
            grid_step_m: 0.2,
            headings: 36,
            clearance_m: 0.3,
            points: 48,
            sigma_m: 0.1,
            tempering: 0.25,
            hypotheses: 100,
            separation: (0.4, 15f64.to_radians()),
            merge: (0.1, 5f64.to_radians()),
            refine_iterations: 4,
            prune_margin: 30.0,
            update_every: (0.05, 0.05),
            poor_fit: 0.5,
            poor_after: 20,
            work_per_step: 150_000,
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Hypothesis {
    /// Pose when the current scan was taken.
    pose: Pose2,
    /// Accumulated log-likelihood, the best's is 0 after each round.
    log_w: f64,
    /// Share of the last scan's points near the map at `pose`.
    fit: f64,
}

/// A grid pose (its index) and its score, ordered by score.
#[derive(Debug, Clone, Copy)]
struct Scored {
    score: f64,
    index: usize,
}

impl PartialEq for Scored {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == std::cmp::Ordering::Equal
    }
}

impl Eq for Scored {}

impl PartialOrd for Scored {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Scored {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.score.total_cmp(&other.score)
    }
}

#[derive(Debug, Clone)]
enum Phase {
    /// Scoring the grid (heading-major index `next` over `positions`, the distance-grid
    /// corners they lie on); `best` keeps the best-scoring poses so far, worst on top;
    /// `offsets` are the scan points' cells relative to a position at `heading`.
    Grid {
        positions: Vec<(i32, i32)>,
        next: usize,
        best: BinaryHeap<Reverse<Scored>>,
        heading: usize,
        offsets: Vec<(i32, i32)>,
    },
    /// Updating the hypotheses with the current scan, `next` is the next one.
    Update { next: usize },
    /// Waiting for enough travel for the next update.
    Idle,
}

/// The multi-hypothesis search.
#[derive(Debug, Clone)]
pub struct GlobalLocalizer {
    config: GlobalConfig,
    matcher: MatcherConfig,
    log_likelihood: Vec<f64>,
    field: Field,
    phase: Phase,
    /// The scan being worked on, subsampled.
    scan: Vec<ScanPoint>,
    /// Odometry since `scan` was taken.
    since: Pose2,
    /// Travel and turn since `scan` was taken.
    travel: (f64, f64),
    hypotheses: Vec<Hypothesis>,
    updates: usize,
    poor_in_row: usize,
}

/// One point of one scan-matching iteration (an exact nearest-segment query among its bucket's
/// segments, the kernel and the normal equations) weighs this many likelihood-field look-ups: a
/// rough, generous weight, set when a look-up still rotated its point and converted its
/// distance. The grid's look-ups are now several times cheaper; the weights are kept so that
/// the search does the same work in the same periods (its results did not change).
const MATCH_POINT_COST: usize = 30;

/// The grid search keeps this many best poses per hypothesis wanted.
const SHORTLIST_PER_HYPOTHESIS: usize = 30;
/// Sorting and thinning the shortlist costs about this many field evaluations per entry.
const SELECT_COST: usize = 10;

/// The likelihood table spans this many field widths (beyond: the uniform floor alone) ...
const LIKELIHOOD_SPAN: f64 = 5.0;
/// ... in this many steps.
const LIKELIHOOD_STEPS: usize = 100;

/// Tempered log-likelihood of a point at each tabulated distance from the map: a Gaussian of the
/// field width mixed with a uniform floor, so points on things not on the map cost little.
fn likelihood_table(config: &GlobalConfig) -> Vec<f64> {
    (0..=LIKELIHOOD_STEPS)
        .map(|k| {
            let d = if k == LIKELIHOOD_STEPS {
                f64::INFINITY
            } else {
                (k as f64 + 0.5) * LIKELIHOOD_SPAN / LIKELIHOOD_STEPS as f64
            };
            ((-0.5 * d * d).exp() + 0.05).ln() * config.tempering
        })
        .collect()
}

/// The likelihood field: each cell of the map's distance grid holds the table's
/// log-likelihood at its distance, so that scoring a grid pose costs one look-up and one add
/// per point, with no rotation and no distance conversion per point (the grid search's inner
/// loop, run millions of times per search).
#[derive(Debug, Clone)]
struct Field {
    min: Point2<f64>,
    cell: f64,
    cols: usize,
    rows: usize,
    log_likelihood: Vec<f32>,
    /// Off the grid, where the map's distance is its reach.
    outside: f32,
}

impl Field {
    fn new(map: &LocalizationMap, config: &GlobalConfig, table: &[f64]) -> Self {
        let (min, cell, cols, rows) = map.field_grid();
        let per_step = LIKELIHOOD_STEPS as f64 / (LIKELIHOOD_SPAN * config.sigma_m);
        let at = |d: f64| table[((d * per_step) as usize).min(LIKELIHOOD_STEPS)] as f32;
        let log_likelihood = (0..rows)
            .flat_map(|r| (0..cols).map(move |c| (c, r)))
            .map(|(c, r)| {
                at(map.field_distance(
                    min.x + (c as f64 + 0.5) * cell,
                    min.y + (r as f64 + 0.5) * cell,
                ))
            })
            .collect();
        Field {
            min,
            cell,
            cols,
            rows,
            log_likelihood,
            outside: at(map.reach_m()),
        }
    }

    /// The map point of the grid corner `(c, r)`.
    fn corner(&self, (c, r): (i32, i32)) -> Point2<f64> {
        Point2::new(
            self.min.x + self.cell * f64::from(c),
            self.min.y + self.cell * f64::from(r),
        )
    }

    /// The cells of `scan`'s points, relative to the corner a base at heading `theta` stands
    /// on: a point `p` falls in the corner's cell plus `floor(R(theta) p / cell)`.
    fn offsets(&self, scan: &[ScanPoint], theta: f64) -> Vec<(i32, i32)> {
        let (sin, cos) = theta.sin_cos();
        scan.iter()
            .map(|s| {
                let (x, y) = (s.p_base.x, s.p_base.y);
                (
                    ((cos * x - sin * y) / self.cell).floor() as i32,
                    ((sin * x + cos * y) / self.cell).floor() as i32,
                )
            })
            .collect()
    }

    /// Log-likelihood of the scan whose [`Self::offsets`] are `offsets` for a base on the
    /// corner `(c, r)`: what [`GlobalLocalizer::evaluate`] gives at that pose.
    fn score(&self, (c, r): (i32, i32), offsets: &[(i32, i32)]) -> f64 {
        let mut log_w = 0.0;
        for &(dc, dr) in offsets {
            let (pc, pr) = (c + dc, r + dr);
            let v = if pc >= 0 && pr >= 0 && (pc as usize) < self.cols && (pr as usize) < self.rows
            {
                self.log_likelihood[pr as usize * self.cols + pc as usize]
            } else {
                self.outside
            };
            log_w += f64::from(v);
        }
        log_w
    }
}

fn subsample(points: &[ScanPoint], n: usize) -> Vec<ScanPoint> {
    if points.len() <= n {
        return points.to_vec();
    }
    (0..n).map(|k| points[k * points.len() / n]).collect()
}

/// Free grid positions: distance-grid corners every grid step, starting half a step in,
/// at least the clearance from the map.
fn free_positions(map: &LocalizationMap, field: &Field, config: &GlobalConfig) -> Vec<(i32, i32)> {
    let (_, hi) = map.bounds();
    let stride = ((config.grid_step_m / field.cell).round() as i32).max(1);
    let mut positions = Vec::new();
    let mut r = stride / 2;
    while field.corner((0, r)).y < hi.y {
        let mut c = stride / 2;
        while field.corner((c, r)).x < hi.x {
            let p = field.corner((c, r));
            if map.field_distance(p.x, p.y) >= config.clearance_m {
                positions.push((c, r));
            }
            c += stride;
        }
        r += stride;
    }
    positions
}

impl GlobalLocalizer {
    /// Starts a search with `points`, the scan of this period: nothing is evaluated yet, the
    /// grid search runs in [`Self::step`].
    pub fn start(
        map: &LocalizationMap,
        points: &[ScanPoint],
        config: GlobalConfig,
        matcher: MatcherConfig,
    ) -> Self {
        let log_likelihood = likelihood_table(&config);
        let mut search = GlobalLocalizer {
            config,
            matcher: MatcherConfig {
                iterations: config.refine_iterations.max(1),
                ..matcher
            },
            field: Field::new(map, &config, &log_likelihood),
            log_likelihood,
            phase: Phase::Idle,
            scan: Vec::new(),
            since: Pose2::default(),
            travel: (0.0, 0.0),
            hypotheses: Vec::new(),
            updates: 0,
            poor_in_row: 0,
        };
        search.restart(map, points);
        search
    }

    fn restart(&mut self, map: &LocalizationMap, points: &[ScanPoint]) {
        self.scan = subsample(points, self.config.points);
        self.since = Pose2::default();
        self.travel = (0.0, 0.0);
        self.hypotheses.clear();
        self.updates = 0;
        self.poor_in_row = 0;
        self.phase = Phase::Grid {
            positions: free_positions(map, &self.field, &self.config),
            next: 0,
            best: BinaryHeap::new(),
            heading: 0,
            offsets: self.field.offsets(&self.scan, 0.0),
        };
    }

    /// Moves every hypothesis by one odometry step.
    pub fn predict(&mut self, step: &OdometryStep) {
        self.since = self.since.compose(&step.as_delta());
        self.travel.0 += step.trans.abs();
        self.travel.1 += (step.rot1 + step.rot2).abs();
    }

    /// Does at most [`GlobalConfig::work_per_step`] point evaluations of the search with this
    /// period's scan `points`. Returns whether a round of hypothesis updates completed (then
    /// [`Self::leader`] has news).
    pub fn step(&mut self, map: &LocalizationMap, points: &[ScanPoint]) -> bool {
        let full = self.config.work_per_step.max(1);
        let mut budget = full;
        // a budget smaller than one item still does one item a call: the search always ends
        let may =
            |budget: usize, cost: usize, first: bool| budget >= cost || (first && budget == full);
        loop {
            match &mut self.phase {
                Phase::Idle => {
                    let (every_m, every_rad) = self.config.update_every;
                    if (self.travel.0 < every_m && self.travel.1 < every_rad)
                        || points.len() < self.matcher.min_points
                    {
                        return false;
                    }
                    for h in &mut self.hypotheses {
                        h.pose = h.pose.compose(&self.since);
                    }
                    self.scan = subsample(points, self.config.points);
                    self.since = Pose2::default();
                    self.travel = (0.0, 0.0);
                    self.phase = Phase::Update { next: 0 };
                }
                Phase::Grid {
                    positions,
                    next,
                    best,
                    heading,
                    offsets,
                } => {
                    let total = positions.len() * self.config.headings.max(1);
                    let cost = self.scan.len().max(1);
                    // the candidates for distinct modes lie among the best few percent
                    let shortlist = self.config.hypotheses.max(1) * SHORTLIST_PER_HYPOTHESIS;
                    let (positions, mut best, mut at, mut heading, mut offsets) = (
                        std::mem::take(positions),
                        std::mem::take(best),
                        *next,
                        *heading,
                        std::mem::take(offsets),
                    );
                    let first = at;
                    while at < total && may(budget, cost, at == first) {
                        if at / positions.len() != heading {
                            heading = at / positions.len();
                            offsets = self.field.offsets(&self.scan, self.heading(heading));
                        }
                        let score = self.field.score(positions[at % positions.len()], &offsets);
                        if best.len() < shortlist {
                            best.push(Reverse(Scored { score, index: at }));
                        } else if best.peek().is_some_and(|worst| score > worst.0.score) {
                            best.pop();
                            best.push(Reverse(Scored { score, index: at }));
                        }
                        at += 1;
                        budget = budget.saturating_sub(cost);
                    }
                    if at < total {
                        self.phase = Phase::Grid {
                            positions,
                            next: at,
                            best,
                            heading,
                            offsets,
                        };
                        return false;
                    }
                    budget = budget.saturating_sub(shortlist * SELECT_COST);
                    self.hypotheses = self.distinct_best(&positions, best);
                    self.phase = Phase::Update { next: 0 };
                }
                Phase::Update { next } => {
                    let cost =
                        self.scan.len().max(1) * (self.matcher.iterations * MATCH_POINT_COST + 1);
                    let (first, mut at) = (*next, *next);
                    while at < self.hypotheses.len() && may(budget, cost, at == first) {
                        self.refine(map, at);
                        at += 1;
                        budget = budget.saturating_sub(cost);
                    }
                    if at < self.hypotheses.len() {
                        self.phase = Phase::Update { next: at };
                        return false;
                    }
                    self.end_round(map, points);
                    return true;
                }
            }
        }
    }

    /// Heading number `h` of the grid, rad.
    fn heading(&self, h: usize) -> f64 {
        wrap_angle(std::f64::consts::TAU * h as f64 / self.config.headings.max(1) as f64)
    }

    fn grid_pose(&self, positions: &[(i32, i32)], index: usize) -> Pose2 {
        let p = self.field.corner(positions[index % positions.len()]);
        Pose2::new(p.x, p.y, self.heading(index / positions.len()))
    }

    /// Log-likelihood of the current scan at `pose`, and the share of its points near the map
    /// (within two field widths). The inner loop of the search: one rotation per pose, a table
    /// look-up per point.
    fn evaluate(&self, map: &LocalizationMap, pose: &Pose2) -> (f64, f64) {
        let (sin, cos) = pose.theta.sin_cos();
        let per_step = LIKELIHOOD_STEPS as f64 / (LIKELIHOOD_SPAN * self.config.sigma_m);
        let (mut log_w, mut near) = (0.0, 0usize);
        for s in &self.scan {
            let (x, y) = (s.p_base.x, s.p_base.y);
            let d = map.field_distance(pose.x + cos * x - sin * y, pose.y + sin * x + cos * y);
            let k = ((d * per_step) as usize).min(LIKELIHOOD_STEPS);
            log_w += self.log_likelihood[k];
            near += usize::from(d <= 2.0 * self.config.sigma_m);
        }
        (log_w, near as f64 / self.scan.len().max(1) as f64)
    }

    /// The best-scoring grid poses, pairwise at least [`GlobalConfig::separation`] apart.
    fn distinct_best(
        &self,
        positions: &[(i32, i32)],
        best: BinaryHeap<Reverse<Scored>>,
    ) -> Vec<Hypothesis> {
        // ascending by Reverse: best score first
        let order = best.into_sorted_vec();
        let (sep_m, sep_rad) = self.config.separation;
        let mut chosen: Vec<Hypothesis> = Vec::with_capacity(self.config.hypotheses);
        for Reverse(candidate) in order {
            if chosen.len() >= self.config.hypotheses {
                break;
            }
            let pose = self.grid_pose(positions, candidate.index);
            let distinct = chosen.iter().all(|c| {
                (c.pose.x - pose.x).powi(2) + (c.pose.y - pose.y).powi(2) >= sep_m * sep_m
                    || wrap_angle(c.pose.theta - pose.theta).abs() >= sep_rad
            });
            if distinct {
                chosen.push(Hypothesis {
                    pose,
                    log_w: 0.0,
                    fit: 0.0,
                });
            }
        }
        chosen
    }

    /// Pulls hypothesis `i` onto the map with the current scan and credits its likelihood.
    fn refine(&mut self, map: &LocalizationMap, i: usize) {
        let guess = self.hypotheses[i].pose;
        let pose = match_scan(map, &self.scan, &guess, &self.matcher)
            .map(|m| m.pose)
            // a match that ran off is no refinement
            .filter(|p| (p.x - guess.x).hypot(p.y - guess.y) < 0.5)
            .unwrap_or(guess);
        let (log_w, fit) = self.evaluate(map, &pose);
        let h = &mut self.hypotheses[i];
        h.pose = pose;
        h.log_w += log_w;
        h.fit = fit;
    }

    /// After every hypothesis has seen the scan: merge, prune, and start afresh when even the
    /// best explains the scans poorly.
    fn end_round(&mut self, map: &LocalizationMap, points: &[ScanPoint]) {
        self.updates += 1;
        self.phase = Phase::Idle;
        self.hypotheses
            .sort_unstable_by(|a, b| b.log_w.total_cmp(&a.log_w));
        let best = self.hypotheses.first().map_or(0.0, |h| h.log_w);
        let (merge_m, merge_rad) = self.config.merge;
        let mut kept: Vec<Hypothesis> = Vec::with_capacity(self.hypotheses.len());
        for h in &self.hypotheses {
            let duplicate = kept.iter().any(|k| {
                (k.pose.x - h.pose.x).hypot(k.pose.y - h.pose.y) < merge_m
                    && wrap_angle(k.pose.theta - h.pose.theta).abs() < merge_rad
            });
            if !duplicate && h.log_w - best >= -self.config.prune_margin {
                kept.push(Hypothesis {
                    log_w: h.log_w - best,
                    ..*h
                });
            }
        }
        self.hypotheses = kept;
        let poor = self
            .hypotheses
            .first()
            .is_none_or(|h| h.fit < self.config.poor_fit);
        self.poor_in_row = if poor { self.poor_in_row + 1 } else { 0 };
        if self.poor_in_row >= self.config.poor_after && points.len() >= self.matcher.min_points {
            tracing::debug!("no hypothesis explains the scans: the search starts afresh");
            self.restart(map, points);
        }
    }

    /// The leading hypothesis's current pose and its lead (log-likelihood ratio) over the
    /// next; infinite when it is the only one. `None` before the grid search is done.
    pub fn leader(&self) -> Option<(Pose2, f64)> {
        if matches!(self.phase, Phase::Grid { .. }) {
            return None;
        }
        let best = self.hypotheses.first()?;
        let lead = self
            .hypotheses
            .get(1)
            .map_or(f64::INFINITY, |second| best.log_w - second.log_w);
        Some((best.pose.compose(&self.since), lead))
    }

    /// Mean and covariance of the hypotheses, each weighed by its likelihood; `None` before
    /// the grid search is done.
    pub fn estimate(&self) -> Option<(Pose2, Matrix3<f64>)> {
        if matches!(self.phase, Phase::Grid { .. }) || self.hypotheses.is_empty() {
            return None;
        }
        let best = self
            .hypotheses
            .iter()
            .map(|h| h.log_w)
            .fold(f64::NEG_INFINITY, f64::max);
        let poses: Vec<(Pose2, f64)> = self
            .hypotheses
            .iter()
            .map(|h| (h.pose.compose(&self.since), (h.log_w - best).exp()))
            .collect();
        let total: f64 = poses.iter().map(|(_, w)| w).sum();
        let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
        for (p, w) in &poses {
            x += w * p.x;
            y += w * p.y;
            s += w * p.theta.sin();
            c += w * p.theta.cos();
        }
        let mean = Pose2::new(x / total, y / total, s.atan2(c));
        let mut cov = Matrix3::zeros();
        for (p, w) in &poses {
            let d = Vector3::new(p.x - mean.x, p.y - mean.y, wrap_angle(p.theta - mean.theta));
            cov += d * d.transpose() * (w / total);
        }
        Some((mean, cov))
    }

    /// Rounds of hypothesis updates since the search (re)started.
    pub fn updates(&self) -> usize {
        self.updates
    }

    /// Hypotheses alive (0 while the grid search runs).
    pub fn len(&self) -> usize {
        self.hypotheses.len()
    }

    /// Whether there are no hypotheses (the grid search runs, or the map has no free space).
    pub fn is_empty(&self) -> bool {
        self.hypotheses.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid's look-up score is the per-point evaluation at the grid pose (up to the
    /// field's f32 rounding), at every grid pose of a small room.
    #[test]
    fn the_grid_scores_by_look_up_what_the_evaluation_gives() {
        let corners = [(0.0, 0.0), (6.0, 0.0), (6.0, 3.0), (2.5, 5.0), (0.0, 4.0)];
        let segments = (0..corners.len())
            .map(|i| {
                let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
                (Point2::new(a.0, a.1), Point2::new(b.0, b.1))
            })
            .collect();
        let map = LocalizationMap::new(segments, vec![], 1.0).expect("map");
        let points: Vec<ScanPoint> = (0..60)
            .map(|k| {
                // off the cells' boundaries at every heading (on one, either cell is right)
                let (a, r) = (f64::from(k) * 0.37 + 0.011, 0.503 + f64::from(k % 7) * 0.61);
                ScanPoint {
                    p_base: Point2::new(r * a.cos(), r * a.sin()),
                    sigma_m: 0.02,
                    beam_base: nalgebra::Vector2::new(a.cos(), a.sin()),
                }
            })
            .collect();
        let config = GlobalConfig::default();
        let search = GlobalLocalizer::start(&map, &points, config, MatcherConfig::default());
        let Phase::Grid { positions, .. } = &search.phase else {
            panic!("a new search starts with the grid")
        };
        assert!(positions.len() > 200, "{} free positions", positions.len());
        for h in 0..config.headings {
            let offsets = search.field.offsets(&search.scan, search.heading(h));
            for (i, &corner) in positions.iter().enumerate() {
                let pose = search.grid_pose(positions, h * positions.len() + i);
                let (exact, fast) = (
                    search.evaluate(&map, &pose).0,
                    search.field.score(corner, &offsets),
                );
                assert!((exact - fast).abs() < 1e-4, "{pose:?}: {exact} != {fast}");
            }
        }
    }
}
