//! Figures (plotters, PNG and SVG): the Pareto front (P_tar vs energy coloured
//! by P_coll, baselines marked) and the scenario map with sampled trajectories
//! coloured by the expected rate of the threshold in force (the paper's Fig. 4).
//!
//! The font is embedded (DejaVu Sans, see `assets/`), so plots render the same on
//! a machine without any installed fonts.

use anyhow::{Context, Result, anyhow};
use etp_shared::episode::Outcome;
use etp_shared::scenario::Scenario;
use etp_synthesis::pareto::ParetoFront;
use etp_synthesis::validate::Trajectory;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

pub(crate) fn register_font() {
    REGISTER.call_once(|| {
        // The bytes are a valid TTF shipped with the crate; failure would only
        // lose text, never the plot.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Blue (low) → red (high) colour map on [0, 1].
fn heat(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let r = (255.0 * t.min(0.5) * 2.0) as u8;
    let b = (255.0 * (1.0 - t).min(0.5) * 2.0) as u8;
    let g = (200.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8;
    RGBColor(r, g, b)
}

/// Write the front plot to `stem.png` and `stem.svg`.
pub fn front_plot(front: &ParetoFront, stem: &Path) -> Result<()> {
    register_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, (1000, 700)).into_drawing_area();
        draw_front(&root, front)?;
        root.present()
            .with_context(|| format!("writing {}", png.display()))?;
    }
    let root = SVGBackend::new(&svg, (1000, 700)).into_drawing_area();
    draw_front(&root, front)?;
    root.present()
        .with_context(|| format!("writing {}", svg.display()))?;
    Ok(())
}

fn draw_front<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, front: &ParetoFront) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |x: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {x:?}");
    root.fill(&WHITE).map_err(e)?;
    let all: Vec<(f64, f64, f64)> = front
        .vertices
        .iter()
        .map(|v| &v.objectives)
        .chain(front.baselines.iter().map(|b| &b.objectives))
        .map(|o| (o.energy, o.p_target, o.p_collision))
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
    let area = root
        .titled(
            &format!(
                "Pareto front of {}: least expected energy for each P_tar, per bound on P_coll",
                front.scenario_name
            ),
            ("sans-serif", 20),
        )
        .map_err(e)?;
    let mut chart = ChartBuilder::on(&area)
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
    chart
        .configure_mesh()
        .x_desc("expected energy per episode (transmissions × cost)")
        .y_desc("P_tar (probability of reaching the target)")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(e)?;
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
            format!("any P_coll ({} points)", curve.len())
        } else {
            format!("P_coll ≤ {b} ({} points)", curve.len())
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
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(e)?;
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

/// Write the map plot to `stem.png` and `stem.svg`. The map is drawn in the
/// workspace (MODEL.md §7: `q = C x`, d coordinates): d ≤ 2 in one panel; d ≥ 3
/// in two projections side by side, top view (q₁, q₂) and side view (q₁, q₃),
/// each named in its caption.
pub fn map_plot(scenario: &Scenario, trajectories: &[Trajectory], stem: &Path) -> Result<()> {
    register_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    let size = if scenario.workspace_dim() >= 3 {
        (1800, 800)
    } else {
        (1200, 900)
    };
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        draw_maps(&root, scenario, trajectories)?;
        root.present()
            .with_context(|| format!("writing {}", png.display()))?;
    }
    let root = SVGBackend::new(&svg, size).into_drawing_area();
    draw_maps(&root, scenario, trajectories)?;
    root.present()
        .with_context(|| format!("writing {}", svg.display()))?;
    Ok(())
}

