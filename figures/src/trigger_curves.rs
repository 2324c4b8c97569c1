//! The literature's comparison of trigger families (`etp trigger-curves`):
//! estimation error against communication rate, one curve per family
//! through its thresholds δ — RMSE in one panel, NEES/n in the next — and
//! the rate against δ with each family's closed form where it has one. A
//! family whose measured rate is the same at every δ (its points stack at
//! one rate) is drawn in rings over the others and named in a note under
//! the panels.

use crate::style::{self, text};
use crate::{Result, plot_error};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One simulated threshold of one family.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RatePoint {
    pub delta: f64,
    /// Measured transmissions per slot and its 95 % half-width.
    pub rate: (f64, f64),
    pub rmse: (f64, f64),
    pub nees: (f64, f64),
}

/// One family's points (increasing δ) and closed-form rate curve.
#[derive(Debug, Clone)]
pub struct FamilySeries {
    pub name: String,
    pub points: Vec<RatePoint>,
    /// (δ, expected rate) sampled densely; empty without a closed form.
    pub closed_form: Vec<(f64, f64)>,
}

/// Write the figure to `stem.png` and `stem.svg`.
pub fn trigger_curves_plot(scenario: &str, series: &[FamilySeries], stem: &Path) -> Result<()> {
    let notes = series.iter().filter_map(degenerate_note).count() as u32;
    super::png_and_svg(
        &CurvesFigure { scenario, series },
        stem,
        (1800, 680 + NOTE_LINE * notes),
    )
}

/// Height of a note's line under the panels.
const NOTE_LINE: u32 = 32;

/// The note of a family whose measured rate is the same (to 4 decimals) at
/// each of its two or more thresholds: against the rate its points stack
/// at one abscissa, a point rather than a curve.
pub(crate) fn degenerate_note(s: &FamilySeries) -> Option<String> {
    let first = s.points.first()?.rate.0;
    let same = s.points.len() >= 2
        && s.points
            .iter()
            .all(|p| format!("{:.4}", p.rate.0) == format!("{first:.4}"));
    same.then(|| {
        format!(
            "Note: {} sends at rate {first:.4} at every δ ({} thresholds): its points stack at that rate (rings).",
            s.name,
            s.points.len()
        )
    })
}

struct CurvesFigure<'a> {
    scenario: &'a str,
    series: &'a [FamilySeries],
}

fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-9 {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

impl super::Figure for CurvesFigure<'_> {
    fn title(&self) -> Option<String> {
        Some(format!(
            "Trigger families on {}: estimation error vs communication rate (one point per δ, ± 95 %)",
            self.scenario
        ))
    }
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
        let notes: Vec<String> = self.series.iter().filter_map(degenerate_note).collect();
        let (_, h) = area.dim_in_pixel();
        let (area, below) = area.split_vertically(h.saturating_sub(NOTE_LINE * notes.len() as u32));
        for (k, note) in notes.iter().enumerate() {
            below
                .draw(&Text::new(
                    note.clone(),
                    (30, NOTE_LINE as i32 * k as i32),
                    ("sans-serif", text::LABEL),
                ))
                .map_err(e)?;
        }
        let cells = area.split_evenly((1, 3));
        let pts = || self.series.iter().flat_map(|s| s.points.iter());
        let (r_lo, r_hi) = bounds(pts().flat_map(|p| [p.rate.0 - p.rate.1, p.rate.0 + p.rate.1]));
        let r_lo = r_lo.max(-0.02);
        type Pick = fn(&RatePoint) -> (f64, f64);
        let panels: [(&str, &str, Pick, Option<f64>); 2] = [
            (
                "estimation error against rate",
                "RMSE ‖x − x̂‖ (scenario units)",
                |p| p.rmse,
                None,
            ),
            (
                "consistency against rate",
                "NEES/n (1 = consistent; no unit)",
                |p| p.nees,
                Some(1.0),
            ),
        ];
        for (k, (caption, desc, pick, reference)) in panels.into_iter().enumerate() {
            let (y_lo, y_hi) = bounds(
                pts()
                    .flat_map(|p| {
                        let (v, h) = pick(p);
                        [v - h, v + h]
                    })
                    .chain(reference),
            );
            let mut chart = ChartBuilder::on(&cells[k])
                .caption(caption, ("sans-serif", text::CAPTION))
                .margin(18)
                .x_label_area_size(60)
                .y_label_area_size(85)
                .build_cartesian_2d(r_lo..r_hi, y_lo.max(0.0)..y_hi)
                .map_err(e)?;
            crate::draw_axes(&mut chart, "rate (transmissions per slot)", desc)?;
            if let Some(r) = reference {
                chart
                    .draw_series(LineSeries::new(
                        vec![(r_lo, r), (r_hi, r)],
                        BLACK.mix(0.4).stroke_width(1),
                    ))
                    .map_err(e)?;
            }
            // The stacked families last, in rings over the others.
            let mut order: Vec<(usize, &FamilySeries)> = self.series.iter().enumerate().collect();
            order.sort_by_key(|(_, s)| degenerate_note(s).is_some());
            for (i, s) in order {
                let look = style::series(i);
                let colour = look.0;
                let mut line: Vec<(f64, f64)> =
                    s.points.iter().map(|p| (p.rate.0, pick(p).0)).collect();
                line.sort_by(|a, b| a.0.total_cmp(&b.0));
                let sample = crate::draw_line(&mut chart, &line, look, 2)?;
                chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                    .map_err(e)?
                    .label(s.name.clone())
                    .legend(move |p| sample.at(p));
                chart
                    .draw_series(s.points.iter().map(|p| {
                        let (v, h) = pick(p);
                        PathElement::new(
                            vec![(p.rate.0, v - h), (p.rate.0, v + h)],
                            colour.stroke_width(1),
                        )
                    }))
                    .map_err(e)?;
                let marker = |at: (f64, f64)| {
                    if degenerate_note(s).is_some() {
                        Circle::new(at, 8, colour.stroke_width(3))
                    } else {
                        Circle::new(at, 4, colour.filled())
                    }
                };
                chart
                    .draw_series(s.points.iter().map(|p| marker((p.rate.0, pick(p).0))))
                    .map_err(e)?;
            }
            crate::draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 0.8)?;
        }
        // The rate against δ: measured (points) and closed form (dashed).
        let (d_lo, d_hi) = bounds(pts().map(|p| p.delta));
        let mut chart = ChartBuilder::on(&cells[2])
            .caption(
                "rate against δ: dots measured, dashed closed form",
                ("sans-serif", text::CAPTION),
            )
            .margin(18)
            .x_label_area_size(60)
            .y_label_area_size(85)
            .build_cartesian_2d(d_lo.max(-0.05)..d_hi, 0.0..1.05)
            .map_err(e)?;
        crate::draw_axes(
            &mut chart,
            "threshold δ (noise standard deviations)",
            "rate (transmissions per slot)",
        )?;
        for (i, s) in self.series.iter().enumerate() {
            let colour = style::series(i).0;
            crate::draw_line(
                &mut chart,
                &s.closed_form,
                (colour, style::Line::Dashed(10, 6)),
                2,
            )?;
            chart
                .draw_series(
                    s.points
                        .iter()
                        .map(|p| Circle::new((p.delta, p.rate.0), 4, colour.filled())),
                )
                .map_err(e)?
                .label(s.name.clone());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn family(rates: &[f64]) -> FamilySeries {
        FamilySeries {
            name: "variance".into(),
            points: rates
                .iter()
                .enumerate()
                .map(|(i, &r)| RatePoint {
                    delta: 1.0 + i as f64,
                    rate: (r, 0.0),
                    rmse: (0.02, 0.001),
                    nees: (1.0, 0.01),
                })
                .collect(),
            closed_form: Vec::new(),
        }
    }

    #[test]
    fn a_family_of_one_rate_gets_a_note() {
        let note = degenerate_note(&family(&[1.0; 4])).expect("a note");
        assert!(note.contains("variance sends at rate 1.0000 at every δ (4 thresholds)"));
        assert_eq!(degenerate_note(&family(&[0.4, 0.3, 0.2])), None);
        assert_eq!(degenerate_note(&family(&[0.5])), None);
    }
}
