//! `summary.json` and the pictures.

use std::path::Path;

use iw_plot::paths::{Outline, PathFigure, PathSeries, plot_paths};
use iw_plot::plotters::prelude::*;
use iw_sim::Map;
use iw_stats::{Alternative, Wilcoxon, wilcoxon_signed_rank};

use crate::{Config, ExperimentError, Mode, Report, Trial};

/// Totals of one paradigm over all drivers.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ModeSummary {
    /// Collision events (one per new contact), all drivers and laps.
    pub collisions: u64,
    /// Collisions per lap attempted (a lap abandoned on the timeout counts as attempted).
    pub collisions_per_lap: f64,
    /// Collisions per finished lap (`null` when no lap was finished).
    pub collisions_per_completed_lap: Option<f64>,
    /// Collisions of each driver.
    pub collisions_per_driver: Vec<u64>,
    /// Collisions per lap attempted, each driver: the paired samples of the Wilcoxon tests (in
    /// the thesis's protocol, one lap, the collisions of each trial).
    pub collisions_per_lap_per_driver: Vec<f64>,
    /// Collisions per 100 m driven, all drivers.
    pub collisions_per_100m: f64,
    /// Laps finished, all drivers.
    pub laps_completed: usize,
    /// Laps asked for, all drivers.
    pub laps_attempted: usize,
    /// `laps_completed / laps_attempted`.
    pub completion_rate: f64,
    /// Trials abandoned on the lap timeout.
    pub trials_timed_out: usize,
    /// Mean time of a finished lap, s.
    pub mean_lap_time_s: Option<f64>,
    /// Ground distance over time driven, all drivers, m/s.
    pub mean_speed_mps: f64,
    /// Fraction of periods in which the command reaching the wheels differed from the user's.
    pub intervention_rate: f64,
    /// Same, over periods with the footprint near an obstacle.
    pub intervention_rate_near: f64,
    /// Same, over periods in free space.
    pub intervention_rate_free: f64,
    /// Mean wheel-speed change of a changed period, m/s.
    pub mean_intervention_mps: f64,
    /// Fraction of periods spent near obstacles.
    pub near_fraction: f64,
    /// Smallest footprint clearance over all trials, m.
    pub min_clearance_m: f64,
    /// Ground distance driven, all drivers, m.
    pub distance_m: f64,
}

/// One paired comparison, first paradigm against second.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// Relative reduction of collisions per lap, 1 - second / first (`null` if first had none).
    pub collision_reduction: Option<f64>,
    /// Wilcoxon signed-rank on collisions per lap, one-tailed (first has more), paired per driver:
    /// `t` is the thesis's T, `p_exact` and `p_normal` its two p values.
    pub wilcoxon: Wilcoxon,
    /// Mean finished-lap time of the second over the first (`null` without finished laps).
    pub lap_time_ratio: Option<f64>,
}

/// The task-success target for the control agent's policy: at least 95 % of laps finished, at
/// most 0.05 collisions per lap, at most 1.5 times the manual lap time.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TaskSuccess {
    /// Completion rate at least 0.95.
    pub completes: bool,
    /// Collisions per lap at most 0.05.
    pub safe: bool,
    /// Mean lap time at most 1.5 x manual.
    pub timely: bool,
    /// All three.
    pub met: bool,
}

