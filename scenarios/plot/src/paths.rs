//! Top views of a map with driven paths and marked events (collisions): the simulated experiment's
//! counterpart of thesis figure 3.9.

use std::path::Path;

use plotters::prelude::*;

use crate::{PlotError, draw_legend, line_key};

/// A piece of map geometry, world frame, m.
#[derive(Debug, Clone)]
pub struct Outline {
    /// Vertices in order.
    pub points: Vec<(f64, f64)>,
    /// True: a filled polygon (furniture); false: a polyline (walls).
    pub filled: bool,
}

/// One driven path.
#[derive(Debug, Clone)]
pub struct PathSeries {
    /// Legend label (e.g. "driver 3").
    pub label: String,
    /// Positions in time order, m.
    pub points: Vec<(f64, f64)>,
}

/// Everything one path figure shows.
#[derive(Debug, Clone, Default)]
pub struct PathFigure {
    /// Title on top.
    pub title: String,
    /// Walls and furniture.
    pub map: Vec<Outline>,
    /// A reference line drawn dashed-grey under the paths (the circuit), closed if `route_closed`.
    pub route: Vec<(f64, f64)>,
    /// Whether the route loops back to its first point.
    pub route_closed: bool,
    /// The driven paths.
    pub paths: Vec<PathSeries>,
    /// Event positions drawn as red crosses (collisions), m.
    pub markers: Vec<(f64, f64)>,
    /// Legend label of the markers.
    pub marker_label: String,
}

const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(23, 190, 207),
];

/// Draws `figure` into a 1200 px wide PNG at `path`, equal scales on both axes.
pub fn plot_paths(path: &Path, figure: &PathFigure) -> Result<(), PlotError> {
    crate::register_fonts();
    let err = |e| PlotError::draw(path, e);
    let all = figure
        .map
        .iter()
        .flat_map(|o| o.points.iter())
        .chain(figure.paths.iter().flat_map(|p| p.points.iter()))
        .chain(figure.route.iter());
    let (mut lo, mut hi) = (
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for &(x, y) in all.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    if !lo.0.is_finite() {
        (lo, hi) = ((0.0, 0.0), (1.0, 1.0));
    }
    let pad = 0.03 * (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-3);
    let (x_range, y_range) = ((lo.0 - pad)..(hi.0 + pad), (lo.1 - pad)..(hi.1 + pad));
    let width_px = 1200u32;
    let aspect = (y_range.end - y_range.start) / (x_range.end - x_range.start);
    let height_px = ((width_px as f64 - 90.0) * aspect + 130.0).clamp(300.0, 2400.0) as u32;
    let root = BitMapBackend::new(path, (width_px, height_px)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .margin(15)
        .caption(&figure.title, ("sans-serif", 24))
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x_range, y_range)
        .map_err(err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    let furniture = RGBColor(200, 200, 200);
    for outline in &figure.map {
        if outline.filled {
            chart
                .draw_series(std::iter::once(Polygon::new(
                    outline.points.clone(),
                    furniture.filled(),
                )))
                .map_err(err)?;
        } else {
            chart
                .draw_series(std::iter::once(PathElement::new(
                    outline.points.clone(),
                    BLACK.stroke_width(3),
                )))
                .map_err(err)?;
        }
    }
    if !figure.route.is_empty() {
        let mut route = figure.route.clone();
        if figure.route_closed {
            route.extend(figure.route.first().copied());
        }
        let grey = RGBColor(150, 150, 150);
        chart
            .draw_series(DashedLineSeries::new(route, 6, 6, grey.stroke_width(2)))
            .map_err(err)?
            .label("circuit")
            .legend(line_key(grey.stroke_width(2)));
    }
    for (i, series) in figure.paths.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(
                series.points.iter().copied(),
                colour.mix(0.85).stroke_width(2),
            ))
            .map_err(err)?
            .label(series.label.clone())
            .legend(line_key(colour.stroke_width(3)));
    }
    if !figure.markers.is_empty() {
        chart
            .draw_series(
                figure
                    .markers
                    .iter()
                    .map(|&p| Cross::new(p, 7, RED.stroke_width(3))),
            )
            .map_err(err)?
            .label(figure.marker_label.clone())
            .legend(|(x, y)| Cross::new((x + 10, y), 6, RED.stroke_width(3)));
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, path)?;
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_with_paths_and_markers() {
        let dir = std::env::temp_dir().join(format!("iw-plot-paths-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("paths.png");
        let figure = PathFigure {
            title: "test".into(),
            map: vec![
                Outline {
                    points: vec![(0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0), (0.0, 0.0)],
                    filled: false,
                },
                Outline {
                    points: vec![(1.0, 1.0), (2.0, 1.0), (2.0, 2.0)],
                    filled: true,
                },
            ],
            route: vec![(0.5, 0.5), (3.5, 0.5), (3.5, 2.5)],
            route_closed: true,
            paths: vec![PathSeries {
                label: "a".into(),
                points: vec![(0.5, 0.6), (3.4, 0.7), (3.4, 2.4)],
            }],
            markers: vec![(3.4, 0.7)],
            marker_label: "collision".into(),
        };
        plot_paths(&file, &figure).unwrap();
        let bytes = std::fs::read(&file).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        std::fs::remove_dir_all(&dir).ok();
    }
}
