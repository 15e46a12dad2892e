//! `summary.json` and the pictures.

use std::path::Path;

use iw_plot::paths::{Outline, PathFigure, PathSeries, plot_paths};
use iw_plot::plotters::prelude::*;
use iw_sim::Map;

use crate::{Config, ExperimentError, Report};

/// Position error of one estimator over all tracking drives.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ErrorStats {
    /// Root mean square position error over every period of every drive, m.
    pub rmse_m: f64,
    /// Largest position error, m.
    pub max_m: f64,
    /// Worst drive's RMSE, m.
    pub worst_drive_rmse_m: f64,
}

/// Global localization over all runs.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GlobalSummary {
    /// Runs.
    pub runs: usize,
    /// Runs that converged (tracking within 5 m of driving, then within 10 cm and 3 degrees).
    pub converged: usize,
    /// Median distance driven before the localizer first reported tracking, m (runs that did).
    pub median_distance_m: Option<f64>,
    /// Runs that reported tracking at some point.
    pub fixed: usize,
    /// Runs that reported tracking while more than 30 cm off.
    pub falsely_confident: usize,
    /// Largest position error while reporting tracking, over all runs, m.
    pub max_tracking_error_m: f64,
}

/// Blind runs of one estimator after the same distance with the laser.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BlindStats {
    /// Median position error when the blind stretch ends, m.
    pub median_error_m: f64,
    /// Largest of those errors, m.
    pub max_error_m: f64,
    /// Median of twice the standard deviation along the longest x-y axis then, m.
    pub median_two_sigma_m: f64,
    /// Median trace of the x-y covariance then, m².
    pub median_trace_m2: f64,
    /// Runs whose end error was within that 2 sigma.
    pub within_two_sigma: usize,
    /// Mean share of the once-a-second position NEES samples under the 95 % bound.
    pub inside_rate: f64,
}

/// The blind runs after one distance with the laser.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BlindSummary {
    /// Metres driven with the laser before it went silent.
    pub learn_m: f64,
    /// Runs.
    pub runs: usize,
    /// The localizer as shipped: wheel bias in its state.
    pub modelled: BlindStats,
    /// The same without the bias states.
    pub unmodelled: BlindStats,
}

fn blind_stats(runs: &[&crate::BlindEnd]) -> BlindStats {
    let of = |f: fn(&crate::BlindEnd) -> f64| {
        let mut v: Vec<f64> = runs.iter().map(|r| f(r)).collect();
        percentile(&mut v, 0.5)
    };
    BlindStats {
        median_error_m: of(|r| r.error_m),
        max_error_m: runs.iter().map(|r| r.error_m).fold(0.0, f64::max),
        median_two_sigma_m: of(|r| r.two_sigma_m),
        median_trace_m2: of(|r| r.trace_m2),
        within_two_sigma: runs.iter().filter(|r| r.error_m <= r.two_sigma_m).count(),
        inside_rate: runs.iter().map(|r| r.inside_rate).sum::<f64>() / runs.len().max(1) as f64,
    }
}

