//! The front figure: for a few bounds on P_coll, the (energy, P_tar)
//! frontier of the front's vertices within the bound, with the constant-δ
//! baselines, the certified front and the Method 1 front; over them, where
//! `front.json` holds it, the predicted front (the strategies etp returns,
//! at their predictions with ±). Each series has its own hue of the one
//! palette; the references (baselines, certified front) are black; the δ
//! labels and the legend are placed off the curves.

use crate::labels::{self, Rect};
use crate::style::{self, text};
use crate::{Result, plot_error};
use etp_synthesis::pareto::ParetoFront;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// Write the front plot to `stem.png` and `stem.svg`.
pub fn front_plot(front: &ParetoFront, stem: &Path) -> Result<()> {
    super::png_and_svg(&FrontFigure(front), stem, (880, 660))
}

struct FrontFigure<'a>(&'a ParetoFront);

impl super::Figure for FrontFigure<'_> {
    fn title(&self) -> Option<String> {
        Some(if self.0.predicted.is_empty() {
            format!(
                "Pareto front of {} on its MDP (selection-time values)",
                self.0.scenario_name
            )
        } else {
            format!(
                "Pareto front of {}: etp's strategies as predicted",
                self.0.scenario_name
            )
        })
    }
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_front(area, self.0).map(|_| ())
    }
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// What the front's panel put where, in pixels: the curves (polylines),
/// the boxes of the δ labels and of the legend.
#[derive(Debug, Default)]
pub(crate) struct Placed {
    pub(crate) lines: Vec<Vec<(i32, i32)>>,
    pub(crate) labels: Vec<Rect>,
    pub(crate) legend: Option<Rect>,
}

/// The front's panel in `area` (under the title).
pub(crate) fn draw_front<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    front: &ParetoFront,
) -> Result<Placed>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let certified = certified_frontier(front);
    let (e_max, y_lo) = ranges(front, &certified);
    // With the predicted front drawn, the caption says what the MDP's
    // curves are: values at selection time, optimistic for the strategy
    // that runs (docs/MODEL.md §7.5).
    let caption = if front.predicted.is_empty() {
        format!(
            "{} vertices, certified to ε = {:.1e} (energy {:.1e}); curves: non-dominated in this plane",
            front.vertices.len(),
            front.epsilon,
            front.epsilon_energy
        )
    } else {
        format!(
            "MDP: {} vertices, values at selection time (optimistic for the strategy that runs)",
            front.vertices.len()
        )
    };
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", text::CAPTION))
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..e_max, y_lo..1.005)
        .map_err(e)?;
    crate::draw_axes(
        &mut chart,
        "expected energy per episode (transmissions × cost)",
        "P_tar (probability, reaching the target)",
    )?;
    let mut lines = draw_bounds(&mut chart, front)?;
    let n_series = lines.len();
    lines.extend(draw_references(&mut chart, front, &certified, n_series)?);
    lines.extend(draw_predicted(&mut chart, front, n_series + 1)?);
    let mut placed = Placed {
        lines: lines
            .iter()
            .map(|l| l.iter().map(|p| chart.backend_coord(p)).collect())
            .collect(),
        ..Placed::default()
    };
    let ((px, py), (pw, ph)) = (
        chart.plotting_area().get_base_pixel(),
        chart.plotting_area().dim_in_pixel(),
    );
    let plot = Rect {
        x0: px,
        y0: py,
        x1: px + pw as i32,
        y1: py + ph as i32,
    };
    let mut marks = placed.lines.clone();
    marks.extend(
        front
            .baselines
            .iter()
            .map(|b| vec![chart.backend_coord(&(b.objectives.energy, b.objectives.p_target))]),
    );
    let legend = legend_box(area, front, &marks, plot);
    let baselines: Vec<_> = front
        .baselines
        .iter()
        .filter(|b| b.objectives.p_target >= y_lo)
        .collect();
    let font: TextStyle = ("sans-serif", text::LABEL).into();
    let names: Vec<String> = baselines
        .iter()
        .map(|b| format!("δ = {}", b.delta.unwrap_or(f64::NAN)))
        .collect();
    let at: Vec<(i32, i32)> = baselines
        .iter()
        .map(|b| chart.backend_coord(&(b.objectives.energy, b.objectives.p_target)))
        .collect();
    let sizes: Vec<(u32, u32)> = names
        .iter()
        .map(|n| {
            area.estimate_text_size(n, &font)
                .unwrap_or((120, text::LABEL))
        })
        .collect();
    // The legend's box and the baselines' own triangles are curves to avoid too.
    let mut avoid = placed.lines.clone();
    avoid.extend(at.iter().map(|&p| vec![p]));
    if let Some((_, r)) = legend {
        avoid.extend(outline(r));
    }
    placed.labels = labels::place(&at, &sizes, &avoid, plot);
    let root = chart.plotting_area().strip_coord_spec();
    let base = root.get_base_pixel();
    for (name, r) in names.iter().zip(&placed.labels) {
        root.draw(&Text::new(
            name.clone(),
            (r.x0 - base.0, r.y0 - base.1),
            font.clone(),
        ))
        .map_err(e)?;
    }
    if let Some((corner, r)) = legend {
        crate::draw_legend(&mut chart, corner, 0.85)?;
        placed.legend = Some(r);
    }
    Ok(placed)
}

