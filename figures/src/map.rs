//! The map figure: obstacles, target, route, named sensors and sampled
//! trajectories coloured by γ̄(δ) (viridis) with a colour bar, equal
//! aspect; for d ≥ 3 two projections. The colour bar and the legend stand
//! beside the panels, so that nothing covers the map; the markers
//! (collision, obstacle, target, route, sensors) are in colours the colour
//! map never takes.

use crate::style::{COLLISION, OBSTACLE, colormap, text};
use crate::{Result, plot_error};
use etp_shared::episode::Outcome;
use etp_shared::scenario::Scenario;
use etp_synthesis::validate::Trajectory;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Width of the strip beside the panels: colour bar and legend.
const STRIP: u32 = 250;

/// Write the map plot to `stem.png` and `stem.svg`. The map is drawn in the
/// workspace (MODEL.md §7: `q = C x`, d coordinates): d ≤ 2 in one panel; d ≥ 3
/// in two projections side by side, top view (q₁, q₂) and side view (q₁, q₃),
/// each named in its caption.
pub fn map_plot(scenario: &Scenario, trajectories: &[Trajectory], stem: &Path) -> Result<()> {
    let size = if scenario.workspace_dim() >= 3 {
        (1850, 800)
    } else {
        (1130, 820)
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
        draw_maps(root, self.0, self.1).map(|_| ())
    }
}

/// The panels and the strip beside them; the pixel centres of the
/// obstacles as drawn (panel by panel), each of which a reader must see.
pub(crate) fn draw_maps<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    scenario: &Scenario,
    trajectories: &[Trajectory],
) -> Result<Vec<(i32, i32)>>
where
    DB::ErrorType: 'static,
{
    let (w, _) = root.dim_in_pixel();
    let (root, strip) = root.split_horizontally(w.saturating_sub(STRIP));
    side_strip(&strip)?;
    let n = trajectories.len();
    if scenario.workspace_dim() >= 3 {
        let panels = root.split_evenly((1, 2));
        let mut centres = draw_map(
            &panels[0],
            scenario,
            trajectories,
            (0, 1),
            &format!("{}: top view (q₁, q₂), q₃ dropped", scenario.name),
        )?;
        centres.extend(draw_map(
            &panels[1],
            scenario,
            trajectories,
            (0, 2),
            &format!("side view (q₁, q₃), q₂ dropped; {n} episodes"),
        )?);
        Ok(centres)
    } else {
        let title = format!("{}: {n} sampled episodes, coloured by γ̄(δ)", scenario.name);
        draw_map(&root, scenario, trajectories, (0, 1), &title)
    }
}

/// The plotted range of the projection onto `(a, b)`: the route and the
/// obstacles with a margin, widened on one axis so that one unit is as
/// long on both axes in a plotting area of `pw` × `ph` pixels.
fn view(scenario: &Scenario, (a, b): (usize, usize), (pw, ph): (f64, f64)) -> [(f64, f64); 2] {
    let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(0.0);
    let pt = |v: &[f64]| (at(v, a), at(v, b));
    let mut pts: Vec<(f64, f64)> = vec![pt(scenario.route_start.as_slice())];
    pts.extend(scenario.legs.iter().map(|l| pt(l.to.as_slice())));
    for o in &scenario.obstacles {
        pts.extend([pt(&o.bounds.min), pt(&o.bounds.max)]);
    }
    let lo_hi = |f: fn(&(f64, f64)) -> f64| {
        pts.iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(v), h.max(v))
            })
    };
    let ((x0, x1), (y0, y1)) = (lo_hi(|p| p.0), lo_hi(|p| p.1));
    let pad = 0.05 * (x1 - x0).max(y1 - y0).max(1e-3);
    let (mut xr, mut yr) = ((x0 - pad, x1 + pad), (y0 - pad, y1 + pad));
    let (dx, dy) = (xr.1 - xr.0, yr.1 - yr.0);
    if dx / pw > dy / ph {
        let grow = (dx * ph / pw - dy) / 2.0;
        yr = (yr.0 - grow, yr.1 + grow);
    } else {
        let grow = (dy * pw / ph - dx) / 2.0;
        xr = (xr.0 - grow, xr.1 + grow);
    }
    [xr, yr]
}