/// The contract shape of `summary.json`, plus details.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Wheel odometry alone.
    pub wheel: ErrorStats,
    /// Visual odometry alone (`null` when it did not run).
    pub vo: Option<ErrorStats>,
    /// EKF of wheel and visual odometry.
    pub fused: ErrorStats,
    /// The map-based localizer.
    pub localized: ErrorStats,
    /// Global localization.
    pub global: GlobalSummary,
    /// Fraction of the once-a-second NEES samples of the localizer within the two-sided 95 %
    /// chi-square interval (3 degrees of freedom); 0.95 for a consistent filter.
    pub nees_pass_rate: f64,
    /// Mean NEES (3 for a consistent filter).
    pub nees_mean: f64,
    /// Fraction of NEES samples above the interval (overconfident).
    pub nees_above_rate: f64,
    /// Mean squared error over variance of x, y and theta in the same samples (1 each if
    /// consistent): which component the NEES misses on.
    pub nees_components: [f64; 3],
    /// Ground distance per drive, m.
    pub distance_m: Vec<f64>,
    /// Localizer time per 50 ms period: median and 99th percentile, µs.
    pub localizer_us: (f64, f64),
    /// Visual odometry frames processed, all drives.
    pub vo_frames: usize,
    /// Landmark sightings fused by the localizer, all drives.
    pub landmark_sightings: usize,
    /// Collisions of the measured chair, all drives.
    pub collisions: u64,
    /// Times the localizer lost its pose during the tracking drives.
    pub searches: u64,
    /// Global runs, each.
    pub global_runs: Vec<crate::GlobalRun>,
    /// Blind runs: the laser silent for [`crate::BLIND_M`] after each of
    /// [`crate::BLIND_LEARN_M`]; with and without the wheel bias in the filter's state.
    pub blind: Vec<BlindSummary>,
    /// Blind runs, each.
    pub blind_runs: Vec<crate::BlindRun>,
    /// Map driven.
    pub map: String,
    /// Configuration.
    pub config: Config,
}

/// The two-sided 95 % chi-square interval with 3 degrees of freedom.
pub const NEES_BOUNDS: (f64, f64) = (0.2158, 9.348);

fn percentile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}

impl Summary {
    /// Summarises a report.
    pub fn of(report: &Report) -> Summary {
        let stats = |k: usize| {
            let periods: usize = report.drives.iter().map(|d| d.periods).sum();
            let sum: f64 = report.drives.iter().map(|d| d.errors[k].0).sum();
            ErrorStats {
                rmse_m: (sum / periods.max(1) as f64).sqrt(),
                max_m: report
                    .drives
                    .iter()
                    .map(|d| d.errors[k].1)
                    .fold(0.0, f64::max),
                worst_drive_rmse_m: report
                    .drives
                    .iter()
                    .map(|d| (d.errors[k].0 / d.periods.max(1) as f64).sqrt())
                    .fold(0.0, f64::max),
            }
        };
        let nees: Vec<f64> = report
            .drives
            .iter()
            .flat_map(|d| d.samples.iter().map(|s| s.nees))
            .collect();
        let n = nees.len().max(1) as f64;
        let inside = nees
            .iter()
            .filter(|v| (NEES_BOUNDS.0..=NEES_BOUNDS.1).contains(*v))
            .count();
        let above = nees.iter().filter(|v| **v > NEES_BOUNDS.1).count();
        let mut fixes: Vec<f64> = report.global.iter().filter_map(|g| g.distance_m).collect();
        let median_distance_m = (!fixes.is_empty()).then(|| percentile(&mut fixes, 0.5));
        let mut us: Vec<f64> = report
            .drives
            .iter()
            .flat_map(|d| d.localizer_us.iter().copied())
            .collect();
        let vo_frames = report.drives.iter().map(|d| d.vo_frames).sum();
        Summary {
            wheel: stats(0),
            vo: (vo_frames > 0).then(|| stats(1)),
            fused: stats(2),
            localized: stats(3),
            global: GlobalSummary {
                runs: report.global.len(),
                converged: report.global.iter().filter(|g| g.converged).count(),
                median_distance_m,
                fixed: report
                    .global
                    .iter()
                    .filter(|g| g.distance_m.is_some())
                    .count(),
                falsely_confident: report.global.iter().filter(|g| g.falsely_confident).count(),
                max_tracking_error_m: report
                    .global
                    .iter()
                    .map(|g| g.max_tracking_error_m)
                    .fold(0.0, f64::max),
            },
            nees_pass_rate: inside as f64 / n,
            nees_mean: nees.iter().filter(|v| v.is_finite()).sum::<f64>() / n,
            nees_above_rate: above as f64 / n,
            nees_components: std::array::from_fn(|k| {
                report
                    .drives
                    .iter()
                    .flat_map(|d| d.samples.iter().map(|s| s.nees_components[k]))
                    .filter(|v| v.is_finite())
                    .sum::<f64>()
                    / n
            }),
            distance_m: report.drives.iter().map(|d| d.distance_m).collect(),
            localizer_us: (percentile(&mut us, 0.5), percentile(&mut us, 0.99)),
            vo_frames,
            landmark_sightings: report.drives.iter().map(|d| d.landmark_sightings).sum(),
            collisions: report.drives.iter().map(|d| d.collisions).sum(),
            searches: report.drives.iter().map(|d| d.searches).sum(),
            global_runs: report.global.clone(),
            blind: crate::BLIND_LEARN_M
                .iter()
                .map(|&learn_m| {
                    let runs: Vec<&crate::BlindRun> = report
                        .blind
                        .iter()
                        .filter(|b| b.learn_m == learn_m)
                        .collect();
                    BlindSummary {
                        learn_m,
                        runs: runs.len(),
                        modelled: blind_stats(
                            &runs.iter().map(|b| &b.modelled).collect::<Vec<_>>(),
                        ),
                        unmodelled: blind_stats(
                            &runs.iter().map(|b| &b.unmodelled).collect::<Vec<_>>(),
                        ),
                    }
                })
                .filter(|b| b.runs > 0)
                .collect(),
            blind_runs: report.blind.clone(),
            map: report.map.clone(),
            config: report.config.clone(),
        }
    }
}