/// The contract shape of `summary.json`, plus details.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Manual driving.
    pub manual: ModeSummary,
    /// The thesis's potential field as a joystick filter.
    pub shared: ModeSummary,
    /// The same equations through the arc-chord mapping.
    pub shared_chord: ModeSummary,
    /// VFH+ shared control.
    pub vfh: ModeSummary,
    /// The control agent's policy: the arc guard.
    pub guarded: ModeSummary,
    /// One-tailed Wilcoxon signed-rank p, manual > shared collisions per lap, paired per driver
    /// (exact when computable, as [`Wilcoxon::p`]).
    pub wilcoxon_p: f64,
    /// The same test's T (the thesis reports T = 0, p = 0.009 in its simulator).
    pub wilcoxon_t: f64,
    /// The same test's normal-approximation p.
    pub wilcoxon_p_normal: f64,
    /// Manual vs shared.
    pub manual_vs_shared: Comparison,
    /// Manual vs the arc-chord variant.
    pub manual_vs_shared_chord: Comparison,
    /// Manual vs VFH+.
    pub manual_vs_vfh: Comparison,
    /// Manual vs the guarded policy.
    pub manual_vs_guarded: Comparison,
    /// VFH+ vs shared.
    pub vfh_vs_shared: Comparison,
    /// VFH+ vs the guarded policy.
    pub vfh_vs_guarded: Comparison,
    /// The guarded policy against the task-success target.
    pub guarded_task: TaskSuccess,
    /// Map driven.
    pub map: String,
    /// Configuration.
    pub config: Config,
}

fn mode_summary(trials: &[&Trial], laps_per_trial: usize) -> ModeSummary {
    let sum = |f: &dyn Fn(&Trial) -> u64| trials.iter().map(|t| f(t)).sum::<u64>();
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    let collisions = sum(&|t| t.collisions);
    let laps_completed: usize = trials.iter().map(|t| t.laps_completed).sum();
    let laps_attempted = trials.len() * laps_per_trial;
    let lap_times: Vec<f64> = trials
        .iter()
        .flat_map(|t| t.lap_times_s.iter().copied())
        .collect();
    let periods = sum(&|t| t.periods) as f64;
    let near = sum(&|t| t.periods_near) as f64;
    let changed_near = sum(&|t| t.changed_near) as f64;
    let changed_free = sum(&|t| t.changed_free) as f64;
    let changed = changed_near + changed_free;
    let distance_m: f64 = trials.iter().map(|t| t.distance_m).sum();
    ModeSummary {
        collisions,
        collisions_per_lap: ratio(collisions as f64, laps_attempted as f64),
        collisions_per_completed_lap: (laps_completed > 0)
            .then(|| collisions as f64 / laps_completed as f64),
        collisions_per_driver: trials.iter().map(|t| t.collisions).collect(),
        collisions_per_lap_per_driver: trials
            .iter()
            .map(|t| t.collisions as f64 / laps_per_trial.max(1) as f64)
            .collect(),
        collisions_per_100m: ratio(100.0 * collisions as f64, distance_m),
        laps_completed,
        laps_attempted,
        completion_rate: ratio(laps_completed as f64, laps_attempted as f64),
        trials_timed_out: trials.iter().filter(|t| t.timed_out).count(),
        mean_lap_time_s: (!lap_times.is_empty())
            .then(|| lap_times.iter().sum::<f64>() / lap_times.len() as f64),
        mean_speed_mps: ratio(distance_m, trials.iter().map(|t| t.duration_s).sum()),
        intervention_rate: ratio(changed, periods),
        intervention_rate_near: ratio(changed_near, near),
        intervention_rate_free: ratio(changed_free, periods - near),
        mean_intervention_mps: ratio(trials.iter().map(|t| t.change_sum_mps).sum(), changed),
        near_fraction: ratio(near, periods),
        min_clearance_m: trials
            .iter()
            .map(|t| t.min_clearance_m)
            .fold(f64::INFINITY, f64::min),
        distance_m,
    }
}

/// `first` against `second`, paired per driver.
pub(crate) fn compare(
    first: &ModeSummary,
    second: &ModeSummary,
) -> Result<Comparison, ExperimentError> {
    Ok(Comparison {
        collision_reduction: (first.collisions_per_lap > 0.0)
            .then(|| 1.0 - second.collisions_per_lap / first.collisions_per_lap),
        wilcoxon: wilcoxon_signed_rank(
            &first.collisions_per_lap_per_driver,
            &second.collisions_per_lap_per_driver,
            Alternative::Greater,
        )?,
        lap_time_ratio: first
            .mean_lap_time_s
            .zip(second.mean_lap_time_s)
            .map(|(a, b)| b / a),
    })
}

