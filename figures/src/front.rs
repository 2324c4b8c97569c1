//! The front figure: for a few bounds on P_coll, the (energy, P_tar)
//! frontier of the front's vertices within the bound, with the constant-δ
//! baselines, the certified front and the Method 1 front; over them, where
//! `front.json` holds it, the predicted front (the strategies etp returns,
//! at their predictions with ±).

use crate::{Result, plot_error};
use etp_synthesis::pareto::ParetoFront;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// Write the front plot to `stem.png` and `stem.svg`.
pub fn front_plot(front: &ParetoFront, stem: &Path) -> Result<()> {
    super::png_and_svg(&FrontFigure(front), stem, (1000, 700))
}

struct FrontFigure<'a>(&'a ParetoFront);

impl super::Figure for FrontFigure<'_> {
    fn title(&self) -> Option<String> {
        Some(if self.0.predicted.is_empty() {
            format!(
                "Pareto front of {} on its MDP (selection-time values), per bound on P_coll",
                self.0.scenario_name
            )
        } else {
            format!(
                "Pareto front of {}: etp's strategies as predicted, over the MDP's front",
                self.0.scenario_name
            )
        })
    }
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_front(area, self.0)
    }
}

/// The front's panel in `area` (under the title).
fn draw_front<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, front: &ParetoFront) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let all: Vec<(f64, f64, f64)> = front
        .vertices
        .iter()
        .map(|v| &v.objectives)
        .chain(front.baselines.iter().map(|b| &b.objectives))
        .map(|o| (o.energy, o.p_target, o.p_collision))
        .chain(front.predicted.iter().flat_map(|c| &c.points).map(|p| {
            (
                p.predicted.energy + p.predicted_ci95.energy,
                p.predicted.p_target - p.predicted_ci95.p_target,
                p.predicted.p_collision,
            )
        }))
        .collect();
    // The certified front (docs/MODEL.md §4.1): its points non-dominated in
    // the (energy, P_tar) plane.
    let certified: Vec<(f64, f64)> = frontier_of(
        front
            .certified
            .iter()
            .flat_map(|c| &c.points)
            .filter(|p| !p.dominated)
            .map(|p| (p.energy_high, p.p_target_low)),
    );
    let e_max = all
        .iter()
        .map(|p| p.0)
        .chain(certified.iter().map(|p| p.0))
        .fold(1.0, f64::max)
        * 1.12;
    // The certified points' P_tar is shown down to 0.2 below the nominal range.
    let t_nominal = all.iter().map(|p| p.1).fold(1.0, f64::min);
    let t_min = certified
        .iter()
        .map(|p| p.1)
        .fold(t_nominal, f64::min)
        .max(t_nominal - 0.2);
    let y_lo = (t_min - 0.02).max(0.0);
    let bounds = collision_bounds(front);
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "{} vertices of the 3-D front (P_tar, P_coll, energy), certified to ε = {:.1e} (energy {:.1e}); curves: its non-dominated vertices in the plane",
                front.vertices.len(),
                front.epsilon,
                front.epsilon_energy
            ),
            ("sans-serif", 13),
        )
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..e_max, y_lo..1.005)
        .map_err(e)?;
    crate::draw_axes(
        &mut chart,
        "expected energy per episode (transmissions × cost)",
        "P_tar (probability of reaching the target)",
        (15, 16),
    )?;
    // One curve per P_coll bound: the (energy, P_tar) frontier of the
    // vertices whose P_coll is within the bound (only the non-dominated
    // vertices in that plane; mixtures lie on the segments between them).
    let n = bounds.len().max(2) as f64;
    for (i, b) in bounds.iter().enumerate() {
        let colour = sequential(i as f64 / (n - 1.0));
        let curve = frontier(
            front
                .vertices
                .iter()
                .map(|v| &v.objectives)
                .filter(|o| o.p_collision <= *b + 1e-12),
        );
        let label = if *b >= 1.0 {
            format!(
                "MDP front, any P_coll ({} vertices; selection-time)",
                curve.len()
            )
        } else {
            format!(
                "MDP front, P_coll ≤ {b} ({} vertices; selection-time)",
                curve.len()
            )
        };
        chart
            .draw_series(LineSeries::new(curve.clone(), colour.stroke_width(2)))
            .map_err(e)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x - 12, y), (x + 12, y)], colour.stroke_width(3))
            });
        chart
            .draw_series(curve.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(e)?;
    }
    chart
        .draw_series(front.baselines.iter().map(|b| {
            let o = &b.objectives;
            TriangleMarker::new((o.energy, o.p_target), 8, BLACK.stroke_width(2))
        }))
        .map_err(e)?
        .label("constant δ baselines")
        .legend(|(x, y)| TriangleMarker::new((x, y), 6, BLACK.stroke_width(2)));
    chart
        .draw_series(
            front
                .baselines
                .iter()
                .filter(|b| b.objectives.p_target >= y_lo)
                .map(|b| {
                    let o = &b.objectives;
                    EmptyElement::at((o.energy, o.p_target))
                        + Text::new(
                            format!("δ = {}", b.delta.unwrap_or(f64::NAN)),
                            (8, 4),
                            ("sans-serif", 13),
                        )
                }),
        )
        .map_err(e)?;
    if let Some(c) = &front.certified {
        let purple = RGBColor(120, 0, 160);
        chart
            .draw_series(LineSeries::new(certified.clone(), purple.stroke_width(1)))
            .map_err(e)?;
        chart
            .draw_series(certified.iter().filter(|p| p.1 >= y_lo).map(|&(x, y)| {
                EmptyElement::at((x, y))
                    + Rectangle::new([(-2, -2), (2, 2)], purple.stroke_width(1))
            }))
            .map_err(e)?
            .label(format!(
                "certified front ({:.0} %: upper energy, lower P_tar)",
                100.0 * c.confidence
            ))
            .legend(move |(x, y)| {
                Rectangle::new([(x - 3, y - 3), (x + 3, y + 3)], purple.stroke_width(2))
            });
    }
    if let Some(m1) = &front.kf_convergence {
        chart
            .draw_series(
                frontier(m1.vertices.iter().map(|v| &v.objectives))
                    .into_iter()
                    .map(|p| Cross::new(p, 5, RGBColor(0, 120, 0).stroke_width(2))),
            )
            .map_err(e)?
            .label("Method 1 (KF convergence), any P_coll")
            .legend(|(x, y)| Cross::new((x, y), 5, RGBColor(0, 120, 0).stroke_width(2)));
    }
    draw_predicted(&mut chart, front)?;
    crate::draw_legend(&mut chart, SeriesLabelPosition::LowerRight, 14, 0.8)?;
    Ok(())
}

