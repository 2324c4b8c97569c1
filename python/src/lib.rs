//! `etpareto._native`: the compiled half of the Python package `etpareto`
//! (the Python half, `python/etpareto/`, turns what this returns into
//! dicts, NumPy arrays and pandas DataFrames).
//!
//! Everything here calls the library crates — `etp-shared`,
//! `etp-synthesis`, `etp-pipeline`, `etp-runtime`, `etp-recording-tools`, `etp-launcher` —
//! the functions `etp`'s subcommands call, never the `etp` binary. What the
//! CLI prints as JSON crosses as the same JSON text (parsed by `json.loads`
//! on the Python side), so a dict here equals `json.loads` of the CLI's
//! `--json` output by construction. Tables cross as columns ([`columns`]).
//!
//! * [`errors`] — the exception classes and the CLI's error text.
//! * [`scenario`] — `load_scenario`, `check`.
//! * [`simulate`] — `simulate`: the CLI's summary plus episode and leg tables.
//! * [`recording`] — `read_recording`: one table per channel, streamed.
//! * [`pipeline`] — `synthesize`, `select_strategy`, `validate`: the steps
//!   of `etp synthesize`, `etp strategy`, `etp validate` through `etp-pipeline`,
//!   with a progress callback.
//! * [`study`] — `study`: `etp study`'s cases and tables through
//!   `etp-pipeline`.
//! * [`files`] — `front.json` and `strategy.json` read; `run`, a
//!   multi-process run through `etp-launcher`.

mod columns;
mod errors;
mod files;
mod pipeline;
mod recording;
mod scenario;
mod simulate;
mod study;

use pyo3::prelude::*;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<scenario::PyScenario>()?;
    m.add_function(wrap_pyfunction!(scenario::load_scenario, m)?)?;
    m.add_function(wrap_pyfunction!(scenario::builtin_scenarios, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(recording::read_recording, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_front, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_strategy, m)?)?;
    m.add_function(wrap_pyfunction!(files::mdp_drn, m)?)?;
    m.add_function(wrap_pyfunction!(files::run, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::synthesize, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::select_strategy, m)?)?;
    m.add_function(wrap_pyfunction!(pipeline::validate, m)?)?;
    m.add_function(wrap_pyfunction!(study::study, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
