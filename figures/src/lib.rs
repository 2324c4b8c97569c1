//! `etp-figures`: every figure etpareto draws (plotters, PNG and SVG), as a
//! library the `etp` commands call with their data.
//!
//! A short tour:
//!
//! * [`front_plot`] (`front.rs`) — the Pareto front, P_tar vs energy per
//!   bound on P_coll, baselines marked (`etp synthesize`).
//! * [`fronts_plot`] (`fronts.rs`) — several fronts of one scenario, one
//!   [`Curve`] per synthesis (radio channel or trigger family) with its
//!   certified curve dashed, one [`Panel`] per bound on P_coll (`etp fronts`).
//! * [`trigger_curves_plot`] (`trigger_curves.rs`) — estimation error (RMSE,
//!   NEES/n) against the communication rate per trigger family, and the rate
//!   against δ with the closed forms (`etp trigger-curves`).
//! * [`map_plot`] (`map.rs`) — the scenario map with sampled trajectories
//!   coloured by the expected rate of the threshold in force (the paper's
//!   Fig. 4; `etp validate --plot`, `etp demo`).
//! * [`report_plot`] (`report.rs`) — a run's measured values against the
//!   predicted ones (`etp run --plot`, `etp replay plot`), from the data of
//!   `etp_recording_tools::figure`.
//!
//! All are written by `png_and_svg`, the one writer of a figure: white, the
//! figure's title (`Figure::title`) above its panels (`Figure::draw`), PNG
//! and SVG from one drawing. The chart parts every figure shares are drawn
//! once: `draw_axes` (descriptions and tick labels of two real axes) and
//! `draw_legend` (the framed legend box). Their colours, line styles and
//! text sizes are `style`'s: one palette of distinguishable hues, viridis
//! for a continuous quantity, text readable with each panel printed a
//! column wide. The font is
//! embedded (DejaVu Sans, see `assets/`), so plots render the same on a
//! machine without any installed fonts. Each figure kind has a golden image
//! in `tests/golden/` that `tests/golden.rs` compares it with
//! (`ETP_UPDATE_GOLDEN=1` rewrites them after a deliberate change).

mod front;
mod fronts;
mod labels;
mod map;
mod report;
mod style;
mod trigger_curves;

pub use front::front_plot;
pub use fronts::{Curve, Panel, PredictedMark, fronts_plot};
pub use map::map_plot;
pub use report::{Bar, RunFigure, report_plot, short_label};
pub use trigger_curves::{FamilySeries, RatePoint, trigger_curves_plot};

use etp_files::write::{WriteError, write_via_temp};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// Why a figure could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// plotters refused to draw (its error rendered: its type depends on the
    /// backend).
    #[error("plot: {0}")]
    Plot(String),
    /// The finished figure could not be written.
    #[error("writing {}", path.display())]
    Write {
        path: PathBuf,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// A figure's result.
pub type Result<T> = std::result::Result<T, FigureError>;

/// A drawing error of plotters as a [`FigureError::Plot`].
pub(crate) fn plot_error<E: std::fmt::Debug>(e: E) -> FigureError {
    FigureError::Plot(format!("{e:?}"))
}

/// A white figure with its title: the area left for the panels.
fn titled_area<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<DrawingArea<DB, Shift>>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    root.fill(&WHITE).map_err(e)?;
    root.titled(title, ("sans-serif", style::text::TITLE))
        .map_err(e)
}

/// The axes of a chart of two real axes: their descriptions (each naming
/// its unit) and tick labels.
pub(crate) fn draw_axes<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    x_desc: &str,
    y_desc: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(("sans-serif", style::text::TICK))
        .axis_desc_style(("sans-serif", style::text::AXIS))
        .draw()
        .map_err(plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>)
}

/// The legend box of a chart: framed, on white of opacity `opacity`, in
/// the corner `at`.
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    at: SeriesLabelPosition,
    opacity: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(opacity))
        .border_style(BLACK)
        .label_font(("sans-serif", style::text::LEGEND))
        .position(at)
        .draw()
        .map_err(plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>)
}

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