/// The four edges of a box as polylines.
fn outline(r: Rect) -> [Vec<(i32, i32)>; 2] {
    [
        vec![(r.x0, r.y0), (r.x1, r.y0), (r.x1, r.y1)],
        vec![(r.x1, r.y1), (r.x0, r.y1), (r.x0, r.y0)],
    ]
}

/// The certified front (docs/MODEL.md §4.1): its points non-dominated in
/// the (energy, P_tar) plane.
fn certified_frontier(front: &ParetoFront) -> Vec<(f64, f64)> {
    frontier_of(
        front
            .certified
            .iter()
            .flat_map(|c| &c.points)
            .filter(|p| !p.dominated)
            .map(|p| (p.energy_high, p.p_target_low)),
    )
}

/// The energy axis' top and the P_tar axis' bottom: every vertex,
/// baseline and predicted ± in view, the certified points down to 0.2
/// below the nominal range.
fn ranges(front: &ParetoFront, certified: &[(f64, f64)]) -> (f64, f64) {
    let all: Vec<(f64, f64)> = front
        .vertices
        .iter()
        .map(|v| &v.objectives)
        .chain(front.baselines.iter().map(|b| &b.objectives))
        .map(|o| (o.energy, o.p_target))
        .chain(front.predicted.iter().flat_map(|c| &c.points).map(|p| {
            (
                p.predicted.energy + p.predicted_ci95.energy,
                p.predicted.p_target - p.predicted_ci95.p_target,
            )
        }))
        .collect();
    let e_max = all.iter().chain(certified).map(|p| p.0).fold(1.0, f64::max) * 1.12;
    let t_nominal = all.iter().map(|p| p.1).fold(1.0, f64::min);
    let t_min = certified
        .iter()
        .map(|p| p.1)
        .fold(t_nominal, f64::min)
        .max(t_nominal - 0.2);
    (e_max, (t_min - 0.02).max(0.0))
}

/// One curve per P_coll bound: the (energy, P_tar) frontier of the
/// vertices whose P_coll is within the bound (only the non-dominated
/// vertices in that plane; mixtures lie on the segments between them), in
/// the palette's series styles; the curves drawn.
fn draw_bounds<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    front: &ParetoFront,
) -> Result<Vec<Vec<(f64, f64)>>>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let mut lines = Vec::new();
    for (i, b) in collision_bounds(front).iter().enumerate() {
        let look = style::series(i);
        let curve = frontier(
            front
                .vertices
                .iter()
                .map(|v| &v.objectives)
                .filter(|o| o.p_collision <= *b + 1e-12),
        );
        let label = if *b >= 1.0 {
            format!("MDP, any P_coll ({} vertices)", curve.len())
        } else {
            format!("MDP, P_coll ≤ {b} ({} vertices)", curve.len())
        };
        let sample = crate::draw_line(chart, &curve, look, 3)?;
        chart
            .draw_series(curve.iter().map(|&p| Circle::new(p, 3, look.0.filled())))
            .map_err(e)?
            .label(label)
            .legend(move |p| sample.at(p));
        lines.push(curve);
    }
    Ok(lines)
}

