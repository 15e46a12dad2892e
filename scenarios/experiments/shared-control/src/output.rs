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
    /// Collision events, all drivers and laps.
    pub collisions: u64,
    /// Collisions per finished lap (`null` when no lap was finished).
    pub collisions_per_lap: Option<f64>,
    /// Collisions of each driver (the paired samples of the Wilcoxon test).
    pub collisions_per_driver: Vec<u64>,
    /// Collisions per 100 m driven, each driver: the paired samples of the Wilcoxon tests (raw
    /// counts would reward a paradigm whose drivers give up early on the lap timeout).
    pub collisions_per_100m_per_driver: Vec<f64>,
    /// Collisions per 100 m driven, all drivers.
    pub collisions_per_100m: f64,
    /// Laps finished, all drivers.
    pub laps_completed: usize,
    /// Laps asked for, all drivers.
    pub laps_attempted: usize,
    /// Trials abandoned on the lap timeout.
    pub trials_timed_out: usize,
    /// Mean time of a finished lap, s.
    pub mean_lap_time_s: Option<f64>,
    /// Fraction of periods in which the command reaching the wheels differed from the user's.
    pub intervention_rate: f64,
    /// Same, over periods with the footprint near an obstacle.
    pub intervention_rate_near: f64,
    /// Same, over periods in free space.
    pub intervention_rate_free: f64,
    /// Share of all interventions that happened near obstacles.
    pub interventions_near_share: f64,
    /// Mean wheel-speed change of a changed period, m/s.
    pub mean_intervention_mps: f64,
    /// Fraction of periods spent near obstacles.
    pub near_fraction: f64,
    /// Smallest footprint clearance over all trials, m.
    pub min_clearance_m: f64,
    /// Ground distance driven, all drivers, m.
    pub distance_m: f64,
}

/// One paired comparison.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// Relative reduction of collisions per 100 m driven, 1 - b / a (`null` if a had none).
    pub collision_reduction: Option<f64>,
    /// Wilcoxon signed-rank on collisions per 100 m, one-tailed (first has more), paired per driver.
    pub wilcoxon: Wilcoxon,
}

/// The contract shape of `summary.json`, plus details.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Manual driving.
    pub manual: ModeSummary,
    /// Thesis potential-field shared control.
    pub shared: ModeSummary,
    /// VFH+ shared control.
    pub vfh: ModeSummary,
    /// The control agent's policy: potential field, then the arc guard.
    pub guarded: ModeSummary,
    /// Exact one-tailed Wilcoxon signed-rank p, manual vs shared collisions per 100 m, paired per
    /// driver.
    pub wilcoxon_p: f64,
    /// Manual vs shared.
    pub manual_vs_shared: Comparison,
    /// Manual vs VFH+.
    pub manual_vs_vfh: Comparison,
    /// VFH+ vs shared (is shared ahead of the baseline?).
    pub vfh_vs_shared: Comparison,
    /// Manual vs the guarded potential field.
    pub manual_vs_guarded: Comparison,
    /// VFH+ vs the guarded potential field.
    pub vfh_vs_guarded: Comparison,
    /// Map driven.
    pub map: String,
    /// Configuration.
    pub config: Config,
}

fn mode_summary(trials: &[&Trial], laps_per_trial: usize) -> ModeSummary {
    let sum = |f: &dyn Fn(&Trial) -> u64| trials.iter().map(|t| f(t)).sum::<u64>();
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    let collisions = sum(&|t| t.collisions);
    let laps_completed: usize = trials.iter().map(|t| t.laps_completed).sum();
    let lap_times: Vec<f64> = trials
        .iter()
        .flat_map(|t| t.lap_times_s.iter().copied())
        .collect();
    let periods = sum(&|t| t.periods);
    let near = sum(&|t| t.periods_near);
    let changed_near = sum(&|t| t.changed_near);
    let changed_free = sum(&|t| t.changed_free);
    let changed = changed_near + changed_free;
    ModeSummary {
        collisions,
        collisions_per_lap: (laps_completed > 0).then(|| collisions as f64 / laps_completed as f64),
        collisions_per_driver: trials.iter().map(|t| t.collisions).collect(),
        collisions_per_100m_per_driver: trials
            .iter()
            .map(|t| per_100m(t.collisions, t.distance_m))
            .collect(),
        collisions_per_100m: per_100m(collisions, trials.iter().map(|t| t.distance_m).sum()),
        laps_completed,
        laps_attempted: trials.len() * laps_per_trial,
        trials_timed_out: trials.iter().filter(|t| t.timed_out).count(),
        mean_lap_time_s: (!lap_times.is_empty())
            .then(|| lap_times.iter().sum::<f64>() / lap_times.len() as f64),
        intervention_rate: ratio(changed, periods),
        intervention_rate_near: ratio(changed_near, near),
        intervention_rate_free: ratio(changed_free, periods - near),
        interventions_near_share: ratio(changed_near, changed),
        mean_intervention_mps: if changed == 0 {
            0.0
        } else {
            trials.iter().map(|t| t.change_sum_mps).sum::<f64>() / changed as f64
        },
        near_fraction: ratio(near, periods),
        min_clearance_m: trials
            .iter()
            .map(|t| t.min_clearance_m)
            .fold(f64::INFINITY, f64::min),
        distance_m: trials.iter().map(|t| t.distance_m).sum(),
    }
}

