//! Files of a synthesis read for Python — `front.json`
//! (`ParetoFront::from_json`), `strategy.json` (`etp_runtime::load_strategy`,
//! the loader of `etp validate`: seal and scenario hash checked) and
//! `mdp.bin` as Storm's DRN text (`etp export --format drn`) — and a
//! multi-process run through `etp-launcher`, its report the object `etp run
//! --json` prints.

use crate::columns::{Column, Values, table_into_py};
use crate::errors::{FileFormatError, RunError, anyhow_text, chain};
use clap::Parser;
use etp_synthesis::pareto::ParetoFront;
use pyo3::prelude::*;
use pyo3::types::PyList;
use std::path::{Path, PathBuf};

/// `path` itself, or `path/<file>` when `path` is a folder (a synthesis
/// directory).
fn file_in(path: &Path, file: &str) -> PathBuf {
    if path.is_dir() {
        path.join(file)
    } else {
        path.to_path_buf()
    }
}

/// The text of a `front.json` (or of `DIR/front.json`), checked by the
/// parser `etp strategy` uses; raises `FileFormatError` with its message.
#[pyfunction]
pub fn read_front(path: PathBuf) -> PyResult<String> {
    let path = file_in(&path, "front.json");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| FileFormatError::new_err(format!("reading {}: {e}", path.display())))?;
    ParetoFront::from_json(&text)
        .map_err(|e| FileFormatError::new_err(format!("loading {}: {e}", path.display())))?;
    Ok(text)
}

/// The MDP of a synthesis folder (its `mdp.bin`, checked against its
/// `scenario.toml` as `etp export` does) as the DRN text `etp export
/// --format drn` writes to `model.drn` (energy: the counted cost).
#[pyfunction]
pub fn mdp_drn(dir: PathBuf) -> PyResult<String> {
    let (mdp, _) = etp_pipeline::output::read_mdp(&dir)
        .map_err(|e| FileFormatError::new_err(anyhow_text(&e)))?;
    Ok(etp_synthesis::export::drn::export(
        &mdp,
        etp_synthesis::mdp::CostModel::Counted,
    ))
}

/// A sealed `strategy.json` (or `DIR/strategy.json`): `(text, omega)`,
/// the file's text and its policy as columns — one row per (state,
/// threshold) with `state`, `decision_point`, `region`, `delta`, `omega`.
/// Raises `FileFormatError` with `etp validate`'s message (an edited file,
/// another format version, a scenario of another hash).
#[pyfunction]
pub fn read_strategy<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(String, Bound<'py, PyList>)> {
    let path = file_in(&path, "strategy.json");
    let (strategy, _scenario) = etp_runtime::strategy_arg::load_strategy(&path)
        .map_err(|e| FileFormatError::new_err(chain(&e)))?;
    let text = std::fs::read_to_string(&path)
        .map_err(|e| FileFormatError::new_err(format!("reading {}: {e}", path.display())))?;
    let p = &strategy.policy;
    let (mut state, mut point, mut region, mut delta, mut omega) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, s) in p.states.iter().enumerate() {
        for (d, w) in p.deltas.iter().zip(&s.omega) {
            state.push(i as u64);
            point.push(s.decision_point as u64);
            region.push(Some(s.region.to_string()));
            delta.push(*d);
            omega.push(*w);
        }
    }
    let table = vec![
        Column::new("state", Values::U64(state)),
        Column::new("decision_point", Values::U64(point)),
        Column::new("region", Values::Text(region)),
        Column::new("delta", Values::F64(delta)),
        Column::new("omega", Values::F64(omega)),
    ];
    Ok((text, table_into_py(py, table)?))
}

/// `etp run`'s arguments, parsed by the launcher's own clap definition
/// (the same flags, defaults and checks as the CLI).
#[derive(Debug, Parser)]
#[command(name = "etp run")]
struct RunCommand {
    #[command(flatten)]
    args: etp_launcher::Args,
}

/// Run like `etp run ARGS… --json` through `etp_launcher::execute`: the
/// report's JSON text and the run's problems `(exit code, text)` (empty
/// for a clean run). The run's processes are found in `ETP_PROCESS_DIR`
/// (`etp_launcher::process::sibling_binary`; the Python side sets it).
/// Raises `RunError` with `etp run`'s message for a run that could not
/// start or finish.
#[pyfunction]
pub fn run(py: Python<'_>, args: Vec<String>) -> PyResult<(String, Vec<(u8, String)>)> {
    let argv = std::iter::once("etp run".to_string())
        .chain(args)
        .chain(std::iter::once("--json".to_string()));
    let cmd = RunCommand::try_parse_from(argv).map_err(|e| RunError::new_err(e.to_string()))?;
    let report = py.detach(|| etp_launcher::execute(&cmd.args));
    let (v, problems) = report.map_err(|e| RunError::new_err(anyhow_text(&e)))?;
    let text = serde_json::to_string(&v).map_err(|e| RunError::new_err(e.to_string()))?;
    Ok((text, problems))
}