fn outlines(map: &Map) -> Vec<Outline> {
    let walls = map.walls.iter().map(|w| Outline {
        points: w.iter().map(|p| (p.x, p.y)).collect(),
        filled: false,
    });
    let furniture = map.furniture.iter().map(|f| Outline {
        points: f.polygon.iter().map(|p| (p.x, p.y)).collect(),
        filled: true,
    });
    walls.chain(furniture).collect()
}

/// Writes `summary.json`, `paths.png` (first drive: truth and the four estimates),
/// `error.png` (position error against time, first drive) and `global.png` (share of the global
/// runs localized against metres driven) into `out`.
pub fn write_outputs(report: &Report, map: &Map, out: &Path) -> Result<Summary, ExperimentError> {
    let io = |path: &Path, source| ExperimentError::Io {
        path: path.display().to_string(),
        source,
    };
    std::fs::create_dir_all(out).map_err(|e| io(out, e))?;
    let summary = Summary::of(report);
    let path = out.join("summary.json");
    let text = serde_json::to_string_pretty(&summary).map_err(|e| io(&path, e.into()))?;
    std::fs::write(&path, text).map_err(|e| io(&path, e))?;
    if let Some(drive) = report.drives.first() {
        let series = |label: &str, pick: &dyn Fn(&crate::Sample) -> iw_vo::Pose2| PathSeries {
            label: label.to_string(),
            points: drive
                .samples
                .iter()
                .map(|s| (pick(s).x, pick(s).y))
                .collect(),
        };
        let mut paths = vec![
            series("ground truth", &|s| s.truth),
            series("wheel odometry", &|s| s.wheel),
        ];
        if drive.vo_frames > 0 {
            paths.push(series("visual odometry", &|s| s.vo));
        }
        paths.push(series("wheel + VO (EKF)", &|s| s.fused));
        paths.push(series("localized (map)", &|s| s.localized));
        plot_paths(
            &out.join("paths.png"),
            &PathFigure {
                title: format!(
                    "{}: {:.0} m in {:.0} min, seed {}",
                    report.map,
                    drive.distance_m,
                    drive.periods as f64 * report.config.dt_s / 60.0,
                    drive.seed
                ),
                map: outlines(map),
                route: report.route.iter().map(|p| (p.x, p.y)).collect(),
                route_closed: true,
                paths,
                markers: Vec::new(),
                marker_label: String::new(),
            },
        )?;
        plot_errors(&out.join("error.png"), drive)?;
    }
    if !report.global.is_empty() {
        plot_global(&out.join("global.png"), &report.global, &report.map)?;
    }
    Ok(summary)
}