impl TaskSuccess {
    fn of(policy: &ModeSummary, against_manual: &Comparison) -> Self {
        let completes = policy.completion_rate >= 0.95;
        let safe = policy.collisions_per_lap <= 0.05;
        let timely = against_manual.lap_time_ratio.is_some_and(|r| r <= 1.5);
        TaskSuccess {
            completes,
            safe,
            timely,
            met: completes && safe && timely,
        }
    }
}

impl Summary {
    /// The totals of one paradigm.
    pub fn mode(&self, mode: Mode) -> &ModeSummary {
        match mode {
            Mode::Manual => &self.manual,
            Mode::Shared => &self.shared,
            Mode::SharedChord => &self.shared_chord,
            Mode::Vfh => &self.vfh,
            Mode::Guarded => &self.guarded,
        }
    }

    /// Aggregates a report that has every paradigm of [`Mode::ALL`].
    pub fn from_report(report: &Report) -> Result<Summary, ExperimentError> {
        let of = |mode: Mode| {
            let trials = report.trials_of(mode);
            if trials.is_empty() {
                return Err(ExperimentError::MissingMode { mode: mode.key() });
            }
            Ok(mode_summary(&trials, report.config.laps))
        };
        let (manual, shared, shared_chord, vfh, guarded) = (
            of(Mode::Manual)?,
            of(Mode::Shared)?,
            of(Mode::SharedChord)?,
            of(Mode::Vfh)?,
            of(Mode::Guarded)?,
        );
        let manual_vs_shared = compare(&manual, &shared)?;
        let manual_vs_guarded = compare(&manual, &guarded)?;
        Ok(Summary {
            wilcoxon_p: manual_vs_shared.wilcoxon.p(),
            wilcoxon_t: manual_vs_shared.wilcoxon.t,
            wilcoxon_p_normal: manual_vs_shared.wilcoxon.p_normal,
            manual_vs_shared_chord: compare(&manual, &shared_chord)?,
            manual_vs_vfh: compare(&manual, &vfh)?,
            vfh_vs_shared: compare(&vfh, &shared)?,
            vfh_vs_guarded: compare(&vfh, &guarded)?,
            guarded_task: TaskSuccess::of(&guarded, &manual_vs_guarded),
            manual_vs_guarded,
            manual_vs_shared,
            manual,
            shared,
            shared_chord,
            vfh,
            guarded,
            map: report.map_name.clone(),
            config: report.config.clone(),
        })
    }
}

/// The summary of one paradigm's trials in `report` (for runs of a subset of modes).
pub(crate) fn summary_of(report: &Report, mode: Mode) -> Result<ModeSummary, ExperimentError> {
    let trials = report.trials_of(mode);
    if trials.is_empty() {
        return Err(ExperimentError::MissingMode { mode: mode.key() });
    }
    Ok(mode_summary(&trials, report.config.laps))
}

fn map_outlines(map: &Map) -> Vec<Outline> {
    let xy = |p: &nalgebra::Point2<f64>| (p.x, p.y);
    let mut outlines: Vec<Outline> = map
        .furniture
        .iter()
        .map(|f| Outline {
            points: f.polygon.iter().map(xy).collect(),
            filled: true,
        })
        .collect();
    outlines.extend(map.walls.iter().map(|w| Outline {
        points: w.iter().map(xy).collect(),
        filled: false,
    }));
    outlines.extend(map.doors.iter().map(|d| Outline {
        points: vec![xy(&d.a), xy(&d.b)],
        filled: false,
    }));
    outlines
}

pub(crate) fn create_dir(dir: &Path) -> Result<(), ExperimentError> {
    std::fs::create_dir_all(dir).map_err(|source| ExperimentError::Io {
        path: dir.display().to_string(),
        source,
    })
}

pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    std::fs::write(path, bytes).map_err(|source| ExperimentError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Writes `summary.json`, `trials.json`, `paths-MODE.png` for each mode and `collisions.png`
/// into `out_dir` (created if needed); returns the summary.
pub fn write_outputs(
    report: &Report,
    map: &Map,
    out_dir: &Path,
) -> Result<Summary, ExperimentError> {
    create_dir(out_dir)?;
    let summary = Summary::from_report(report)?;
    write_file(
        &out_dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    write_file(
        &out_dir.join("trials.json"),
        serde_json::to_string_pretty(&report.trials)?.as_bytes(),
    )?;
    let route = map.route(&report.config.route);
    for mode in Mode::ALL {
        let trials = report.trials_of(mode);
        let s = summary.mode(mode);
        let figure = PathFigure {
            title: format!(
                "{}: {} drivers x {} laps, {} collisions, {}/{} laps finished",
                mode.key(),
                report.config.drivers,
                report.config.laps,
                s.collisions,
                s.laps_completed,
                s.laps_attempted
            ),
            map: map_outlines(map),
            route: route
                .map(|r| r.points.iter().map(|p| (p.x, p.y)).collect())
                .unwrap_or_default(),
            route_closed: route.is_some_and(|r| r.closed),
            paths: trials
                .iter()
                .map(|t| PathSeries {
                    label: format!("driver {}", t.driver + 1),
                    points: t.path.clone(),
                })
                .collect(),
            markers: trials
                .iter()
                .flat_map(|t| t.collision_points.iter().copied())
                .collect(),
            marker_label: "collision".into(),
        };
        plot_paths(&out_dir.join(format!("paths-{}.png", mode.key())), &figure)?;
    }
    let drivers: Vec<String> = (1..=report.config.drivers).map(|d| d.to_string()).collect();
    let series: Vec<(String, Vec<f64>)> = Mode::ALL
        .iter()
        .map(|&m| {
            let s = summary.mode(m);
            (
                format!("{} ({:.2}/lap)", m.key(), s.collisions_per_lap),
                s.collisions_per_lap_per_driver.clone(),
            )
        })
        .collect();
    bar_chart(
        &out_dir.join("collisions.png"),
        &format!(
            "{}: collisions per lap (manual > shared T = {}, p = {:.4} exact, {:.4} normal)",
            report.map_name, summary.wilcoxon_t, summary.wilcoxon_p, summary.wilcoxon_p_normal
        ),
        "driver",
        &drivers,
        &series,
    )?;
    Ok(summary)
}

/// Grouped bars: one group per category, one bar per series (thesis figure 3.10's kind).
pub(crate) fn bar_chart(
    path: &Path,
    caption: &str,
    x_desc: &str,
    categories: &[String],
    series: &[(String, Vec<f64>)],
) -> Result<(), ExperimentError> {
    iw_plot::register_fonts();
    let err = |e| iw_plot::PlotError::draw(path, e);
    let colours = [
        RED,
        BLUE,
        RGBColor(140, 60, 200),
        RGBColor(0, 150, 0),
        RGBColor(230, 140, 0),
        RGBColor(0, 160, 160),
    ];
    let top = series
        .iter()
        .flat_map(|s| s.1.iter())
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
        .max(1.0);
    let root = BitMapBackend::new(path, (1100, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .margin(15)
        .caption(caption, ("sans-serif", 18))
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..categories.len().max(1) as f64, 0.0..top * 1.15)
        .map_err(err)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_desc(x_desc)
        .y_desc("collisions per lap")
        .x_labels(categories.len().max(1) * 2 + 1)
        .x_label_formatter(&|x| {
            let k = x.floor();
            if (x - k - 0.5).abs() < 0.26 {
                categories.get(k as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    let width = 0.8 / series.len().max(1) as f64;
    for (k, (label, values)) in series.iter().enumerate() {
        let colour = colours[k % colours.len()];
        chart
            .draw_series(values.iter().enumerate().map(|(d, &c)| {
                let x0 = d as f64 + 0.1 + width * k as f64;
                Rectangle::new([(x0, 0.0), (x0 + width * 0.9, c)], colour.filled())
            }))
            .map_err(err)?
            .label(label.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], colour.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}
