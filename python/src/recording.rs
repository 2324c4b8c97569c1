//! `etpareto.read_recording`: an MCAP recording of `etp run --record` as
//! one table per channel, decoded by `etp_recording_tools::export::Rows`
//! (the decoding of `etp replay export`), streamed from disk chunk by chunk:
//! only the columns being built are held, never the file's messages.

use crate::columns::{Column, table_into_py};
use crate::errors::{RecordingError, anyhow_text};
use etp_recording_tools::export::Rows;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A recording's metadata records: name → key → value.
type Metadata = BTreeMap<String, BTreeMap<String, String>>;

/// Read the finished recording at `path`: `(tables, metadata)`, tables a
/// dict topic → columns (see `columns::Column::into_py`), metadata the
/// recording's metadata records (name → dict). Raises `RecordingError`
/// with `etp replay export`'s message for an unreadable or damaged file.
#[pyfunction]
pub fn read_recording<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyDict>, Metadata)> {
    let read = py.detach(|| -> anyhow::Result<_> {
        if !etp_runtime::recording::ends_finished(&path).unwrap_or(false) {
            anyhow::bail!(
                "{} is unfinished (its recorder stopped before finishing it): \
                 `etp replay repair {} OUT` writes a finished copy",
                path.display(),
                path.display()
            );
        }
        let rows = Rows::open(&path)?;
        let mut columns: BTreeMap<String, Vec<Column>> = rows
            .tables
            .iter()
            .map(|(topic, t)| {
                let cols = t
                    .columns
                    .iter()
                    .map(|c| Column::of_type(&c.name, c.ty))
                    .collect();
                (topic.clone(), cols)
            })
            .collect();
        rows.for_each(|topic, cells| {
            if let Some(cols) = columns.get_mut(topic) {
                for (c, cell) in cols.iter_mut().zip(cells) {
                    c.push(cell);
                }
            }
            Ok(())
        })?;
        Ok((columns, rows.contents.metadata))
    });
    let (columns, metadata) = read.map_err(|e| RecordingError::new_err(anyhow_text(&e)))?;
    let tables = PyDict::new(py);
    for (topic, cols) in columns {
        tables.set_item(topic, table_into_py(py, cols)?)?;
    }
    Ok((tables, metadata))
}
