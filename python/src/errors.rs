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
create_exception!(
    etpareto,
    SynthesisError,
    FileFormatError,
    "A synthesis folder that cannot be used: mdp.bin missing or not etp's, a front.json or \
     scenario.toml of another MDP."
);
create_exception!(
    etpareto,
    StrategyFileError,
    FileFormatError,
    "A strategy file a step was given that cannot be read or is not of the scenario."
);
create_exception!(
    etpareto,
    RequestError,
    EtpError,
    "A request a step cannot carry out as asked: an option out of range, two that exclude \
     each other."
);
create_exception!(
    etpareto,
    OutputError,
    EtpError,
    "An output refused: it exists and force was not given, its folder is a link or another \
     user's, the file system refused, or its figure could not be drawn."
);
create_exception!(
    etpareto,
    ComputeError,
    EtpError,
    "A computation failed: the abstraction, a linear program, a prediction from rebuilds, \
     the executor."
);

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("EtpError", py.get_type::<EtpError>())?;
    m.add("ScenarioError", py.get_type::<ScenarioError>())?;
    m.add("SimulationError", py.get_type::<SimulationError>())?;
    m.add("RecordingError", py.get_type::<RecordingError>())?;
    m.add("FileFormatError", py.get_type::<FileFormatError>())?;
    m.add("RunError", py.get_type::<RunError>())?;
    m.add("SynthesisError", py.get_type::<SynthesisError>())?;
    m.add("StrategyFileError", py.get_type::<StrategyFileError>())?;
    m.add("RequestError", py.get_type::<RequestError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add("ComputeError", py.get_type::<ComputeError>())?;
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

/// A pipeline step's error as the exception of its kind, with the text
/// `etp` prints for it. The match is exhaustive: a new kind of failure in
/// the pipeline gets its class here before it compiles.
pub fn pipeline_error(e: etp_pipeline::error::Error) -> PyErr {
    use etp_pipeline::error::Error as E;
    let text = chain(&e);
    match e {
        E::Scenario { .. } | E::ScenarioArg(_) | E::InvalidScenario(_) => {
            ScenarioError::new_err(text)
        }
        E::Synthesis { .. } => SynthesisError::new_err(text),
        E::Strategy { .. } => StrategyFileError::new_err(text),
        E::Request(_) => RequestError::new_err(text),
        E::Output(_) | E::Figure(_) => OutputError::new_err(text),
        E::Prediction(_) | E::Executor(_) | E::Compute { .. } => ComputeError::new_err(text),
    }
}

/// An `anyhow` error as the CLI prints it.
pub fn anyhow_text(e: &anyhow::Error) -> String {
    format!("{e:#}")
}
