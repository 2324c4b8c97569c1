//! The comparison figure of `etp fronts`: one curve per synthesis of one
//! scenario (one radio channel or trigger family each), least expected
//! energy per episode against P_tar, with each synthesis's certified curve
//! dashed in the same colour; one panel per bound on P_coll. Each synthesis
//! has its series' hue (and line, past the palette's six hues).

use crate::style::{self, text};
use crate::{Result, plot_error};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// One synthesis's curves at one bound on P_coll.
#[derive(Debug, Clone)]
pub struct Curve {
    pub dir: PathBuf,
    /// The legend: the channel in `Radio::describe`'s words, the trigger
    /// family, or both.
    pub label: String,
    /// (P_tar, least energy), increasing P_tar: mixtures of the nominal
    /// front's vertices.
    pub points: Vec<(f64, f64)>,
    /// (certified P_tar, certified energy) corners of the certified front
    /// (front.json `certified`, at its confidence), drawn dashed; empty
    /// when the front has none within the bound.
    pub certified: Vec<(f64, f64)>,
    /// The predicted front under the panel's bound (front.json `predicted`,
    /// docs/MODEL.md §7.5): the strategies etp returns, at their
    /// predictions; empty when the synthesis has none for this bound.
    pub predicted: Vec<PredictedMark>,
}

/// A point of the predicted front as the figure draws it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictedMark {
    pub p_target: f64,
    pub energy: f64,
    /// 95 % half-widths.
    pub p_target_ci95: f64,
    pub energy_ci95: f64,
    /// The request was met (else: the closest strategy found).
    pub met: bool,
}

/// One panel: the curves of every synthesis at one bound on P_coll.
#[derive(Debug, Clone)]
pub struct Panel {
    pub max_collision: Option<f64>,
    pub curves: Vec<Curve>,
}

/// Write the figure to `stem.png` and `stem.svg`: one panel per bound,
/// side by side. `what` names the comparison in the title ("the radio",
/// "trigger families").
pub fn fronts_plot(scenario: &str, what: &str, panels: &[Panel], stem: &Path) -> Result<()> {
    let n = panels.len().max(1) as u32;
    super::png_and_svg(
        &FrontsFigure {
            scenario,
            what,
            panels,
        },
        stem,
        (if n == 1 { 880 } else { 820 * n }, 720),
    )
}

struct FrontsFigure<'a> {
    scenario: &'a str,
    what: &'a str,
    panels: &'a [Panel],
}

impl super::Figure for FrontsFigure<'_> {
    fn title(&self) -> Option<String> {
        Some(format!(
            "What {} cost{} ({}): least expected energy per P_tar",
            self.what,
            if self.what.ends_with('s') { "" } else { "s" },
            self.scenario
        ))
    }
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
        let cells = area.split_evenly((1, self.panels.len().max(1)));
        // One scale for every panel, so that they compare.
        let all = self
            .panels
            .iter()
            .flat_map(|p| p.curves.iter())
            .flat_map(|c| {
                c.points.iter().chain(c.certified.iter()).copied().chain(
                    c.predicted
                        .iter()
                        .map(|m| (m.p_target, m.energy + m.energy_ci95)),
                )
            });
        let (mut t_lo, mut t_hi, mut e_hi) = (1.0f64, 0.0f64, 1.0f64);
        for (t, en) in all {
            t_lo = t_lo.min(t);
            t_hi = t_hi.max(t);
            e_hi = e_hi.max(en);
        }
        if t_lo >= t_hi {
            t_lo = (t_hi - 0.05).max(0.0);
        }
        let pad = 0.03 * (t_hi - t_lo);
        for (panel, cell) in self.panels.iter().zip(&cells) {
            let bound = match panel.max_collision {
                Some(c) => format!("P_coll ≤ {c}"),
                None => "any P_coll".to_string(),
            };
            let mut chart = ChartBuilder::on(cell)
                .caption(
                    format!("{bound}: solid MDP front, dashed certified (95 %), ± predicted"),
                    ("sans-serif", text::CAPTION),
                )
                .margin(20)
                .x_label_area_size(60)
                .y_label_area_size(85)
                .build_cartesian_2d((t_lo - pad)..(t_hi + pad).min(1.0 + pad), 0.0..e_hi * 1.08)
                .map_err(e)?;
            crate::draw_axes(
                &mut chart,
                "P_tar (probability of reaching the target)",
                "least energy per episode (attempts × cost)",
            )?;
            for (i, c) in panel.curves.iter().enumerate() {
                let look = style::series(i);
                let colour = look.0;
                let sample = crate::draw_line(&mut chart, &c.points, look, 2)?;
                chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                    .map_err(e)?
                    .label(match (c.certified.is_empty(), c.predicted.is_empty()) {
                        (true, true) => format!("{} (none certified; no predicted)", c.label),
                        (true, false) => format!("{} (none certified)", c.label),
                        (false, true) => format!("{} (no predicted front)", c.label),
                        (false, false) => c.label.clone(),
                    })
                    .legend(move |p| sample.at(p));
                chart
                    .draw_series(
                        c.certified
                            .iter()
                            .map(|&p| Circle::new(p, 3, colour.filled())),
                    )
                    .map_err(e)?;
                crate::draw_line(
                    &mut chart,
                    &c.certified,
                    (colour, style::Line::Dashed(12, 8)),
                    2,
                )?;
                let at: Vec<(f64, f64)> =
                    c.predicted.iter().map(|m| (m.p_target, m.energy)).collect();
                chart
                    .draw_series(LineSeries::new(at, colour.stroke_width(4)))
                    .map_err(e)?;
                for m in &c.predicted {
                    let (x, y) = (m.p_target, m.energy);
                    chart
                        .draw_series([ErrorBar::new_vertical(
                            x,
                            y - m.energy_ci95,
                            y,
                            y + m.energy_ci95,
                            colour.stroke_width(2),
                            8,
                        )])
                        .map_err(e)?;
                    chart
                        .draw_series([ErrorBar::new_horizontal(
                            y,
                            x - m.p_target_ci95,
                            x,
                            x + m.p_target_ci95,
                            colour.stroke_width(2),
                            8,
                        )])
                        .map_err(e)?;
                    let style = if m.met {
                        colour.filled()
                    } else {
                        colour.stroke_width(2)
                    };
                    chart
                        .draw_series([Circle::new((x, y), 5, style)])
                        .map_err(e)?;
                }
            }
            crate::draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, 0.8)?;
        }
        Ok(())
    }
}