fn per_100m(collisions: u64, distance_m: f64) -> f64 {
    if distance_m > 0.0 {
        100.0 * collisions as f64 / distance_m
    } else {
        0.0
    }
}

fn compare(a: &ModeSummary, b: &ModeSummary) -> Result<Comparison, ExperimentError> {
    Ok(Comparison {
        collision_reduction: (a.collisions_per_100m > 0.0)
            .then(|| 1.0 - b.collisions_per_100m / a.collisions_per_100m),
        wilcoxon: wilcoxon_signed_rank(
            &a.collisions_per_100m_per_driver,
            &b.collisions_per_100m_per_driver,
            Alternative::Greater,
        )?,
    })
}

impl Summary {
    /// The totals of one paradigm.
    pub fn mode(&self, mode: Mode) -> &ModeSummary {
        match mode {
            Mode::Manual => &self.manual,
            Mode::Shared => &self.shared,
            Mode::Vfh => &self.vfh,
            Mode::Guarded => &self.guarded,
        }
    }

    /// Aggregates a report.
    pub fn from_report(report: &Report) -> Result<Summary, ExperimentError> {
        let of = |mode: Mode| {
            let trials: Vec<&Trial> = report.trials.iter().filter(|t| t.mode == mode).collect();
            mode_summary(&trials, report.config.laps)
        };
        let (manual, shared, vfh, guarded) = (
            of(Mode::Manual),
            of(Mode::Shared),
            of(Mode::Vfh),
            of(Mode::Guarded),
        );
        let manual_vs_shared = compare(&manual, &shared)?;
        Ok(Summary {
            wilcoxon_p: manual_vs_shared.wilcoxon.p(),
            manual_vs_vfh: compare(&manual, &vfh)?,
            vfh_vs_shared: compare(&vfh, &shared)?,
            manual_vs_guarded: compare(&manual, &guarded)?,
            vfh_vs_guarded: compare(&vfh, &guarded)?,
            manual_vs_shared,
            manual,
            shared,
            vfh,
            guarded,
            map: report.map_name.clone(),
            config: report.config.clone(),
        })
    }
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

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    std::fs::write(path, bytes).map_err(|source| ExperimentError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Writes `summary.json`, `trials.json`, `paths-{manual,shared,vfh,guarded}.png` and `collisions.png`
/// into `out_dir` (created if needed); returns the summary.
pub fn write_outputs(
    report: &Report,
    map: &Map,
    out_dir: &Path,
) -> Result<Summary, ExperimentError> {
    std::fs::create_dir_all(out_dir).map_err(|source| ExperimentError::Io {
        path: out_dir.display().to_string(),
        source,
    })?;
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
        let trials: Vec<&Trial> = report.trials.iter().filter(|t| t.mode == mode).collect();
        let s = summary.mode(mode);
        let figure = PathFigure {
            title: format!(
                "{}: {} drivers x {} laps, {} collisions",
                mode.key(),
                report.config.drivers,
                report.config.laps,
                s.collisions
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
    plot_collisions(&out_dir.join("collisions.png"), &summary)?;
    Ok(summary)
}

/// Collisions per driver and paradigm, grouped bars (thesis figure 3.10's counterpart).
fn plot_collisions(path: &Path, summary: &Summary) -> Result<(), ExperimentError> {
    iw_plot::register_fonts();
    let err = |e: &dyn std::fmt::Display| iw_plot::PlotError::draw(path, e);
    let colours = [RED, BLUE, RGBColor(0, 150, 0), RGBColor(230, 140, 0)];
    let modes: Vec<_> = Mode::ALL
        .iter()
        .zip(colours)
        .map(|(&m, colour)| (m.key(), summary.mode(m), colour))
        .collect();
    let drivers = summary.manual.collisions_per_driver.len();
    let top = modes
        .iter()
        .flat_map(|m| m.1.collisions_per_driver.iter())
        .copied()
        .max()
        .unwrap_or(0)
        .max(1) as f64;
    let root = BitMapBackend::new(path, (1000, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(15)
        .caption(
            format!(
                "Collisions per driver (Wilcoxon manual > shared p = {:.4}, manual > guarded p = {:.4})",
                summary.wilcoxon_p,
                summary.manual_vs_guarded.wilcoxon.p()
            ),
            ("sans-serif", 20),
        )
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..drivers as f64, 0.0..top * 1.1)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_desc("driver")
        .y_desc("collisions")
        .x_labels(drivers.max(1))
        .x_label_formatter(&|x| format!("{}", x.floor() as usize + 1))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    for (k, (label, s, colour)) in modes.iter().enumerate() {
        let colour = *colour;
        chart
            .draw_series(s.collisions_per_driver.iter().enumerate().map(|(d, &c)| {
                let x0 = d as f64 + 0.1 + 0.2 * k as f64;
                Rectangle::new([(x0, 0.0), (x0 + 0.18, c as f64)], colour.filled())
            }))
            .map_err(|e| err(&e))?
            .label(format!("{label} ({} total)", s.collisions))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], colour.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
