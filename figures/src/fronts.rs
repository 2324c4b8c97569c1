//! The radio-cost figure of `etp fronts`: one curve per synthesis (one
//! channel each), least expected energy per episode against P_tar at a fixed
//! bound on P_coll.

use crate::{Result, plot_error};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// One synthesis's curve: least energy per P_tar within the P_coll bound.
#[derive(Debug, Clone)]
pub struct Curve {
    pub dir: PathBuf,
    /// The channel the synthesis sampled under, in `Radio::describe`'s words.
    pub radio: String,
    /// (P_tar, least energy), increasing P_tar.
    pub points: Vec<(f64, f64)>,
}

/// Write the figure to `stem.png` and `stem.svg`.
pub fn fronts_plot(
    scenario: &str,
    curves: &[Curve],
    max_collision: Option<f64>,
    stem: &Path,
) -> Result<()> {
    super::png_and_svg(
        &FrontsFigure {
            scenario,
            curves,
            max_collision,
        },
        stem,
        (1000, 700),
    )
}

struct FrontsFigure<'a> {
    scenario: &'a str,
    curves: &'a [Curve],
    max_collision: Option<f64>,
}

/// Distinct colours (Okabe–Ito, readable by colour-blind readers).
const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];

impl super::Figure for FrontsFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
        root.fill(&WHITE).map_err(e)?;
        let all = self.curves.iter().flat_map(|c| c.points.iter());
        let (mut t_lo, mut t_hi, mut e_hi) = (1.0f64, 0.0f64, 1.0f64);
        for &(t, en) in all {
            t_lo = t_lo.min(t);
            t_hi = t_hi.max(t);
            e_hi = e_hi.max(en);
        }
        if t_lo >= t_hi {
            t_lo = (t_hi - 0.05).max(0.0);
        }
        let pad = 0.03 * (t_hi - t_lo);
        let bound = match self.max_collision {
            Some(c) => format!("P_coll ≤ {c}"),
            None => "any P_coll".to_string(),
        };
        let area = root
            .titled(
                &format!(
                    "What the radio costs ({}): least expected energy per P_tar, {bound}",
                    self.scenario
                ),
                ("sans-serif", 20),
            )
            .map_err(e)?;
        let mut chart = ChartBuilder::on(&area)
            .caption(
                "one curve per synthesis (`etp synthesize --loss … --estimator …`); mixtures of each front's vertices",
                ("sans-serif", 13),
            )
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d((t_lo - pad)..(t_hi + pad).min(1.0 + pad), 0.0..e_hi * 1.08)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("P_tar (probability of reaching the target)")
            .y_desc("least expected energy per episode (attempts × cost)")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(e)?;
        for (i, c) in self.curves.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            chart
                .draw_series(LineSeries::new(c.points.clone(), colour.stroke_width(2)))
                .map_err(e)?
                .label(c.radio.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x - 12, y), (x + 12, y)], colour.stroke_width(3))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(e)?;
        Ok(())
    }
}
