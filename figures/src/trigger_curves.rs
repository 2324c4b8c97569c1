//! The literature's comparison of trigger families (`etp trigger-curves`):
//! estimation error against communication rate, one curve per family
//! through its thresholds δ — RMSE in one panel, NEES/n in the next — and
//! the rate against δ with each family's closed form where it has one.

use crate::fronts::{PALETTE, dashes};
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
    super::png_and_svg(&CurvesFigure { scenario, series }, stem, (1800, 640))
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
        let cells = area.split_evenly((1, 3));
        let pts = || self.series.iter().flat_map(|s| s.points.iter());
        let (r_lo, r_hi) = bounds(pts().flat_map(|p| [p.rate.0 - p.rate.1, p.rate.0 + p.rate.1]));
        let r_lo = r_lo.max(-0.02);
        type Pick = fn(&RatePoint) -> (f64, f64);
        let panels: [(&str, Pick, Option<f64>); 2] = [
            (
                "RMSE of the estimate ‖x − x̂‖ (scenario units)",
                |p| p.rmse,
                None,
            ),
            ("NEES/n (1 = consistent)", |p| p.nees, Some(1.0)),
        ];
        for (k, (desc, pick, reference)) in panels.into_iter().enumerate() {
            let (y_lo, y_hi) = bounds(
                pts()
                    .flat_map(|p| {
                        let (v, h) = pick(p);
                        [v - h, v + h]
                    })
                    .chain(reference),
            );
            let mut chart = ChartBuilder::on(&cells[k])
                .margin(18)
                .x_label_area_size(50)
                .y_label_area_size(70)
                .build_cartesian_2d(r_lo..r_hi, y_lo.max(0.0)..y_hi)
                .map_err(e)?;
            crate::draw_axes(
                &mut chart,
                "communication rate (transmissions per slot)",
                desc,
                (14, 15),
            )?;
            if let Some(r) = reference {
                chart
                    .draw_series(LineSeries::new(
                        vec![(r_lo, r), (r_hi, r)],
                        BLACK.mix(0.4).stroke_width(1),
                    ))
                    .map_err(e)?;
            }
            for (i, s) in self.series.iter().enumerate() {
                let colour = PALETTE[i % PALETTE.len()];
                let mut line: Vec<(f64, f64)> =
                    s.points.iter().map(|p| (p.rate.0, pick(p).0)).collect();
                line.sort_by(|a, b| a.0.total_cmp(&b.0));
                chart
                    .draw_series(LineSeries::new(line, colour.stroke_width(2)))
                    .map_err(e)?
                    .label(s.name.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x - 12, y), (x + 12, y)], colour.stroke_width(3))
                    });
                chart
                    .draw_series(s.points.iter().map(|p| {
                        let (v, h) = pick(p);
                        PathElement::new(
                            vec![(p.rate.0, v - h), (p.rate.0, v + h)],
                            colour.stroke_width(1),
                        )
                    }))
                    .map_err(e)?;
                chart
                    .draw_series(
                        s.points
                            .iter()
                            .map(|p| Circle::new((p.rate.0, pick(p).0), 3, colour.filled())),
                    )
                    .map_err(e)?;
            }
            crate::draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 13, 0.8)?;
        }
        // The rate against δ: measured (points) and closed form (dashed).
        let (d_lo, d_hi) = bounds(pts().map(|p| p.delta));
        let mut chart = ChartBuilder::on(&cells[2])
            .caption(
                "points: measured; dashed: closed form (stochastic; box and periodic share one)",
                ("sans-serif", 13),
            )
            .margin(18)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(d_lo.max(-0.05)..d_hi, 0.0..1.05)
            .map_err(e)?;
        crate::draw_axes(
            &mut chart,
            "threshold δ",
            "communication rate (transmissions per slot)",
            (14, 15),
        )?;
        for (i, s) in self.series.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            chart
                .draw_series(
                    dashes(&s.closed_form, 2)
                        .into_iter()
                        .map(|d| PathElement::new(d, colour.stroke_width(2))),
                )
                .map_err(e)?;
            chart
                .draw_series(
                    s.points
                        .iter()
                        .map(|p| Circle::new((p.delta, p.rate.0), 4, colour.filled())),
                )
                .map_err(e)?
                .label(s.name.clone())
                .legend(move |(x, y)| Circle::new((x, y), 4, colour.filled()));
        }
        crate::draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 13, 0.8)?;
        Ok(())
    }
}