/// The predicted front (docs/MODEL.md §7.5), over the MDP's: each point the
/// strategy `etp strategy` returns for its request, at its prediction with
/// its 95 % ± in energy and P_tar; a hollow marker where the request was out
/// of reach (the point is the closest strategy found).
fn draw_predicted<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    front: &ParetoFront,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let styles = [
        RGBColor(200, 30, 30),
        RGBColor(230, 120, 0),
        RGBColor(150, 0, 90),
    ];
    for (i, curve) in front.predicted.iter().enumerate() {
        let colour = styles[i % styles.len()];
        let at: Vec<(f64, f64)> = curve
            .points
            .iter()
            .map(|p| (p.predicted.energy, p.predicted.p_target))
            .collect();
        let label = match curve.max_collision {
            Some(c) => format!("predicted front, P_coll ≤ {c}: etp's strategies, ± 95 %"),
            None => "predicted front: etp's strategies for requests across the range, ± 95 %"
                .to_string(),
        };
        // A thin guide between the points: only the points are strategies.
        chart
            .draw_series(LineSeries::new(at.clone(), colour.stroke_width(1)))
            .map_err(e)?
            .label(label)
            .legend(move |(x, y)| Circle::new((x, y), 6, colour.filled()));
        for p in &curve.points {
            let (x, y) = (p.predicted.energy, p.predicted.p_target);
            let (hx, hy) = (p.predicted_ci95.energy, p.predicted_ci95.p_target);
            chart
                .draw_series([ErrorBar::new_vertical(
                    x,
                    y - hy,
                    y,
                    y + hy,
                    colour.stroke_width(2),
                    8,
                )])
                .map_err(e)?;
            chart
                .draw_series([ErrorBar::new_horizontal(
                    y,
                    x - hx,
                    x,
                    x + hx,
                    colour.stroke_width(2),
                    8,
                )])
                .map_err(e)?;
            let marker = if p.met() {
                Circle::new((x, y), 6, colour.filled())
            } else {
                Circle::new((x, y), 8, colour.stroke_width(3))
            };
            chart.draw_series([marker]).map_err(e)?;
        }
    }
    if front
        .predicted
        .iter()
        .flat_map(|c| &c.points)
        .any(|p| !p.met())
    {
        let grey = RGBColor(200, 30, 30);
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(e)?
            .label("hollow: request out of reach (closest strategy found)")
            .legend(move |(x, y)| Circle::new((x, y), 7, grey.stroke_width(3)));
    }
    Ok(())
}

/// A few round bounds on P_coll spanning the front's vertices, then 1 (any).
fn collision_bounds(front: &ParetoFront) -> Vec<f64> {
    let mut c: Vec<f64> = front
        .vertices
        .iter()
        .map(|v| v.objectives.p_collision)
        .collect();
    c.sort_by(f64::total_cmp);
    let Some(&hi) = c.last() else {
        return vec![1.0];
    };
    let mut out: Vec<f64> = Vec::new();
    for q in [0.05, 0.3, 0.6, 0.9] {
        let x = c[((c.len() - 1) as f64 * q) as usize];
        // Round up to 1, 2 or 5 × 10^k.
        if x <= 0.0 {
            continue;
        }
        let k = x.log10().floor();
        let r = [1.0, 2.0, 5.0, 10.0]
            .iter()
            .map(|m| m * 10f64.powf(k))
            .find(|&r| r >= x * (1.0 - 1e-9))
            .unwrap_or(x);
        let r = format!("{r:.1e}").parse().unwrap_or(r);
        if r < hi && out.last().is_none_or(|&l| r > l) {
            out.push(r);
        }
    }
    out.push(1.0);
    out
}

/// The non-dominated (energy ↓, P_tar ↑) points of the objectives, by energy.
fn frontier<'a>(
    points: impl Iterator<Item = &'a etp_synthesis::pareto::policy::Objectives>,
) -> Vec<(f64, f64)> {
    frontier_of(points.map(|o| (o.energy, o.p_target)))
}

/// The non-dominated (energy ↓, P_tar ↑) points of `(energy, P_tar)`, by energy.
fn frontier_of(points: impl Iterator<Item = (f64, f64)>) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> = points.collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for q in p {
        if out.last().is_none_or(|l| q.1 > l.1) {
            out.push(q);
        }
    }
    out
}

/// Dark blue → teal → yellow (viridis-like) on [0, 1].
fn sequential(t: f64) -> RGBColor {
    let stops = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (220.0, 190.0, 30.0),
    ];
    let t = t.clamp(0.0, 1.0) * (stops.len() - 1) as f64;
    let i = (t.floor() as usize).min(stops.len() - 2);
    let f = t - i as f64;
    let (a, b) = (stops[i], stops[i + 1]);
    let mix = |x: f64, y: f64| (x + (y - x) * f) as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}
