//! Files of a synthesis read for Python — `front.json`
//! (`ParetoFront::from_json`), `strategy.json` (`etp_runtime::load_strategy`,
//! the loader of `etp validate`: seal and scenario hash checked) and
//! `mdp.bin` as Storm's DRN text (`etp export --format drn`) — and a
//! multi-process run through `etp-launcher`, its report the object `etp run
//! --json` prints.

use crate::columns::{Column, Values, table_into_py};
use crate::errors::{
    FileFormatError, RunRequestError, chain, launcher_error, launcher_error_under, pipeline_error,
};
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
    let (mdp, _) = etp_pipeline::output::read_mdp(&dir).map_err(pipeline_error)?;
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

/// A JSON object of run-file keys, read key by key so that a wrong type is
/// named by its key (serde_json's own message gives a line and column only).
fn run_keys(keys: &str) -> Result<etp_launcher::config::RunConfig, String> {
    use serde_json::{Map, Value};
    let object: Map<String, Value> =
        serde_json::from_str(keys).map_err(|e| format!("run keys: {e}"))?;
    for (key, value) in &object {
        let one = Value::Object(Map::from_iter([(key.clone(), value.clone())]));
        serde_json::from_value::<etp_launcher::config::RunConfig>(one)
            .map_err(|e| format!("run key `{key}` = {value}: {e}"))?;
    }
    serde_json::from_value(Value::Object(object)).map_err(|e| format!("run keys: {e}"))
}

/// A run (`etp_launcher::execute`, as `etp run … --json`): `keys` is a
/// JSON object of run-file keys (`etp run --config`'s, e.g. `{"scenario":
/// "open-2d", "delta": 1.0518, "loss": 0.3}`; an unknown key or a wrong type
/// is refused by name), over the run file `config` if given (a key in
/// `keys` wins), checked by the same `RunRequest::from_config` as the
/// command line. Returns the report's JSON text and the run's problems
/// `(exit code, text)` (empty for a clean run). The run's processes are
/// found in `ETP_PROCESS_DIR` (`etp_launcher::process::sibling_binary`; the
/// Python side sets it). A run that could not start or finish raises the
/// `RunError` subclass of its kind (`errors::launcher_error`) with the text
/// `etp run` prints after `error: `.
#[pyfunction]
#[pyo3(signature = (keys, config=None, force=false))]
pub fn run(
    py: Python<'_>,
    keys: &str,
    config: Option<PathBuf>,
    force: bool,
) -> PyResult<(String, Vec<(u8, String)>)> {
    use etp_launcher::config as run_file;
    let given = run_keys(keys).map_err(RunRequestError::new_err)?;
    let request = match &config {
        // As `etp run --config`: the file's own errors name it; a request
        // refused over it gets `run file PATH: ` in front.
        Some(path) => {
            let file = run_file::read(path).map_err(launcher_error)?;
            etp_launcher::RunRequest::from_config(run_file::merge(given, file))
                .map_err(|e| launcher_error_under(&format!("run file {}", path.display()), e))
        }
        None => etp_launcher::RunRequest::from_config(given).map_err(launcher_error),
    }?;
    let request = etp_launcher::RunRequest {
        force,
        json: true,
        ..request
    };
    let report = py.detach(|| etp_launcher::execute(&request));
    let (v, problems) = report.map_err(launcher_error)?;
    let text = serde_json::to_string(&v).map_err(|e| launcher_error(e.into()))?;
    Ok((text, problems))
}
