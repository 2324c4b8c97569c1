//! The look every figure shares: one palette of distinguishable hues, each
//! series with its own line style; the colour map of a continuous quantity
//! (viridis: perceptually uniform, no white middle) and the marker colours
//! kept outside it; the text sizes, readable with each panel printed a
//! column wide.

use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;

/// The series colours (Okabe–Ito, readable by colour-blind readers; its
/// yellow left out, too pale on white). Black is kept for references
/// (baselines, certified bounds), not for series.
pub(crate) const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

/// The line of a series: solid, or dashed with `(dash, gap)` pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Line {
    Solid,
    Dashed(u32, u32),
}

/// The colour and line of series `i`: the hues in turn, then the same hues
/// again with a different dash pattern, so that no two series look alike.
pub(crate) fn series(i: usize) -> (RGBColor, Line) {
    const LINES: [Line; 3] = [Line::Solid, Line::Dashed(14, 6), Line::Dashed(4, 4)];
    (
        PALETTE[i % PALETTE.len()],
        LINES[(i / PALETTE.len()) % LINES.len()],
    )
}

/// The colour of the continuous quantity `t` in [0, 1] (viridis: dark
/// violet → teal → yellow; clamped outside).
pub(crate) fn colormap(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    ViridisRGB::get_color(t)
}

/// The collision marker of the map: a red the colour map never takes.
pub(crate) const COLLISION: RGBColor = RGBColor(220, 0, 30);
/// Obstacles: a neutral grey (the colour map has no grey).
pub(crate) const OBSTACLE: RGBColor = RGBColor(120, 120, 120);

/// Text sizes as plotters takes them (the glyphs' em is 1/1.24 of it: 22
/// draws 17.7-pixel text). The figures are sized so that the smallest
/// text, ticks, legends and labels, is at least 1/50 of a panel's width: 5 pt
/// or more with each panel printed 3.5 in (one column) wide.
pub(crate) mod text {
    pub(crate) const TITLE: u32 = 28;
    pub(crate) const CAPTION: u32 = 22;
    pub(crate) const AXIS: u32 = 24;
    pub(crate) const TICK: u32 = 22;
    pub(crate) const LEGEND: u32 = 22;
    pub(crate) const LABEL: u32 = 22;
}

/// CIE L*a*b* (D65) of an sRGB colour.
#[cfg(test)]
pub(crate) fn lab(c: RGBColor) -> [f64; 3] {
    let lin = |u: u8| {
        let v = f64::from(u) / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    let (r, g, b) = (lin(c.0), lin(c.1), lin(c.2));
    let x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047;
    let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883;
    let f = |t: f64| {
        if t > 216.0 / 24389.0 {
            t.cbrt()
        } else {
            (24389.0 / 27.0 * t + 16.0) / 116.0
        }
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// The perceptual distance ΔE*ab (CIE76) of two colours: about 2.3 is just
/// noticeable, 20 and more reads as another colour.
#[cfg(test)]
pub(crate) fn delta_e(a: RGBColor, b: RGBColor) -> f64 {
    let (p, q) = (lab(a), lab(b));
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples() -> Vec<RGBColor> {
        (0..=100).map(|k| colormap(f64::from(k) / 100.0)).collect()
    }

    #[test]
    fn the_colour_map_has_no_white_middle_and_rises_in_lightness() {
        for t in [0.0, 0.25, 0.5, 0.75, 1.0] {
            let c = colormap(t);
            assert!(delta_e(c, WHITE) > 30.0, "γ̄ = {t}: {c:?} is near white");
        }
        // γ̄ ≈ 0.5 was white under the old blue → red map: now mid-lightness.
        assert!(lab(colormap(0.5))[0] < 65.0);
        let l: Vec<f64> = samples().into_iter().map(|c| lab(c)[0]).collect();
        for w in l.windows(2) {
            assert!(w[1] > w[0], "lightness not increasing: {w:?}");
        }
    }

    #[test]
    fn the_map_markers_are_outside_the_colour_map() {
        for (what, c) in [("collision", COLLISION), ("obstacle", OBSTACLE)] {
            let nearest = samples()
                .into_iter()
                .map(|s| delta_e(s, c))
                .fold(f64::INFINITY, f64::min);
            assert!(nearest > 25.0, "{what} {c:?}: ΔE {nearest:.1} to the map");
        }
    }

    #[test]
    fn the_palette_hues_are_pairwise_distinguishable_and_readable_on_white() {
        for (i, a) in PALETTE.iter().enumerate() {
            assert!(delta_e(*a, WHITE) > 25.0, "{a:?} too pale");
            assert!(delta_e(*a, BLACK) > 25.0, "{a:?} too close to black");
            for b in &PALETTE[i + 1..] {
                assert!(delta_e(*a, *b) > 20.0, "{a:?} and {b:?}");
            }
        }
        // Series beyond the hues repeat a hue with another line.
        let n = PALETTE.len();
        for i in 0..n {
            assert_ne!(series(i).1, series(i + n).1);
        }
    }

    #[test]
    fn lab_of_known_colours() {
        let w = lab(WHITE);
        assert!((w[0] - 100.0).abs() < 0.1 && w[1].abs() < 0.1 && w[2].abs() < 0.1);
        assert!(lab(BLACK)[0].abs() < 1e-9);
        let red = lab(RGBColor(255, 0, 0));
        assert!((red[0] - 53.2).abs() < 0.5 && (red[1] - 80.1).abs() < 0.5);
    }
}
