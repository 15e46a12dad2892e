//! Box plots of grouped samples, as the thesis draws them (figs. 4.10, 4.15, 4.20, 4.25): the
//! box spans the quartiles, a line marks the median, whiskers reach the minimum and maximum.

use std::path::Path;

use plotters::prelude::*;

use crate::PlotError;

/// One box: a label under it and its sample.
#[derive(Debug, Clone)]
pub struct BoxSeries {
    /// Label on the x axis (e.g. "surf").
    pub label: String,
    /// The observations (NaNs ignored).
    pub values: Vec<f64>,
}

/// One panel: a caption and its boxes.
#[derive(Debug, Clone)]
pub struct BoxPanel {
    /// Caption above the panel (e.g. "LIC").
    pub caption: String,
    /// The boxes, left to right.
    pub boxes: Vec<BoxSeries>,
}

const COLOURS: [RGBColor; 4] = [
    RGBColor(200, 40, 40),
    RGBColor(40, 90, 200),
    RGBColor(0, 150, 0),
    RGBColor(200, 120, 0),
];

/// `[min, q1, median, q3, max]` with numpy's linear quantiles; `None` for an empty sample.
pub fn five_numbers(values: &[f64]) -> Option<[f64; 5]> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    v.sort_by(f64::total_cmp);
    let last = v.len().checked_sub(1)?;
    let q = |p: f64| {
        let pos = p * last as f64;
        let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
        v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
    };
    Some([v[0], q(0.25), q(0.5), q(0.75), v[last]])
}

/// Draws the panels side by side into one PNG (500 px wide per panel, 600 high); the y axis
/// runs over `y_range` with `y_label`.
pub fn plot_boxes(
    path: &Path,
    title: &str,
    y_label: &str,
    y_range: std::ops::Range<f64>,
    panels: &[BoxPanel],
) -> Result<(), PlotError> {
    crate::register_fonts();
    let err = |e| PlotError::draw(path, e);
    let width = 500 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (width, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 24)).map_err(err)?;
    for (panel, area) in panels
        .iter()
        .zip(root.split_evenly((1, panels.len().max(1))).iter())
    {
        let n = panel.boxes.len().max(1);
        let labels: Vec<String> = panel.boxes.iter().map(|b| b.label.clone()).collect();
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .caption(&panel.caption, ("sans-serif", 20))
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), y_range.clone())
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&|x: &f64| {
                let i = x.round();
                if (x - i).abs() < 1e-6 && i >= 0.0 {
                    labels.get(i as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .y_desc(y_label)
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(err)?;
        for (i, series) in panel.boxes.iter().enumerate() {
            let Some([min, q1, median, q3, max]) = five_numbers(&series.values) else {
                continue;
            };
            let colour = COLOURS[i % COLOURS.len()];
            let x = i as f64;
            let (l, r) = (x - 0.3, x + 0.3);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(l, q1), (r, q3)],
                    colour.mix(0.25).filled(),
                )))
                .map_err(err)?;
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(l, q1), (r, q3)],
                    colour.stroke_width(2),
                )))
                .map_err(err)?;
            let lines = [
                vec![(l, median), (r, median)],
                vec![(x, q3), (x, max)],
                vec![(x, q1), (x, min)],
                vec![(x - 0.15, max), (x + 0.15, max)],
                vec![(x - 0.15, min), (x + 0.15, min)],
            ];
            for line in lines {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        line,
                        colour.stroke_width(2),
                    )))
                    .map_err(err)?;
            }
        }
    }
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn five_numbers_match_numpy() {
        assert_eq!(
            five_numbers(&[4.0, 1.0, 3.0, 2.0]),
            Some([1.0, 1.75, 2.5, 3.25, 4.0])
        );
        assert_eq!(five_numbers(&[]), None);
    }

    #[test]
    fn writes_a_png() {
        let dir = std::env::temp_dir().join(format!("iw-boxplot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("box.png");
        let panel = BoxPanel {
            caption: "LIC".into(),
            boxes: vec![
                BoxSeries {
                    label: "surf".into(),
                    values: vec![10.0, 50.0, 70.0],
                },
                BoxSeries {
                    label: "lsac".into(),
                    values: vec![],
                },
            ],
        };
        plot_boxes(&path, "t", "repeatability (%)", 0.0..100.0, &[panel]).unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