/// One panel: the projection of the workspace onto coordinates `axes`;
/// the pixel centres of its obstacles.
fn draw_map<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    scenario: &Scenario,
    trajectories: &[Trajectory],
    axes: (usize, usize),
    caption: &str,
) -> Result<Vec<(i32, i32)>>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let (a, b) = axes;
    let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(0.0);
    let pt = |v: &[f64]| (at(v, a), at(v, b));
    let area = root
        .titled(caption, ("sans-serif", text::CAPTION))
        .map_err(e)?;
    // Equal aspect: one unit is as long on both axes. The plotting area is
    // the titled area less the margins and label areas set below.
    let (margin, x_label, y_label) = (15u32, 60u32, 75u32);
    let (aw, ah) = area.dim_in_pixel();
    let pw = f64::from(aw.saturating_sub(2 * margin + y_label).max(1));
    let ph = f64::from(ah.saturating_sub(2 * margin + x_label).max(1));
    let [xr, yr] = view(scenario, axes, (pw, ph));
    let mut chart = ChartBuilder::on(&area)
        .margin(margin)
        .x_label_area_size(x_label)
        .y_label_area_size(y_label)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
        .map_err(e)?;
    let name = |i: usize| {
        if scenario.workspace.is_some() {
            format!("q{} = (C x){} (scenario units)", i + 1, i + 1)
        } else {
            format!("x{} (scenario units)", i + 1)
        }
    };
    crate::draw_axes(&mut chart, &name(a), &name(b))?;
    // Projected boxes overlap in 3-D: translucent so the ones behind show.
    let obstacle_style = if scenario.workspace_dim() >= 3 {
        OBSTACLE.mix(0.35).filled()
    } else {
        OBSTACLE.filled()
    };
    chart
        .draw_series(
            scenario
                .obstacles
                .iter()
                .map(|o| Rectangle::new([pt(&o.bounds.min), pt(&o.bounds.max)], obstacle_style)),
        )
        .map_err(e)?;
    for tr in trajectories {
        chart
            .draw_series(tr.points.windows(2).map(|w| {
                PathElement::new(
                    vec![pt(&w[0].x), pt(&w[1].x)],
                    colormap(w[1].expected_rate).stroke_width(2),
                )
            }))
            .map_err(e)?;
    }
    // Collisions over every trajectory: a white-edged red cross.
    let ends = trajectories
        .iter()
        .filter(|t| t.outcome == Outcome::Collision)
        .filter_map(|t| t.points.last())
        .map(|p| pt(&p.x));
    for end in ends {
        chart
            .draw_series([
                Cross::new(end, 8, WHITE.stroke_width(6)),
                Cross::new(end, 8, COLLISION.stroke_width(3)),
            ])
            .map_err(e)?;
    }
    // The target over the trajectories, as an outline.
    let t = &scenario.target;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [pt(&t.min), pt(&t.max)],
            BLACK.stroke_width(3),
        )))
        .map_err(e)?;
    let mut route = vec![pt(scenario.route_start.as_slice())];
    route.extend(scenario.legs.iter().map(|l| pt(l.to.as_slice())));
    chart
        .draw_series(route.iter().map(|&p| Circle::new(p, 5, BLACK.filled())))
        .map_err(e)?;
    let label: TextStyle = ("sans-serif", text::LABEL).into();
    chart
        .draw_series(scenario.sensors.iter().map(|s| {
            // On a white patch, readable over the trajectories.
            let (w, h) = area
                .estimate_text_size(&s.name, &label)
                .unwrap_or((10 * s.name.len() as u32, text::LABEL));
            EmptyElement::at(pt(s.position.as_slice()))
                + TriangleMarker::new((0, 0), 9, WHITE.filled())
                + TriangleMarker::new((0, 0), 9, BLACK.stroke_width(2))
                + Rectangle::new(
                    [(10, -(h as i32) - 6), (14 + w as i32, -2)],
                    WHITE.mix(0.85).filled(),
                )
                + Text::new(s.name.clone(), (12, -(h as i32) - 4), label.clone())
        }))
        .map_err(e)?;
    Ok(scenario
        .obstacles
        .iter()
        .map(|o| {
            let (p, q) = (pt(&o.bounds.min), pt(&o.bounds.max));
            chart.backend_coord(&((p.0 + q.0) / 2.0, (p.1 + q.1) / 2.0))
        })
        .collect())
}