fn draw_maps<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    scenario: &Scenario,
    trajectories: &[Trajectory],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |x: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {x:?}");
    root.fill(&WHITE).map_err(e)?;
    let title = format!(
        "{} — {} sampled episodes, colour: expected rate γ̄(δ) (blue 0 → red 1)",
        scenario.name,
        trajectories.len()
    );
    if scenario.workspace_dim() >= 3 {
        let panels = root.split_evenly((1, 2));
        draw_map(
            &panels[0],
            scenario,
            trajectories,
            (0, 1),
            &format!(
                "{} — top view: projection onto (q₁, q₂), q₃ dropped",
                scenario.name
            ),
        )?;
        draw_map(
            &panels[1],
            scenario,
            trajectories,
            (0, 2),
            &format!(
                "side view: (q₁, q₃), q₂ dropped — {} episodes, colour γ̄(δ) blue 0 → red 1",
                trajectories.len()
            ),
        )?;
        Ok(())
    } else {
        draw_map(root, scenario, trajectories, (0, 1), &title)
    }
}

/// One panel: the projection of the workspace onto coordinates `axes`.
fn draw_map<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    scenario: &Scenario,
    trajectories: &[Trajectory],
    axes: (usize, usize),
    caption: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |x: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {x:?}");
    let (a, b) = axes;
    let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(0.0);
    let pt = |v: &[f64]| (at(v, a), at(v, b));
    let start = scenario.route_start.as_slice();
    let mut pts: Vec<(f64, f64)> = vec![pt(start)];
    for l in &scenario.legs {
        pts.push(pt(l.to.as_slice()));
    }
    for o in &scenario.obstacles {
        pts.extend([pt(&o.bounds.min), pt(&o.bounds.max)]);
    }
    let (x0, x1) = (
        pts.iter().map(|p| p.0).fold(f64::INFINITY, f64::min),
        pts.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max),
    );
    let (y0, y1) = (
        pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min),
        pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max),
    );
    let pad = 0.05 * (x1 - x0).max(y1 - y0).max(1e-3);
    let lines: Vec<&str> = caption.lines().collect();
    let mut chart = ChartBuilder::on(root)
        .caption(lines.join(" — "), ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d((x0 - pad)..(x1 + pad), (y0 - pad)..(y1 + pad))
        .map_err(e)?;
    let name = |i: usize| {
        if scenario.workspace.is_some() {
            format!("q{} (workspace C x)", i + 1)
        } else {
            format!("x{}", i + 1)
        }
    };
    chart
        .configure_mesh()
        .x_desc(name(a))
        .y_desc(name(b))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    // Projected boxes overlap in 3-D: translucent so the ones behind show.
    let obstacle_style = if scenario.workspace_dim() >= 3 {
        RGBColor(90, 90, 90).mix(0.35).filled()
    } else {
        RGBColor(90, 90, 90).filled()
    };
    chart
        .draw_series(
            scenario
                .obstacles
                .iter()
                .map(|o| Rectangle::new([pt(&o.bounds.min), pt(&o.bounds.max)], obstacle_style)),
        )
        .map_err(e)?;
    let t = &scenario.target;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [pt(&t.min), pt(&t.max)],
            RGBColor(0, 170, 0).filled(),
        )))
        .map_err(e)?;
    for tr in trajectories {
        for w in tr.points.windows(2) {
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![pt(&w[0].x), pt(&w[1].x)],
                    heat(w[1].expected_rate).stroke_width(1),
                )))
                .map_err(e)?;
        }
        if tr.outcome == Outcome::Collision
            && let Some(last) = tr.points.last()
        {
            chart
                .draw_series(std::iter::once(Cross::new(
                    pt(&last.x),
                    6,
                    RED.stroke_width(2),
                )))
                .map_err(e)?;
        }
    }
    // The target on top of the trajectories, as an outline.
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [pt(&t.min), pt(&t.max)],
            RGBColor(0, 140, 0).stroke_width(3),
        )))
        .map_err(e)?;
    let mut route = vec![pt(start)];
    route.extend(scenario.legs.iter().map(|l| pt(l.to.as_slice())));
    chart
        .draw_series(route.iter().map(|&p| Circle::new(p, 4, BLACK.filled())))
        .map_err(e)?;
    chart
        .draw_series(scenario.sensors.iter().map(|s| {
            TriangleMarker::new(pt(s.position.as_slice()), 8, RGBColor(128, 0, 128).filled())
        }))
        .map_err(e)?;
    Ok(())
}
