//! Figures (plotters, PNG and SVG): the Pareto front (P_tar vs energy per
//! bound on P_coll, baselines marked) and the scenario map with sampled
//! trajectories coloured by the expected rate of the threshold in force (the
//! paper's Fig. 4). The run report figure is `crate::report_plot`; all three are written by
//! `png_and_svg`.
//!
//! The font is embedded (DejaVu Sans, see `assets/`), so plots render the same on
//! a machine without any installed fonts.
//!
//! * `front.rs` — the Pareto front (`etp synthesize`).
//! * `fronts.rs` — several fronts of one scenario, one per radio channel (`etp fronts`).
//! * `map.rs` — the scenario map with sampled trajectories (`etp validate --plot`).

mod front;
mod fronts;
mod map;

pub use front::front_plot;
pub use fronts::fronts_plot;
pub use map::map_plot;

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

pub(crate) fn register_font() {
    REGISTER.call_once(|| {
        // The bytes are a valid TTF shipped with the crate; failure would only
        // lose text, never the plot.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// A figure drawn the same way on any plotters backend (PNG and SVG).
pub(crate) trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static;
}

/// THE way every figure is written: `stem.png` and `stem.svg`, `size` pixels.
pub(crate) fn png_and_svg(fig: &impl Figure, stem: &Path, size: (u32, u32)) -> Result<()> {
    register_font();
    let png = stem.with_extension("png");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        fig.draw(&root)?;
        root.present()
            .with_context(|| format!("writing {}", png.display()))?;
    }
    let svg = stem.with_extension("svg");
    let root = SVGBackend::new(&svg, size).into_drawing_area();
    fig.draw(&root)?;
    root.present()
        .with_context(|| format!("writing {}", svg.display()))?;
    Ok(())
}

/// Blue (low) → red (high) colour map on [0, 1].
pub(crate) fn heat(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let r = (255.0 * t.min(0.5) * 2.0) as u8;
    let b = (255.0 * (1.0 - t).min(0.5) * 2.0) as u8;
    let g = (200.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8;
    RGBColor(r, g, b)
}
