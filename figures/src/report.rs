//! The figure of `etp run --plot` and `etp replay plot`: measured against
//! predicted, per sensor (energy per episode) and per outcome (P_tar,
//! P_coll, P_free), measured values with their 95 % intervals (PNG + SVG).

use crate::{Result, plot_error};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

use etp_recording_tools::figure::short_to;
pub use etp_recording_tools::figure::{Bar, RunFigure, short_label};

/// Write `stem.png` and `stem.svg`.
pub fn report_plot(fig: &RunFigure, stem: &Path) -> Result<()> {
    crate::png_and_svg(&ReportFigure(fig), stem, (1200, 560))
}

struct ReportFigure<'a>(&'a RunFigure);

impl crate::Figure for ReportFigure<'_> {
    fn title(&self) -> Option<String> {
        Some(self.0.title.clone())
    }
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw(area, self.0)
    }
}

/// The two panels in `area` (under the title).
fn draw<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, fig: &RunFigure) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (left, right) = area.split_horizontally(740);
    let top = fig
        .sensors
        .iter()
        .map(|b| {
            b.interval
                .map_or(b.measured, |(_, hi)| hi)
                .max(b.predicted.unwrap_or(0.0))
        })
        .filter(|x| x.is_finite())
        .fold(1e-9, f64::max)
        * 1.15;
    panel(
        &left,
        &fig.sensors,
        &format!(
            "energy per episode, per sensor — predicted by {}",
            short(&fig.prediction_note)
        ),
        "energy per episode (transmissions × cost)",
        0.0..top,
        f64::INFINITY,
    )?;
    panel(
        &right,
        &fig.outcomes,
        "outcomes",
        "probability",
        0.0..1.05,
        1.0,
    )?;
    Ok(())
}

/// The note shortened to fit a panel caption (the part before `(` or `:`).
fn short(note: &str) -> String {
    let head = note.split([':', '(']).next().unwrap_or(note).trim_end();
    short_to(head, 64)
}

fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    bars: &[Bar],
    caption: &str,
    y_desc: &str,
    y: std::ops::Range<f64>,
    // The largest value the quantity can take (1 for a probability; a
    // Wilson interval never passes it, a mean's normal interval is cut at it
    // and at 0).
    cap: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let n = bars.len().max(1);
    let names: Vec<String> = bars.iter().map(|b| b.name.clone()).collect();
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 14))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.6..(n as f64 - 0.4), y)
        .map_err(e)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n)
        .x_label_formatter(&|x: &f64| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                names.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc(y_desc)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    let blue = RGBColor(31, 90, 180);
    let orange = RGBColor(230, 120, 0);
    // Error bars: a vertical line and two caps per measured value that has
    // an interval (none under two episodes: only its point).
    chart
        .draw_series(
            bars.iter()
                .enumerate()
                .filter_map(|(i, b)| Some((i, b.interval?)))
                .flat_map(|(i, (lo, hi))| {
                    let x = i as f64 - 0.12;
                    let (lo, hi) = (lo.max(0.0), hi.min(cap));
                    let w = 0.06;
                    [
                        PathElement::new(vec![(x, lo), (x, hi)], blue.stroke_width(2)),
                        PathElement::new(vec![(x - w, lo), (x + w, lo)], blue.stroke_width(2)),
                        PathElement::new(vec![(x - w, hi), (x + w, hi)], blue.stroke_width(2)),
                    ]
                }),
        )
        .map_err(e)?
        .label("measured, 95 % interval")
        .legend(move |(x, y)| Circle::new((x, y), 4, blue.filled()));
    chart
        .draw_series(
            bars.iter()
                .enumerate()
                .filter(|(_, b)| b.measured.is_finite())
                .map(|(i, b)| Circle::new((i as f64 - 0.12, b.measured), 4, blue.filled())),
        )
        .map_err(e)?;
    chart
        .draw_series(bars.iter().enumerate().filter_map(|(i, b)| {
            b.predicted
                .map(|p| TriangleMarker::new((i as f64 + 0.12, p), 7, orange.filled()))
        }))
        .map_err(e)?
        .label("predicted")
        .legend(move |(x, y)| TriangleMarker::new((x, y), 6, orange.filled()));
    crate::draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 13, 0.85)?;
    Ok(())
}