/// The baselines (black triangles), the certified front (black, dashed,
/// hollow squares) and the Method 1 front (crosses of series `method1`);
/// the curves drawn.
fn draw_references<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    front: &ParetoFront,
    certified: &[(f64, f64)],
    method1: usize,
) -> Result<Vec<Vec<(f64, f64)>>>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let mut lines = Vec::new();
    chart
        .draw_series(front.baselines.iter().map(|b| {
            let o = &b.objectives;
            TriangleMarker::new((o.energy, o.p_target), 9, BLACK.filled())
        }))
        .map_err(e)?
        .label("constant δ")
        .legend(|(x, y)| TriangleMarker::new((x, y), 8, BLACK.filled()));
    if let Some(c) = &front.certified {
        let sample = crate::draw_line(chart, certified, (BLACK, style::Line::Dashed(10, 6)), 2)?;
        chart
            .draw_series(certified.iter().map(|&(x, y)| {
                EmptyElement::at((x, y)) + Rectangle::new([(-3, -3), (3, 3)], BLACK.stroke_width(1))
            }))
            .map_err(e)?
            .label(format!(
                "certified ({:.0} %: upper energy, lower P_tar)",
                100.0 * c.confidence
            ))
            .legend(move |p| sample.at(p));
        lines.push(certified.to_vec());
    }
    if let Some(m1) = &front.kf_convergence {
        let colour = style::series(method1).0;
        let points = frontier(m1.vertices.iter().map(|v| &v.objectives));
        chart
            .draw_series(
                points
                    .iter()
                    .map(|&p| Cross::new(p, 6, colour.stroke_width(2))),
            )
            .map_err(e)?
            .label("Method 1 (KF convergence), any P_coll")
            .legend(move |(x, y)| Cross::new((x, y), 6, colour.stroke_width(2)));
        lines.extend(points.into_iter().map(|p| vec![p]));
    }
    Ok(lines)
}

/// The legend's place and box: of the four corners of `plot`, then of
/// every place on a 20-pixel grid inside it, the first whose box crosses
/// the fewest curves and points.
fn legend_box<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    front: &ParetoFront,
    lines: &[Vec<(i32, i32)>],
    plot: Rect,
) -> Option<(SeriesLabelPosition, Rect)> {
    let font: TextStyle = ("sans-serif", text::LEGEND).into();
    let mut entries: Vec<String> = collision_bounds(front)
        .iter()
        .map(|b| format!("MDP, P_coll ≤ {b} (0000 vertices)"))
        .collect();
    entries.push("constant δ".into());
    if front.certified.is_some() {
        entries.push("certified (95 %: upper energy, lower P_tar)".into());
    }
    if front.kf_convergence.is_some() {
        entries.push("Method 1 (KF convergence), any P_coll".into());
    }
    entries.extend(
        front
            .predicted
            .iter()
            .map(|_| "predicted front, P_coll ≤ 0.05: etp's strategies, ± 95 %".to_string()),
    );
    if front
        .predicted
        .iter()
        .flat_map(|c| &c.points)
        .any(|p| !p.met())
    {
        entries.push("hollow: out of reach (closest strategy found)".into());
    }
    // plotters' legend: the labels' lines, 30 pixels of samples, 10 of
    // margin all round.
    let width = entries
        .iter()
        .filter_map(|t| area.estimate_text_size(t, &font).ok())
        .map(|s| s.0)
        .max()? as i32
        + 55;
    let height = (entries.len() as i32) * (text::LEGEND as i32 * 5 / 4 + 1) + 22;
    let (w, h) = (plot.x1 - plot.x0 - width, plot.y1 - plot.y0 - height);
    let corners = [(w, h), (0, 0), (0, h), (w, 0)];
    let grid = (0..=h.max(0) / 20).flat_map(|j| (0..=w.max(0) / 20).map(move |i| (20 * i, 20 * j)));
    let boxed = |(x, y): (i32, i32)| Rect {
        x0: plot.x0 + x,
        y0: plot.y0 + y,
        x1: plot.x0 + x + width,
        y1: plot.y0 + y + height,
    };
    corners
        .into_iter()
        .chain(grid)
        .min_by_key(|&at| lines.iter().filter(|l| boxed(at).hit_by_line(l)).count())
        .map(|at| (SeriesLabelPosition::Coordinate(at.0, at.1), boxed(at)))
}

