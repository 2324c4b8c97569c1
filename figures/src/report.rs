//! The figure of `etp run --plot` and `etp replay plot`: measured against
//! predicted, per sensor (energy per episode) and per outcome (P_tar,
//! P_coll, P_free), measured values with their 95 % intervals (PNG + SVG).
//! Where the sensors' energies span a decade or more, their axis is
//! logarithmic, so that the small ones stay readable beside the large.

use crate::style::{self, text};
use crate::{Result, plot_error};
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use std::path::Path;

use etp_recording_tools::figure::short_to;
pub use etp_recording_tools::figure::{Bar, RunFigure, short_label};

/// Write `stem.png` and `stem.svg`.
pub fn report_plot(fig: &RunFigure, stem: &Path) -> Result<()> {
    crate::png_and_svg(&ReportFigure(fig), stem, (1200, 600))
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

/// The range of the sensors' energy axis when it is logarithmic: their
/// positive values (measured, interval ends, predicted) spanning a factor
/// of 10 or more; `None`: a linear axis from 0.
pub(crate) fn log_range(bars: &[Bar]) -> Option<(f64, f64)> {
    let values = bars.iter().flat_map(|b| {
        let (lo, hi) = b.interval.unwrap_or((b.measured, b.measured));
        [Some(b.measured), Some(lo), Some(hi), b.predicted]
    });
    let (lo, hi) = values
        .flatten()
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    // Whole decades, with headroom above for the legend.
    let decade = |v: f64| 10f64.powf(v.log10().floor());
    (hi.is_finite() && hi >= 10.0 * lo).then(|| (decade(lo), 10.0 * decade(hi * 4.0)))
}

/// The two panels in `area` (under the title).
fn draw<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, fig: &RunFigure) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let (left, right) = area.split_horizontally(720);
    let caption = format!("per sensor, predicted by {}", short(&fig.prediction_note));
    let desc = "energy per episode (transmissions × cost)";
    match log_range(&fig.sensors) {
        Some((lo, hi)) => panel(
            &left,
            &fig.sensors,
            (&caption, &format!("{desc}, log scale")),
            (lo..hi).log_scale(),
            (lo, f64::INFINITY),
        )?,
        None => {
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
                * 1.45;
            panel(
                &left,
                &fig.sensors,
                (&caption, desc),
                0.0..top,
                (0.0, f64::INFINITY),
            )?
        }
    }
    panel(
        &right,
        &fig.outcomes,
        ("outcomes", "probability (fraction of episodes)"),
        0.0..1.05,
        (0.0, 1.0),
    )?;
    Ok(())
}

/// The note shortened to fit a panel caption (the part before `(` or `:`).
fn short(note: &str) -> String {
    let head = note.split([':', '(']).next().unwrap_or(note).trim_end();
    short_to(head, 40)
}

fn panel<DB: DrawingBackend, Y>(
    area: &DrawingArea<DB, Shift>,
    bars: &[Bar],
    (caption, y_desc): (&str, &str),
    y: Y,
    // The range the quantity can take (0 to 1 for a probability; a Wilson
    // interval never leaves it, a mean's normal interval is cut at it; on a
    // log axis the bottom is the axis').
    (floor, cap): (f64, f64),
) -> Result<()>
where
    DB::ErrorType: 'static,
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let n = bars.len().max(1);
    let names: Vec<String> = bars.iter().map(|b| b.name.clone()).collect();
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", text::CAPTION))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(85)
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
        .y_labels(12)
        .y_label_formatter(&|v: &f64| format!("{}", (v * 1e3).round() / 1e3))
        .y_desc(y_desc)
        .label_style(("sans-serif", text::TICK))
        .axis_desc_style(("sans-serif", text::AXIS))
        .draw()
        .map_err(e)?;
    let (blue, orange) = (style::PALETTE[0], style::PALETTE[1]);
    // Error bars: a vertical line and two caps per measured value that has
    // an interval (none under two episodes: only its point).
    chart
        .draw_series(
            bars.iter()
                .enumerate()
                .filter_map(|(i, b)| Some((i, b.interval?)))
                .flat_map(|(i, (lo, hi))| {
                    let x = i as f64 - 0.12;
                    let (lo, hi) = (lo.max(floor), hi.min(cap));
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
                .filter(|(_, b)| b.measured.is_finite() && b.measured >= floor)
                .map(|(i, b)| Circle::new((i as f64 - 0.12, b.measured), 4, blue.filled())),
        )
        .map_err(e)?;
    chart
        .draw_series(bars.iter().enumerate().filter_map(|(i, b)| {
            b.predicted
                .filter(|&p| p >= floor)
                .map(|p| TriangleMarker::new((i as f64 + 0.12, p), 7, orange.filled()))
        }))
        .map_err(e)?
        .label("predicted")
        .legend(move |(x, y)| TriangleMarker::new((x, y), 6, orange.filled()));
    // Over the headroom of the energies; between P_tar (high) and P_coll,
    // P_free (low) for the outcomes.
    let corner = if cap > 1.0 {
        SeriesLabelPosition::UpperRight
    } else {
        SeriesLabelPosition::MiddleRight
    };
    crate::draw_legend(&mut chart, corner, 0.85)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bar(measured: f64) -> Bar {
        Bar {
            name: "s".into(),
            measured,
            interval: Some((0.9 * measured, 1.1 * measured)),
            predicted: Some(measured),
        }
    }

    #[test]
    fn energies_spanning_a_decade_get_a_log_axis() {
        // s0–s3 about 3 packets per episode, s4 about 42.
        let wide: Vec<Bar> = [3.0, 3.2, 2.9, 3.1, 42.0].map(bar).into();
        let (lo, hi) = log_range(&wide).expect("a log axis");
        assert!(lo < 0.9 * 2.9 && hi > 1.1 * 42.0);
        let narrow: Vec<Bar> = [3.0, 3.2, 2.9, 20.0].map(bar).into();
        assert_eq!(log_range(&narrow), None);
        // Zeros (a silent sensor) do not count as a decade.
        let zero: Vec<Bar> = [0.0, 3.0, 4.0].map(bar).into();
        assert_eq!(log_range(&zero), None);
    }
}
