//! The exception classes of `etpareto` and the text they carry: the text
//! `etp` prints after `error: ` for the same failure (an error's chain of
//! causes joined by `: `, as `anyhow`'s `{:#}` does).

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    etpareto,
    EtpError,
    PyException,
    "Any etpareto error; its message is the text `etp` prints after `error: `."
);
create_exception!(
    etpareto,
    ScenarioError,
    EtpError,
    "A scenario argument that is neither a built-in name nor a valid scenario TOML file."
);
create_exception!(
    etpareto,
    SimulationError,
    EtpError,
    "A simulation request that cannot run (a bad delta, a trigger family unknown)."
);
create_exception!(
    etpareto,
    RecordingError,
    EtpError,
    "An unreadable, unfinished or damaged MCAP recording."
);
create_exception!(
    etpareto,
    FileFormatError,
    EtpError,
    "An unreadable front.json or strategy.json."
);
create_exception!(
    etpareto,
    RunError,
    EtpError,
    "A multi-process run that could not start or finish."
);

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("EtpError", py.get_type::<EtpError>())?;
    m.add("ScenarioError", py.get_type::<ScenarioError>())?;
    m.add("SimulationError", py.get_type::<SimulationError>())?;
    m.add("RecordingError", py.get_type::<RecordingError>())?;
    m.add("FileFormatError", py.get_type::<FileFormatError>())?;
    m.add("RunError", py.get_type::<RunError>())?;
    Ok(())
}

/// `e` and its causes joined by `: ` (what `etp` prints for it: the CLI
/// wraps library errors in `anyhow` and prints `{:#}`).
pub fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text.push_str(": ");
        text.push_str(&c.to_string());
        cause = c.source();
    }
    text
}

/// An `anyhow` error as the CLI prints it.
pub fn anyhow_text(e: &anyhow::Error) -> String {
    format!("{e:#}")
}
