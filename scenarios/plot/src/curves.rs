//! Cost curves: measured quantities against one swept parameter (e.g. the number of chair
//! processes), one panel per quantity, one PNG.

use std::path::Path;

use plotters::prelude::*;

use crate::{PlotError, draw_legend, line_key};

/// One measured line of a panel: a legend name and `(x, y)` points in x order.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Legend label.
    pub name: String,
    /// The points.
    pub points: Vec<(f64, f64)>,
}

/// One panel: a quantity, its lines and an optional target drawn as a dashed level.
#[derive(Debug, Clone)]
pub struct CurvePanel {
    /// The y axis label, with its unit.
    pub y_label: String,
    /// The lines.
    pub curves: Vec<Curve>,
    /// A level to compare with (a target, a capacity): its legend label and value, drawn grey.
    pub level: Option<(String, f64)>,
}

const COLOURS: [RGBColor; 4] = [BLUE, RED, RGBColor(0, 150, 0), RGBColor(200, 120, 0)];

/// Draws `panels` side by side (two per row) against `x_label` into a PNG at `path`.
pub fn plot_curves(
    path: &Path,
    title: &str,
    x_label: &str,
    panels: &[CurvePanel],
) -> Result<(), PlotError> {
    crate::register_fonts();
    let err = |e| PlotError::draw(path, e);
    let rows = panels.len().div_ceil(2).max(1);
    let root = BitMapBackend::new(path, (1200, 450 * rows as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 24)).map_err(err)?;
    let areas = root.split_evenly((rows, 2));
    for (panel, area) in panels.iter().zip(&areas) {
        let points = || panel.curves.iter().flat_map(|c| c.points.iter());
        let x_max = points().map(|p| p.0).fold(1.0, f64::max);
        let y_max = points()
            .map(|p| p.1)
            .chain(panel.level.as_ref().map(|l| l.1))
            .filter(|y| y.is_finite())
            .fold(1e-3, f64::max);
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_max * 1.05, 0.0..y_max * 1.1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(&panel.y_label)
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        if let Some((label, target)) = &panel.level {
            let target = *target;
            chart
                .draw_series(DashedLineSeries::new(
                    [(0.0, target), (x_max * 1.05, target)],
                    6,
                    4,
                    ShapeStyle::from(&RGBColor(120, 120, 120)).stroke_width(2),
                ))
                .map_err(err)?
                .label(label.clone())
                .legend(line_key(RGBColor(120, 120, 120)));
        }
        for (i, curve) in panel.curves.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(
                    curve.points.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(err)?
                .label(curve.name.clone())
                .legend(line_key(colour));
            chart
                .draw_series(
                    curve
                        .points
                        .iter()
                        .map(|&p| Circle::new(p, 4, colour.filled())),
                )
                .map_err(err)?;
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, path)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_with_a_target_level() {
        let dir = std::env::temp_dir().join(format!("iw-plot-curves-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("curves.png");
        let panel = CurvePanel {
            y_label: "converge (s)".into(),
            curves: vec![Curve {
                name: "measured".into(),
                points: vec![(10.0, 0.5), (50.0, 1.5), (100.0, 4.0)],
            }],
            level: Some(("target 5 s".into(), 5.0)),
        };
        plot_curves(&path, "fleet", "chairs", &[panel.clone(), panel]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_png_that_cannot_be_written_keeps_plotters_error() {
        use plotters::drawing::DrawingAreaErrorKind;
        use plotters::prelude::DrawingBackend;
        use std::error::Error;
        type BitmapError = <BitMapBackend<'static> as DrawingBackend>::ErrorType;

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no-such-dir").join("curves.png");
        let panel = CurvePanel {
            y_label: "y".into(),
            curves: vec![Curve {
                name: "c".into(),
                points: vec![(1.0, 1.0)],
            }],
            level: None,
        };
        let err = plot_curves(&path, "t", "x", &[panel]).unwrap_err();
        let cause = err
            .source()
            .and_then(|s| s.downcast_ref::<DrawingAreaErrorKind<BitmapError>>())
            .unwrap_or_else(|| panic!("no plotters error under `{err}`"));
        let text = err.to_string();
        assert!(
            text.starts_with(&format!("drawing {}: ", path.display()))
                && text.ends_with(&cause.to_string()),
            "{text}"
        );
    }
}