/// The share of runs that have found their pose (first tracking within 10 cm and 3 degrees)
/// against the metres driven.
fn plot_global(path: &Path, runs: &[crate::GlobalRun], map: &str) -> Result<(), ExperimentError> {
    let mut found: Vec<f64> = runs
        .iter()
        .filter(|r| {
            r.error_at_fix
                .is_some_and(|(m, deg)| m <= 0.10 && deg <= 3.0)
        })
        .filter_map(|r| r.distance_m)
        .collect();
    found.sort_by(f64::total_cmp);
    let share = |k: usize| k as f64 / runs.len() as f64;
    let points = std::iter::once((0.0, 0.0))
        .chain(
            found
                .iter()
                .enumerate()
                .flat_map(|(k, d)| [(*d, share(k)), (*d, share(k + 1))]),
        )
        .collect();
    iw_plot::curves::plot_curves(
        path,
        &format!("{map}: global localization, {} runs", runs.len()),
        "metres driven",
        &[iw_plot::curves::CurvePanel {
            y_label: "share of runs localized".into(),
            curves: vec![iw_plot::curves::Curve {
                name: "within 10 cm and 3 degrees".into(),
                points,
            }],
            level: Some(("target: 95 % within 5 m".into(), 0.95)),
        }],
    )?;
    Ok(())
}

/// A curve of the error plot: label, colour, (minutes, metres).
type Curve = (&'static str, RGBColor, Vec<(f64, f64)>);

fn plot_errors(path: &Path, drive: &crate::Drive) -> Result<(), ExperimentError> {
    iw_plot::register_fonts();
    let err = |e| iw_plot::PlotError::draw(path, e);
    let error =
        |a: &iw_vo::Pose2, b: &iw_vo::Pose2| ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt();
    let mut curves: Vec<Curve> = vec![
        ("wheel odometry", RGBColor(255, 127, 14), Vec::new()),
        ("visual odometry", RGBColor(44, 160, 44), Vec::new()),
        ("wheel + VO (EKF)", RGBColor(148, 103, 189), Vec::new()),
        ("localized (map)", RGBColor(31, 119, 180), Vec::new()),
    ];
    for s in &drive.samples {
        let minutes = s.time_s / 60.0;
        curves[0].2.push((minutes, error(&s.wheel, &s.truth)));
        curves[1].2.push((minutes, error(&s.vo, &s.truth)));
        curves[2].2.push((minutes, error(&s.fused, &s.truth)));
        curves[3].2.push((minutes, error(&s.localized, &s.truth)));
    }
    if drive.vo_frames == 0 {
        curves.remove(1);
    }
    let t_max = drive
        .samples
        .last()
        .map_or(1.0, |s| s.time_s / 60.0)
        .max(1e-3);
    let root = BitMapBackend::new(path, (1200, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let (upper, lower) = root.split_vertically(400);
    for (area, log, title) in [
        (&upper, false, "position error, all estimators (m)"),
        (&lower, true, "position error, log scale (m)"),
    ] {
        let y_max = curves
            .iter()
            .flat_map(|c| c.2.iter().map(|p| p.1))
            .fold(0.01, f64::max)
            * 1.05;
        let mut builder = ChartBuilder::on(area);
        builder
            .caption(title, ("sans-serif", 20))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60);
        macro_rules! draw {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc("time (min)")
                    .draw()
                    .map_err(err)?;
                for (label, colour, points) in &curves {
                    let colour = *colour;
                    chart
                        .draw_series(LineSeries::new(
                            points.iter().map(|&(t, e)| (t, e.max(1e-4))),
                            colour.stroke_width(2),
                        ))
                        .map_err(err)?
                        .label(*label)
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                        });
                }
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .position(SeriesLabelPosition::UpperLeft)
                    .draw()
                    .map_err(err)?;
            }};
        }
        if log {
            draw!(
                builder
                    .build_cartesian_2d(0.0..t_max, (1e-3..y_max).log_scale())
                    .map_err(err)?
            );
        } else {
            draw!(
                builder
                    .build_cartesian_2d(0.0..t_max, 0.0..y_max)
                    .map_err(err)?
            );
        }
    }
    root.present().map_err(err)?;
    Ok(())
}