/// The strip beside the panels: the colour bar of γ̄(δ) with its unit, and
/// under it the legend of the map's marks.
fn side_strip<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let (_, h) = area.dim_in_pixel();
    let font = ("sans-serif", text::LEGEND);
    for (k, line) in ["γ̄(δ): expected", "transmissions", "per slot"]
        .iter()
        .enumerate()
    {
        area.draw(&Text::new(line.to_string(), (12, 20 + 24 * k as i32), font))
            .map_err(e)?;
    }
    let (top, bottom) = (100i32, (h as i32 / 2 + 60).max(160));
    let (left, right) = (20i32, 50i32);
    let steps: i32 = 100;
    // Integer edges shared by neighbouring steps: no gaps.
    let edge = |k: i32| bottom - (bottom - top) * k / steps;
    for k in 0..steps {
        let t = f64::from(k) / f64::from(steps);
        area.draw(&Rectangle::new(
            [(left, edge(k + 1)), (right, edge(k))],
            colormap(t).filled(),
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
            vec![(right, y), (right + 6, y)],
            BLACK.stroke_width(1),
        ))
        .map_err(e)?;
        area.draw(&Text::new(format!("{t}"), (right + 10, y - 10), font))
            .map_err(e)?;
    }
    legend(area, bottom + 40)
}

/// The map's legend from `y` down, one mark per line.
fn legend<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, y: i32) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = plot_error::<plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>>;
    let font = ("sans-serif", text::LEGEND);
    let step = 30;
    let row = |k: i32| (30, y + step * k);
    let rows = [
        "trajectory",
        "collision",
        "obstacle",
        "target",
        "waypoint",
        "sensor",
    ];
    for (k, what) in rows.iter().enumerate() {
        let (x, y) = row(k as i32);
        area.draw(&Text::new(what.to_string(), (x + 25, y - 11), font))
            .map_err(e)?;
    }
    let (x, y0) = row(0);
    area.draw(&PathElement::new(
        vec![(x - 14, y0), (x, y0)],
        colormap(0.2).stroke_width(3),
    ))
    .map_err(e)?;
    area.draw(&PathElement::new(
        vec![(x, y0), (x + 14, y0)],
        colormap(0.8).stroke_width(3),
    ))
    .map_err(e)?;
    area.draw(&Cross::new(row(1), 8, COLLISION.stroke_width(3)))
        .map_err(e)?;
    let (x, y) = row(2);
    area.draw(&Rectangle::new(
        [(x - 10, y - 8), (x + 10, y + 8)],
        OBSTACLE.filled(),
    ))
    .map_err(e)?;
    let (x, y) = row(3);
    area.draw(&Rectangle::new(
        [(x - 10, y - 8), (x + 10, y + 8)],
        BLACK.stroke_width(3),
    ))
    .map_err(e)?;
    area.draw(&Circle::new(row(4), 5, BLACK.filled()))
        .map_err(e)?;
    area.draw(&TriangleMarker::new(row(5), 9, BLACK.stroke_width(2)))
        .map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every obstacle of winding-2d shows at its centre (b4 was under the
    /// legend when the legend stood in the map's corner).
    #[test]
    fn every_obstacle_is_visible() {
        crate::register_font();
        let scenario = Scenario::builtin("winding-2d").expect("built in");
        let (w, h) = (1130u32, 820u32);
        let mut buf = vec![0u8; (w * h * 3) as usize];
        let centres = {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            root.fill(&WHITE).expect("filled");
            draw_maps(&root, &scenario, &[]).expect("drawn")
        };
        assert_eq!(centres.len(), scenario.obstacles.len());
        for (i, &(x, y)) in centres.iter().enumerate() {
            let at = 3 * (y as usize * w as usize + x as usize);
            let px = &buf[at..at + 3];
            assert_eq!(
                px,
                [OBSTACLE.0, OBSTACLE.1, OBSTACLE.2],
                "obstacle {} covered at ({x}, {y})",
                scenario.obstacles[i].name
            );
        }
    }
}
