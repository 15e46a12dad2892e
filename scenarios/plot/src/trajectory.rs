//! Trajectories against ground truth: x, y and z over time and a top view (x-y), one PNG.

use std::path::Path;

use plotters::prelude::*;

use crate::{PlotError, draw_legend, line_key};

/// One trajectory: a name for the legend and `(time s, [x, y, z] m)` samples.
#[derive(Debug, Clone)]
pub struct Trajectory {
    /// Legend label (e.g. "ground truth", "lsac-surf keyframe").
    pub name: String,
    /// Samples in time order.
    pub samples: Vec<(f64, [f64; 3])>,
}

const COLOURS: [RGBColor; 5] = [
    RED,
    BLUE,
    RGBColor(0, 150, 0),
    RGBColor(200, 120, 0),
    MAGENTA,
];

fn range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    (lo - pad)..(hi + pad)
}

/// Draws the trajectories (first one red: the reference) into a 1200x900 PNG at `path`;
/// time starts at the first sample of the first trajectory.
pub fn plot_trajectories(
    path: &Path,
    title: &str,
    trajectories: &[Trajectory],
) -> Result<(), PlotError> {
    crate::register_fonts();
    let err = |e| PlotError::draw(path, e);
    let root = BitMapBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 24)).map_err(err)?;
    let panels = root.split_evenly((2, 2));
    let t0 = trajectories
        .iter()
        .flat_map(|t| t.samples.first())
        .map(|s| s.0)
        .next()
        .unwrap_or(0.0);
    let all = || trajectories.iter().flat_map(|t| t.samples.iter());
    let time_range = range(all().map(|s| s.0 - t0));
    for (axis, panel) in panels.iter().take(3).enumerate() {
        let label = ["x", "y", "z"][axis];
        let mut chart = ChartBuilder::on(panel)
            .margin(10)
            .caption(format!("{label} over time"), ("sans-serif", 18))
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(time_range.clone(), range(all().map(|s| s.1[axis])))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(format!("{label} (m)"))
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        for (i, t) in trajectories.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(
                    t.samples.iter().map(|s| (s.0 - t0, s.1[axis])),
                    colour.stroke_width(2),
                ))
                .map_err(err)?
                .label(t.name.clone())
                .legend(line_key(colour.stroke_width(2)));
        }
        if axis == 0 {
            draw_legend(&mut chart, SeriesLabelPosition::MiddleRight, path)?;
        }
    }
    // Top view with equal scales on both axes so shapes are not distorted.
    let (xs, ys) = (range(all().map(|s| s.1[0])), range(all().map(|s| s.1[1])));
    let half = 0.5 * (xs.end - xs.start).max(ys.end - ys.start);
    let (mx, my) = (0.5 * (xs.start + xs.end), 0.5 * (ys.start + ys.end));
    let mut chart = ChartBuilder::on(&panels[3])
        .margin(10)
        .caption("top view (x-y)", ("sans-serif", 18))
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d((mx - half)..(mx + half), (my - half)..(my + half))
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    for (i, t) in trajectories.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(
                t.samples.iter().map(|s| (s.1[0], s.1[1])),
                colour.stroke_width(2),
            ))
            .map_err(err)?;
    }
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png() {
        let dir = std::env::temp_dir().join(format!("iw-plot-traj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("t.png");
        let circle = |r: f64| Trajectory {
            name: format!("r {r}"),
            samples: (0..50)
                .map(|i| {
                    (
                        i as f64 * 0.1,
                        [
                            r * (i as f64 * 0.1).cos(),
                            r * (i as f64 * 0.1).sin(),
                            0.01 * i as f64,
                        ],
                    )
                })
                .collect(),
        };
        plot_trajectories(
            &path,
            "test",
            &[
                circle(1.0),
                circle(1.1),
                Trajectory {
                    name: "empty".into(),
                    samples: vec![],
                },
            ],
        )
        .expect("drawn");
        let bytes = std::fs::read(&path).expect("written");
        assert!(bytes.starts_with(b"\x89PNG"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
