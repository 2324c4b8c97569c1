//! `etp-figures`: every figure etpareto draws (plotters, PNG and SVG), as a
//! library the `etp` commands call with their data.
//!
//! A short tour:
//!
//! * [`front_plot`] (`front.rs`) — the Pareto front, P_tar vs energy per
//!   bound on P_coll, baselines marked (`etp synthesize`).
//! * [`fronts_plot`] (`fronts.rs`) — several fronts of one scenario, one
//!   [`Curve`] per radio channel (`etp fronts`).
//! * [`map_plot`] (`map.rs`) — the scenario map with sampled trajectories
//!   coloured by the expected rate of the threshold in force (the paper's
//!   Fig. 4; `etp validate --plot`, `etp demo`).
//! * [`report_plot`] (`report.rs`) — a run's measured values against the
//!   predicted ones (`etp run --plot`, `etp replay plot`), from the data of
//!   `etp_recording_tools::figure`.
//!
//! All are written by `png_and_svg`, the one writer of a figure. The font is
//! embedded (DejaVu Sans, see `assets/`), so plots render the same on a
//! machine without any installed fonts.

mod front;
mod fronts;
mod map;
mod report;

pub use front::front_plot;
pub use fronts::{Curve, fronts_plot};
pub use map::map_plot;
pub use report::{Bar, RunFigure, mean_ci, proportion, report_plot, short_label};

use anyhow::{Context, Result};
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

/// A figure drawn the same way on any plotters backend (PNG and SVG).
pub(crate) trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static;
}

/// THE way every figure is written: `stem.png` and `stem.svg`, `size` pixels,
/// each drawn into a temporary sibling and renamed into place
/// (`etp_recording_tools::files::write_via_temp`: its folder checked, no
/// planted link followed).
pub(crate) fn png_and_svg(fig: &impl Figure, stem: &Path, size: (u32, u32)) -> Result<()> {
    use etp_recording_tools::files::write_via_temp;
    register_font();
    let png = stem.with_extension("png");
    write_via_temp(&png, |tmp| {
        let root = BitMapBackend::new(tmp, size).into_drawing_area();
        fig.draw(&root)?;
        root.present()
            .with_context(|| format!("writing {}", png.display()))
    })?;
    let svg = stem.with_extension("svg");
    write_via_temp(&svg, |tmp| {
        let root = SVGBackend::new(tmp, size).into_drawing_area();
        fig.draw(&root)?;
        root.present()
            .with_context(|| format!("writing {}", svg.display()))
    })
}

/// Blue (low) → red (high) colour map on [0, 1].
pub(crate) fn heat(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let r = (255.0 * t.min(0.5) * 2.0) as u8;
    let b = (255.0 * (1.0 - t).min(0.5) * 2.0) as u8;
    let g = (200.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8;
    RGBColor(r, g, b)
}