/// The predicted front (docs/MODEL.md §7.5), over the MDP's: each point the
/// strategy `etp strategy` returns for its request, at its prediction with
/// its 95 % ± in energy and P_tar, curve `k` in series `first + k`; a
/// hollow marker where the request was out of reach (the point is the
/// closest strategy found). The curves drawn.
fn draw_predicted<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    front: &ParetoFront,
    first: usize,
) -> Result<Vec<Vec<(f64, f64)>>>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let mut lines = Vec::new();
    for (i, curve) in front.predicted.iter().enumerate() {
        let look = style::series(first + i);
        let colour = look.0;
        let at: Vec<(f64, f64)> = curve
            .points
            .iter()
            .map(|p| (p.predicted.energy, p.predicted.p_target))
            .collect();
        let label = match curve.max_collision {
            Some(c) => format!("predicted front, P_coll ≤ {c}: etp's strategies, ± 95 %"),
            None => "predicted front: etp's strategies, ± 95 %".to_string(),
        };
        // A thin guide between the points: only the points are strategies.
        crate::draw_line(chart, &at, look, 1)?;
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(e)?
            .label(label)
            .legend(move |(x, y)| Circle::new((x, y), 6, colour.filled()));
        for p in &curve.points {
            let (x, y) = (p.predicted.energy, p.predicted.p_target);
            let (hx, hy) = (p.predicted_ci95.energy, p.predicted_ci95.p_target);
            let bar = colour.stroke_width(2);
            chart
                .draw_series([ErrorBar::new_vertical(x, y - hy, y, y + hy, bar, 8)])
                .map_err(e)?;
            chart
                .draw_series([ErrorBar::new_horizontal(y, x - hx, x, x + hx, bar, 8)])
                .map_err(e)?;
            let marker = if p.met() {
                Circle::new((x, y), 6, colour.filled())
            } else {
                Circle::new((x, y), 8, colour.stroke_width(3))
            };
            chart.draw_series([marker]).map_err(e)?;
        }
        lines.push(at);
    }
    if front
        .predicted
        .iter()
        .flat_map(|c| &c.points)
        .any(|p| !p.met())
    {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(e)?
            .label("hollow: out of reach (closest strategy found)")
            .legend(move |(x, y)| Circle::new((x, y), 7, BLACK.stroke_width(3)));
    }
    Ok(lines)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The front of winding-2d (a small synthesis, thinned): its baselines'
    /// δ labels sit beside curves at δ = 1.0518 and δ = 2.2365.
    fn fixture() -> ParetoFront {
        serde_json::from_str(include_str!("../tests/data/front-winding-2d.json"))
            .expect("the fixture is a front.json")
    }

    fn placed(front: &ParetoFront) -> Placed {
        crate::register_font();
        let mut buf = vec![0u8; 880 * 660 * 3];
        let root = BitMapBackend::with_buffer(&mut buf, (880, 660)).into_drawing_area();
        draw_front(&root, front).expect("drawn")
    }

    #[test]
    fn no_delta_label_crosses_a_curve_or_the_legend() {
        let front = fixture();
        let p = placed(&front);
        assert_eq!(p.labels.len(), front.baselines.len());
        assert!(p.lines.len() >= 4, "bound curves and the certified front");
        let legend = p.legend.expect("a legend");
        for (r, b) in p.labels.iter().zip(&front.baselines) {
            for line in &p.lines {
                assert!(!r.hit_by_line(line), "δ = {:?} at {r:?}", b.delta);
            }
            assert!(!r.overlaps(&legend), "δ = {:?} under the legend", b.delta);
        }
    }

    #[test]
    fn the_certified_front_is_not_in_a_bound_curve_colour() {
        // Bound curves take the palette's series; the certified front is black.
        for i in 0..collision_bounds(&fixture()).len() {
            assert_ne!(style::series(i).0, BLACK);
        }
    }
}
