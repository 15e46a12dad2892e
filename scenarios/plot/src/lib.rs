//! PNG plots for the experiments: the pictures people look at.
//!
//! Organization: one module per kind of figure; [`register_fonts`] runs once before any text is
//! drawn, so plots look the same on every machine whatever fonts it has installed.
#![warn(missing_docs)]

use std::sync::Once;

pub use plotters;

pub mod boxplot;
pub mod curves;
pub mod paths;
pub mod trajectory;

static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Registers the embedded DejaVu Sans as `sans-serif` (idempotent).
pub fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for style in [
            plotters::style::FontStyle::Normal,
            plotters::style::FontStyle::Bold,
            plotters::style::FontStyle::Italic,
            plotters::style::FontStyle::Oblique,
        ] {
            // The embedded font is a valid TTF, so registration cannot fail on its bytes.
            let _ = plotters::style::register_font("sans-serif", style, FONT);
        }
    });
}

/// The legend box of every figure: white, framed, 13 px labels, at `position`; a drawing
/// error names the file being drawn, `path`.
pub(crate) fn draw_legend<'a, DB, CT>(
    chart: &mut plotters::prelude::ChartContext<'a, DB, CT>,
    position: plotters::prelude::SeriesLabelPosition,
    path: &std::path::Path,
) -> Result<(), PlotError>
where
    DB: plotters::prelude::DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: plotters::coord::CoordTranslate,
{
    use plotters::prelude::{BLACK, Color, WHITE};
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(|e| PlotError::draw(path, e))
}

/// A legend entry's key for a line series: a 20 px stroke in `style`.
pub(crate) fn line_key(
    style: impl Into<plotters::style::ShapeStyle>,
) -> impl Fn((i32, i32)) -> plotters::element::PathElement<(i32, i32)> {
    let style = style.into();
    move |(x, y)| plotters::element::PathElement::new([(x, y), (x + 20, y)], style)
}

/// Why a plot could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// The drawing backend failed (usually writing the PNG).
    #[error("drawing {path}: {source}")]
    Draw {
        /// Output file.
        path: String,
        /// What plotters said (a `DrawingAreaErrorKind` of the backend's error), kept whole;
        /// boxed because its type names the backend.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
}

impl PlotError {
    /// Wraps a drawing error with the file it was drawing.
    pub fn draw(
        path: &std::path::Path,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        PlotError::Draw {
            path: path.display().to_string(),
            source: Box::new(source),
        }
    }
}
