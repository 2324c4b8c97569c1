//! The figure of `etp run --plot` and `etp replay --plot`: measured against
//! predicted, per sensor (energy per episode) and per outcome (P_tar,
//! P_coll, P_free), measured values with their 95 % intervals (PNG + SVG).

use anyhow::{Context, Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One measured quantity beside its prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct Bar {
    pub name: String,
    pub measured: f64,
    /// 95 % half-width of `measured`.
    pub ci95: f64,
    pub predicted: Option<f64>,
}

/// What the figure shows.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFigure {
    /// `run r1 · open-2d · constant δ = 1.05 · 200 episodes`.
    pub title: String,
    /// Where the per-sensor prediction comes from.
    pub prediction_note: String,
    pub sensors: Vec<Bar>,
    pub outcomes: Vec<Bar>,
}

/// Mean and 95 % half-width (normal approximation) of `xs`.
pub fn mean_ci(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    if xs.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = xs.iter().sum::<f64>() / n;
    if xs.len() < 2 {
        return (m, 0.0);
    }
    let var = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, 1.96 * (var / n).sqrt())
}

/// A proportion `k / n` with its 95 % half-width (normal approximation).
pub fn proportion(k: u64, n: u64) -> (f64, f64) {
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let p = k as f64 / n as f64;
    (p, 1.96 * (p * (1.0 - p) / n as f64).sqrt())
}

/// Write `stem.png` and `stem.svg`.
pub fn report_plot(fig: &RunFigure, stem: &Path) -> Result<()> {
    crate::plot::register_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, (1200, 560)).into_drawing_area();
        draw(&root, fig)?;
        root.present()
            .with_context(|| format!("writing {}", png.display()))?;
    }
    let root = SVGBackend::new(&svg, (1200, 560)).into_drawing_area();
    draw(&root, fig)?;
    root.present()
        .with_context(|| format!("writing {}", svg.display()))?;
    Ok(())
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &RunFigure) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |x: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {x:?}");
    root.fill(&WHITE).map_err(e)?;
    let area = root.titled(&fig.title, ("sans-serif", 20)).map_err(e)?;
    let (left, right) = area.split_horizontally(740);
    let top = fig
        .sensors
        .iter()
        .map(|b| (b.measured + b.ci95).max(b.predicted.unwrap_or(0.0)))
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

/// A strategy label without its parenthesised details, at most 50 characters.
pub fn short_label(label: &str) -> String {
    let head = label.split(" (").next().unwrap_or(label);
    short_to(head, 50)
}

fn short_to(s: &str, n: usize) -> String {
    let t: String = s.chars().take(n).collect();
    if t.len() < s.len() {
        format!("{t}…")
    } else {
        t
    }
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
    // The largest value the quantity can take (1 for a probability): a
    // normal-approximation interval is cut there, not drawn past it.
    cap: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |x: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {x:?}");
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
    // Error bars: a vertical line and two caps per measured value.
    chart
        .draw_series(bars.iter().enumerate().flat_map(|(i, b)| {
            let x = i as f64 - 0.12;
            let (lo, hi) = (
                (b.measured - b.ci95).max(0.0),
                (b.measured + b.ci95).min(cap),
            );
            let w = 0.06;
            [
                PathElement::new(vec![(x, lo), (x, hi)], blue.stroke_width(2)),
                PathElement::new(vec![(x - w, lo), (x + w, lo)], blue.stroke_width(2)),
                PathElement::new(vec![(x - w, hi), (x + w, hi)], blue.stroke_width(2)),
            ]
        }))
        .map_err(e)?
        .label("measured, 95 % interval")
        .legend(move |(x, y)| Circle::new((x, y), 4, blue.filled()));
    chart
        .draw_series(
            bars.iter()
                .enumerate()
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
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals() {
        let (m, h) = mean_ci(&[1.0, 3.0]);
        assert_eq!(m, 2.0);
        assert!((h - 1.96 * (2.0f64 / 2.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_ci(&[5.0]), (5.0, 0.0));
        let (p, h) = proportion(50, 100);
        assert_eq!(p, 0.5);
        assert!((h - 0.098).abs() < 1e-12);
    }
}
