//! `etpareto.read_recording`: an MCAP recording of `etp run --record` as
//! one table per channel, decoded by `etp_recording_tools::export::Rows`
//! (the decoding of `etp replay export`), streamed from disk chunk by chunk:
//! only the columns being built are held, never the file's messages.

use crate::columns::{Column, table_into_py};
use crate::errors::{RecordingUnfinishedError, recording_error};
use etp_recording_tools::export::Rows;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A recording's metadata records: name → key → value.
type Metadata = BTreeMap<String, BTreeMap<String, String>>;

/// Read the finished recording at `path`: `(tables, metadata)`, tables a
/// dict topic → columns (see `columns::Column::into_py`), metadata the
/// recording's metadata records (name → dict). A file that cannot be read
/// raises the `RecordingError` subclass of its kind
/// (`errors::recording_error`, `RecordingUnfinishedError` for an unfinished
/// one) with `etp replay`'s words.
#[pyfunction]
pub fn read_recording<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyDict>, Metadata)> {
    let read = py.detach(|| -> PyResult<_> {
        refuse_unfinished(&path)?;
        let rows = Rows::open(&path).map_err(recording_error)?;
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
        })
        .map_err(recording_error)?;
        Ok((columns, rows.contents.metadata))
    });
    let (columns, metadata) = read?;
    let tables = PyDict::new(py);
    for (topic, cols) in columns {
        tables.set_item(topic, table_into_py(py, cols)?)?;
    }
    Ok((tables, metadata))
}

/// Refuse a file that is not a finished recording: the tables are a
/// finished file's (the tools would read an unfinished one leniently). A
/// file that cannot be opened, or that is no MCAP file at all, is refused
/// with the reader's own words, not as unfinished.
fn refuse_unfinished(path: &Path) -> PyResult<()> {
    use etp_recording_tools::Error;
    use std::io::Read;
    let unreadable = |source: std::io::Error| {
        recording_error(Error::Io {
            what: format!("reading {}", path.display()),
            source,
        })
    };
    if etp_runtime::recording::ends_finished(path).map_err(unreadable)? {
        return Ok(());
    }
    let mut head = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(8).read_to_end(&mut head))
        .map_err(unreadable)?;
    // The lenient reader reads any prefix of an MCAP file: it refuses the
    // first bytes only when they are not MCAP's magic.
    etp_runtime::recording::read_lenient(&path.display().to_string(), &head)
        .map_err(|e| recording_error(e.into()))?;
    Err(RecordingUnfinishedError::new_err(format!(
        "{} is unfinished (its recorder stopped before finishing it): \
         `etp replay repair {} OUT` writes a finished copy",
        path.display(),
        path.display()
    )))
}
