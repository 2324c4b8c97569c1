//! Figures (plotters, PNG and SVG): the Pareto front (P_tar vs energy per
//! bound on P_coll, baselines marked) and the scenario map with sampled
//! trajectories coloured by the expected rate of the threshold in force (the
//! paper's Fig. 4). The run report figure is `crate::report_plot`.
//!
//! The font is embedded (DejaVu Sans, see `assets/`), so plots render the same on
//! a machine without any installed fonts.
//!
//! * `front.rs` — the Pareto front (`etp synthesize`).
//! * `map.rs` — the scenario map with sampled trajectories (`etp validate --plot`).

mod front;
mod map;

pub use front::front_plot;
pub use map::map_plot;

use plotters::prelude::*;
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

/// Blue (low) → red (high) colour map on [0, 1].
pub(crate) fn heat(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let r = (255.0 * t.min(0.5) * 2.0) as u8;
    let b = (255.0 * (1.0 - t).min(0.5) * 2.0) as u8;
    let g = (200.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8;
    RGBColor(r, g, b)
}
