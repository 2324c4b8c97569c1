//! The map figure: obstacles, target, route, named sensors and sampled
//! trajectories coloured by γ̄(δ) with a colour bar, equal aspect; for d ≥ 3
//! two projections.

use super::heat;
use crate::{Result, plot_error};
use etp_shared::episode::Outcome;
use etp_shared::scenario::Scenario;
use etp_synthesis::validate::Trajectory;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Write the map plot to `stem.png` and `stem.svg`. The map is drawn in the
/// workspace (MODEL.md §7: `q = C x`, d coordinates): d ≤ 2 in one panel; d ≥ 3
/// in two projections side by side, top view (q₁, q₂) and side view (q₁, q₃),
/// each named in its caption.
pub fn map_plot(scenario: &Scenario, trajectories: &[Trajectory], stem: &Path) -> Result<()> {
    let size = if scenario.workspace_dim() >= 3 {
        (1800, 800)
    } else {
        (1200, 900)
    };
    super::png_and_svg(&MapFigure(scenario, trajectories), stem, size)
}

struct MapFigure<'a>(&'a Scenario, &'a [Trajectory]);

impl super::Figure for MapFigure<'_> {
    /// The map titles itself (its title names what its panels show).
    fn title(&self) -> Option<String> {
        None
    }
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_maps(root, self.0, self.1)
    }
}

fn draw_maps<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    scenario: &Scenario,
    trajectories: &[Trajectory],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let title = format!(
        "{} — {} sampled episodes coloured by the expected transmission rate γ̄(δ) of the threshold in force",
        scenario.name,
        trajectories.len()
    );
    let (w, _) = root.dim_in_pixel();
    let (root, bar) = root.split_horizontally(w.saturating_sub(110));
    colour_bar(&bar, "γ̄(δ)")?;
    let root = &root;
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
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
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
    let area = root
        .titled(&lines.join(" — "), ("sans-serif", 17))
        .map_err(e)?;
    // Equal aspect: one unit is as long on both axes. The plotting area is
    // the titled area less the margins and label areas set below.
    let (margin, x_label, y_label) = (15u32, 40u32, 50u32);
    let (aw, ah) = area.dim_in_pixel();
    let pw = f64::from(aw.saturating_sub(2 * margin + y_label).max(1));
    let ph = f64::from(ah.saturating_sub(2 * margin + x_label).max(1));
    let (mut xr, mut yr) = ((x0 - pad, x1 + pad), (y0 - pad, y1 + pad));
    let (dx, dy) = (xr.1 - xr.0, yr.1 - yr.0);
    if dx / pw > dy / ph {
        let grow = (dx * ph / pw - dy) / 2.0;
        yr = (yr.0 - grow, yr.1 + grow);
    } else {
        let grow = (dy * pw / ph - dx) / 2.0;
        xr = (xr.0 - grow, xr.1 + grow);
    }
    let mut chart = ChartBuilder::on(&area)
        .margin(margin)
        .x_label_area_size(x_label)
        .y_label_area_size(y_label)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
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
        .map_err(e)?
        .label("obstacle")
        .legend(move |(x, y)| Rectangle::new([(x - 6, y - 5), (x + 6, y + 5)], obstacle_style));
    let t = &scenario.target;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [pt(&t.min), pt(&t.max)],
            RGBColor(0, 170, 0).filled(),
        )))
        .map_err(e)?
        .label("target")
        .legend(|(x, y)| {
            Rectangle::new(
                [(x - 6, y - 5), (x + 6, y + 5)],
                RGBColor(0, 170, 0).filled(),
            )
        });
    chart
        .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
        .map_err(e)?
        .label("sampled trajectory (colour: γ̄(δ))")
        .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], heat(0.2).stroke_width(2)));
    chart
        .draw_series(std::iter::empty::<Cross<(f64, f64), i32>>())
        .map_err(e)?
        .label("collision")
        .legend(|(x, y)| Cross::new((x, y), 5, RED.stroke_width(2)));
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
        .map_err(e)?
        .label("waypoint")
        .legend(|(x, y)| Circle::new((x, y), 4, BLACK.filled()));
    let purple = RGBColor(128, 0, 128);
    chart
        .draw_series(
            scenario
                .sensors
                .iter()
                .map(|s| TriangleMarker::new(pt(s.position.as_slice()), 8, purple.filled())),
        )
        .map_err(e)?
        .label("sensor")
        .legend(move |(x, y)| TriangleMarker::new((x, y), 7, purple.filled()));
    chart
        .draw_series(scenario.sensors.iter().map(|s| {
            // On a white patch, readable over the trajectories.
            let w = 9 * s.name.chars().count() as i32 + 4;
            EmptyElement::at(pt(s.position.as_slice()))
                + Rectangle::new([(6, -18), (6 + w, -1)], WHITE.mix(0.85).filled())
                + Text::new(
                    s.name.clone(),
                    (8, -17),
                    ("sans-serif", 14).into_font().color(&purple),
                )
        }))
        .map_err(e)?;
    crate::draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, 13, 0.85)?;
    Ok(())
}

/// A vertical colour bar of [`heat`] on [0, 1] with ticks, titled `what`.
fn colour_bar<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, what: &str) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let (w, h) = area.dim_in_pixel();
    let (top, bottom) = (80i32, h as i32 - 80);
    let (left, right) = (20i32, 45i32.min(w as i32));
    let steps: i32 = 100;
    // Integer edges shared by neighbouring steps: no gaps.
    let edge = |k: i32| bottom - (bottom - top) * k / steps;
    for k in 0..steps {
        let t = f64::from(k) / f64::from(steps);
        area.draw(&Rectangle::new(
            [(left, edge(k + 1)), (right, edge(k))],
            heat(t).filled(),
        ))
        .map_err(e)?;
    }
    area.draw(&Rectangle::new(
        [(left, top), (right, bottom)],
        BLACK.stroke_width(1),
    ))
    .map_err(e)?;
    for t in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let y = bottom - ((bottom - top) as f64 * t) as i32;
        area.draw(&PathElement::new(
            vec![(right, y), (right + 5, y)],
            BLACK.stroke_width(1),
        ))
        .map_err(e)?;
        area.draw(&Text::new(
            format!("{t}"),
            (right + 8, y - 7),
            ("sans-serif", 13),
        ))
        .map_err(e)?;
    }
    area.draw(&Text::new(
        what.to_string(),
        (left - 5, top - 30),
        ("sans-serif", 15),
    ))
    .map_err(e)?;
    Ok(())
}