pub(crate) fn register_font() {
    REGISTER.call_once(|| {
        // The bytes are a valid TTF shipped with the crate; failure would only
        // lose text, never the plot.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// A figure drawn the same way on any plotters backend (PNG and SVG).
pub(crate) trait Figure {
    /// The title [`png_and_svg`] writes above the panels (20 pt, on white);
    /// `None`: the figure titles itself.
    fn title(&self) -> Option<String>;
    /// The panels, in `area`: under the title, or the whole white figure.
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static;
}

/// A figure on a white `root`, under its title if it has one.
fn draw_figure<DB: DrawingBackend>(fig: &impl Figure, root: &DrawingArea<DB, Shift>) -> Result<()>
where
    DB::ErrorType: 'static,
{
    match fig.title() {
        Some(title) => fig.draw(&titled_area(root, &title)?),
        None => {
            root.fill(&WHITE)
                .map_err(plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>)?;
            fig.draw(root)
        }
    }
}

/// THE way every figure is written: `stem.png` and `stem.svg`, `size` pixels,
/// each drawn into a temporary sibling and renamed into place
/// (`etp_files::write::write_via_temp`: its folder checked, no
/// planted link followed).
pub(crate) fn png_and_svg(fig: &impl Figure, stem: &Path, size: (u32, u32)) -> Result<()> {
    register_font();
    let png = stem.with_extension("png");
    write_figure(&png, |tmp| {
        let root = BitMapBackend::new(tmp, size).into_drawing_area();
        draw_figure(fig, &root)?;
        root.present().map_err(|e| FigureError::Write {
            path: png.clone(),
            source: Box::new(e),
        })
    })?;
    let svg = stem.with_extension("svg");
    write_figure(&svg, |tmp| {
        let root = SVGBackend::new(tmp, size).into_drawing_area();
        draw_figure(fig, &root)?;
        root.present().map_err(|e| FigureError::Write {
            path: svg.clone(),
            source: Box::new(e),
        })
    })
}

/// One file of a figure through the workspace's one file writer: the
/// drawing's own [`FigureError`] comes back as it was, a refusal of the
/// file rule (its folder, a planted link, the rename) as
/// [`FigureError::Write`].
fn write_figure(path: &Path, draw: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    /// What the writer's closure can fail with: the drawing or the file.
    enum Failed {
        Drawing(FigureError),
        File(WriteError),
    }
    impl From<WriteError> for Failed {
        fn from(e: WriteError) -> Self {
            Failed::File(e)
        }
    }
    write_via_temp(path, |tmp| draw(tmp).map_err(Failed::Drawing)).map_err(|e| match e {
        Failed::Drawing(f) => f,
        Failed::File(e) => FigureError::Write {
            path: path.to_path_buf(),
            source: Box::new(e),
        },
    })
}

/// A series' line through `points` in its `line` style, `width` pixels:
/// what a legend entry of it shows is returned with it.
pub(crate) fn draw_line<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    points: &[(f64, f64)],
    (colour, line): (RGBColor, style::Line),
    width: u32,
) -> Result<LegendLine>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let st = colour.stroke_width(width);
    match line {
        style::Line::Solid => chart
            .draw_series(LineSeries::new(points.iter().copied(), st))
            .map_err(e)?,
        style::Line::Dashed(dash, gap) => chart
            .draw_series(DashedLineSeries::new(
                points.iter().copied(),
                dash as i32,
                gap as i32,
                st,
            ))
            .map_err(e)?,
    };
    Ok(LegendLine {
        colour,
        line,
        width,
    })
}

/// A legend entry's sample of a line: a short stroke in the line's style.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LegendLine {
    colour: RGBColor,
    line: style::Line,
    width: u32,
}

impl LegendLine {
    /// The sample centred at `(x, y)`: 28 pixels of the line, in two
    /// pieces with a gap when it is dashed.
    pub(crate) fn at<'a, DB: DrawingBackend + 'a>(
        self,
        (x, y): (i32, i32),
    ) -> impl IntoDynElement<'a, DB, (i32, i32)> {
        let gap = match self.line {
            style::Line::Solid => 0,
            style::Line::Dashed(_, g) => (g as i32).clamp(2, 6),
        };
        let st = self.colour.stroke_width(self.width + 1);
        EmptyElement::at((x, y))
            + PathElement::new(vec![(-14, 0), (-gap / 2, 0)], st)
            + PathElement::new(vec![(gap - gap / 2, 0), (14, 0)], st)
    }
}
