//! `etpareto.study`: a study as `etp study SPEC -o DIR --json` runs it,
//! through `etp_pipeline::study::run` (the library that command calls):
//! the same case files, the same tables, the same JSON; a killed study
//! resumes on the same folder. The SPEC is a file or its keys as JSON
//! (a Python dict), parsed into the typed `Spec` either way.

use crate::errors::study_error;
use crate::pipeline::with_progress;
use etp_pipeline::study::spec::Spec;
use etp_pipeline::study::{Silent, StudyRequest};
use etp_synthesis::exec::Executor;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};

/// Run the study of the SPEC file `spec_file`, or of the SPEC `spec_json`
/// (its keys as JSON: scenario paths relative to the working folder, the
/// name `study` unless it sets one), in `out` (default
/// `out/study-<name>`). Returns `study.json`'s text.
#[pyfunction]
#[pyo3(signature = (spec_file = None, spec_json = None, out = None, progress = None))]
pub fn study(
    py: Python<'_>,
    spec_file: Option<PathBuf>,
    spec_json: Option<String>,
    out: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let spec = match (spec_file, spec_json) {
        (Some(path), None) => Spec::load(&path),
        (None, Some(text)) => Spec::from_json(&text, "study", Path::new(".")).map_err(Into::into),
        _ => {
            return Err(pyo3::exceptions::PyTypeError::new_err(
                "give exactly one of spec_file, spec_json",
            ));
        }
    }
    .map_err(study_error)?;
    let work = move |progress| {
        let request = StudyRequest {
            spec,
            out,
            progress,
        };
        etp_pipeline::study::run(&request, &Executor::LOCAL, &mut Silent)
    };
    let done = with_progress(py, progress, work)?.map_err(study_error)?;
    // One process is rank 0 of its own executor: the outcome is there.
    done.map(|d| d.json)
        .ok_or_else(|| crate::errors::EtpError::new_err("the study ended on a rank other than 0"))
}
