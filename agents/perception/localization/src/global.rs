//! Global localization from an unknown start: a particle filter (Monte Carlo localization)
//! seeded by an exhaustive correlative search over the free space, updated with the laser and
//! sonars on the map's distance grid while the chair drives.

use nalgebra::{Matrix3, Point2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::map::LocalizationMap;
use crate::scan::{ScanPoint, to_map};
use iw_vo::{OdometryStep, Pose2, wrap_angle};

/// How the particle filter searches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalConfig {
    /// Particles kept (the best-scoring poses of the search, then resampled).
    pub particles: usize,
    /// Spacing of the search grid, m.
    pub grid_step_m: f64,
    /// Headings tried at each grid point.
    pub headings: usize,
    /// Poses closer than this to the map are not where a chair can stand, m.
    pub clearance_m: f64,
    /// Scan points used per likelihood (evenly subsampled).
    pub points: usize,
    /// Likelihood field width, m.
    pub sigma_m: f64,
    /// Each point's log-likelihood counts this much (neighbouring beams are not independent).
    pub tempering: f64,
    /// Update after this much travel, m, or this much turn, rad.
    pub update_every: (f64, f64),
    /// Odometry noise is this many times the motion model's.
    pub motion_noise_scale: f64,
}

impl Default for GlobalConfig {
    fn default() -> Self {
        GlobalConfig {
            particles: 3000,
            grid_step_m: 0.2,
            headings: 36,
            clearance_m: 0.3,
            points: 48,
            sigma_m: 0.1,
            tempering: 0.25,
            update_every: (0.05, 0.05),
            motion_noise_scale: 2.0,
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Particle {
    pose: Pose2,
    log_w: f64,
}

/// The particle filter.
#[derive(Debug, Clone)]
pub struct GlobalLocalizer {
    config: GlobalConfig,
    alpha: [f64; 4],
    particles: Vec<Particle>,
    rng: ChaCha8Rng,
    since_update: (f64, f64),
    updates: usize,
}

fn subsample(points: &[ScanPoint], n: usize) -> Vec<ScanPoint> {
    if points.len() <= n {
        return points.to_vec();
    }
    (0..n).map(|k| points[k * points.len() / n]).collect()
}

/// Scores every free pose of the search grid (tempered log-likelihood of `sample`).
fn score_grid(map: &LocalizationMap, sample: &[ScanPoint], config: &GlobalConfig) -> Vec<Particle> {
    let (lo, hi) = map.bounds();
    let step = config.grid_step_m.max(0.02);
    let headings = config.headings.max(1);
    let mut positions = Vec::new();
    let mut y = lo.y + step / 2.0;
    while y < hi.y {
        let mut x = lo.x + step / 2.0;
        while x < hi.x {
            if map.field_distance(x, y) >= config.clearance_m {
                positions.push(Point2::new(x, y));
            }
            x += step;
        }
        y += step;
    }
    let mut scored: Vec<Particle> = Vec::with_capacity(positions.len() * headings);
    for h in 0..headings {
        let theta = wrap_angle(std::f64::consts::TAU * h as f64 / headings as f64);
        let rotated: Vec<Point2<f64>> = sample
            .iter()
            .map(|p| to_map(&Pose2::new(0.0, 0.0, theta), &p.p_base))
            .collect();
        for c in &positions {
            let log_w = rotated
                .iter()
                .map(|q| GlobalLocalizer::log_likelihood(map, c.x + q.x, c.y + q.y, config))
                .sum::<f64>();
            scored.push(Particle {
                pose: Pose2::new(c.x, c.y, theta),
                log_w,
            });
        }
    }
    scored
}

impl GlobalLocalizer {
    /// Starts a search with the first scan: scores every free pose on the grid and keeps the
    /// best [`GlobalConfig::particles`]. `alpha` is the odometry motion model.
    pub fn start(
        map: &LocalizationMap,
        points: &[ScanPoint],
        config: GlobalConfig,
        alpha: [f64; 4],
        seed: u64,
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let sample = subsample(points, config.points);
        let step = config.grid_step_m.max(0.02);
        let headings = config.headings.max(1);
        let mut scored = score_grid(map, &sample, &config);
        let keep = config.particles.max(1).min(scored.len());
        if keep < scored.len() {
            scored.select_nth_unstable_by(keep, |a, b| b.log_w.total_cmp(&a.log_w));
            scored.truncate(keep);
        }
        let half_heading = std::f64::consts::PI / headings as f64;
        let particles = scored
            .into_iter()
            .map(|p| Particle {
                pose: Pose2::new(
                    p.pose.x + rng.random_range(-step / 2.0..step / 2.0),
                    p.pose.y + rng.random_range(-step / 2.0..step / 2.0),
                    p.pose.theta + rng.random_range(-half_heading..half_heading),
                ),
                log_w: 0.0,
            })
            .collect();
        let mut filter = GlobalLocalizer {
            config,
            alpha,
            particles,
            rng,
            since_update: (0.0, 0.0),
            updates: 0,
        };
        filter.weigh(map, &sample);
        filter
    }

    /// The `k` best grid poses for `points` that lie at least `away_m` from `pose` and from each
    /// other: where else the chair could be, by this scan alone.
    pub fn alternatives(
        map: &LocalizationMap,
        points: &[ScanPoint],
        config: &GlobalConfig,
        pose: &Pose2,
        away_m: f64,
        k: usize,
    ) -> Vec<Pose2> {
        let sample = subsample(points, config.points);
        // twice the headings of the search: a twin 5 degrees off its grid heading still scores
        let fine = GlobalConfig {
            headings: config.headings * 2,
            ..*config
        };
        let mut scored = score_grid(map, &sample, &fine);
        scored.sort_unstable_by(|a, b| b.log_w.total_cmp(&a.log_w));
        let far = |a: &Pose2, b: &Pose2| (a.x - b.x).hypot(a.y - b.y) >= away_m;
        let mut chosen: Vec<Pose2> = Vec::with_capacity(k);
        for p in scored {
            if chosen.len() >= k {
                break;
            }
            if far(&p.pose, pose) && chosen.iter().all(|c| far(&p.pose, c)) {
                chosen.push(p.pose);
            }
        }
        chosen
    }

    fn log_likelihood(map: &LocalizationMap, x: f64, y: f64, config: &GlobalConfig) -> f64 {
        let d = map.field_distance(x, y);
        // a mixture with a uniform floor: points on things that are not on the map cost little
        (((-0.5 * (d / config.sigma_m).powi(2)).exp() + 0.05).ln()) * config.tempering
    }

    fn weigh(&mut self, map: &LocalizationMap, sample: &[ScanPoint]) {
        for p in &mut self.particles {
            p.log_w += sample
                .iter()
                .map(|s| {
                    let q = to_map(&p.pose, &s.p_base);
                    Self::log_likelihood(map, q.x, q.y, &self.config)
                })
                .sum::<f64>();
        }
        let max = self
            .particles
            .iter()
            .map(|p| p.log_w)
            .fold(f64::NEG_INFINITY, f64::max);
        for p in &mut self.particles {
            p.log_w -= max;
        }
        self.updates += 1;
    }

    /// Moves every particle by one odometry step with sampled noise.
    pub fn predict(&mut self, step: &OdometryStep) {
        let cov = step.covariance(&self.alpha) * self.config.motion_noise_scale.powi(2);
        for p in &mut self.particles {
            let noisy = OdometryStep {
                rot1: step.rot1 + iw_stats::standard_normal(&mut self.rng) * cov[(0, 0)].sqrt(),
                trans: step.trans + iw_stats::standard_normal(&mut self.rng) * cov[(1, 1)].sqrt(),
                rot2: step.rot2 + iw_stats::standard_normal(&mut self.rng) * cov[(2, 2)].sqrt(),
            };
            p.pose = p.pose.compose(&noisy.as_delta());
        }
        self.since_update.0 += step.trans.abs();
        self.since_update.1 += (step.rot1 + step.rot2).abs();
    }

    /// Weighs the particles with a scan once the chair has moved enough since the last one, and
    /// resamples when the weights have degenerated. Returns whether it weighed.
    pub fn update(&mut self, map: &LocalizationMap, points: &[ScanPoint]) -> bool {
        if self.since_update.0 < self.config.update_every.0
            && self.since_update.1 < self.config.update_every.1
        {
            return false;
        }
        self.since_update = (0.0, 0.0);
        let sample = subsample(points, self.config.points);
        if sample.is_empty() {
            return false;
        }
        self.weigh(map, &sample);
        let weights: Vec<f64> = self.particles.iter().map(|p| p.log_w.exp()).collect();
        let total: f64 = weights.iter().sum();
        let n_eff = total * total / weights.iter().map(|w| w * w).sum::<f64>();
        if n_eff < self.particles.len() as f64 / 2.0 {
            self.resample(&weights, total);
        }
        true
    }

    /// Low-variance resampling with a little roughening against depletion.
    fn resample(&mut self, weights: &[f64], total: f64) {
        let n = self.particles.len();
        let stride = total / n as f64;
        let mut target = self.rng.random_range(0.0..stride);
        let (mut acc, mut i) = (weights[0], 0);
        let mut next = Vec::with_capacity(n);
        for _ in 0..n {
            while acc < target && i + 1 < n {
                i += 1;
                acc += weights[i];
            }
            let pose = self.particles[i].pose;
            next.push(Particle {
                pose: Pose2::new(
                    pose.x + iw_stats::standard_normal(&mut self.rng) * 0.01,
                    pose.y + iw_stats::standard_normal(&mut self.rng) * 0.01,
                    pose.theta + iw_stats::standard_normal(&mut self.rng) * 0.005,
                ),
                log_w: 0.0,
            });
            target += stride;
        }
        self.particles = next;
    }

    /// Weighted mean and covariance of the particles.
    pub fn estimate(&self) -> (Pose2, Matrix3<f64>) {
        let weights: Vec<f64> = self.particles.iter().map(|p| p.log_w.exp()).collect();
        let total: f64 = weights.iter().sum::<f64>().max(f64::MIN_POSITIVE);
        let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
        for (p, w) in self.particles.iter().zip(&weights) {
            x += w * p.pose.x;
            y += w * p.pose.y;
            s += w * p.pose.theta.sin();
            c += w * p.pose.theta.cos();
        }
        let mean = Pose2::new(x / total, y / total, s.atan2(c));
        let mut cov = Matrix3::zeros();
        for (p, w) in self.particles.iter().zip(&weights) {
            let d = nalgebra::Vector3::new(
                p.pose.x - mean.x,
                p.pose.y - mean.y,
                wrap_angle(p.pose.theta - mean.theta),
            );
            cov += d * d.transpose() * (w / total);
        }
        (mean, cov)
    }

    /// Scans weighed so far (the first at the start).
    pub fn updates(&self) -> usize {
        self.updates
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.particles.len()
    }

    /// Whether there are no particles (a map with no free space).
    pub fn is_empty(&self) -> bool {
        self.particles.is_empty()
    }
}
