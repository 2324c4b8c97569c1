//! Tables handed to Python column by column: numbers as little-endian bytes
//! (`numpy.frombuffer`, no copy per value), names as lists of `str`, and a
//! null mask where a column has gaps. `etpareto._frames` builds the
//! pandas DataFrame from them.

use etp_runtime::recording::table::{Cell, ColumnType};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyList, PyTuple};

/// One column's values, in the column's type.
#[derive(Debug)]
pub enum Values {
    U64(Vec<u64>),
    I64(Vec<i64>),
    F64(Vec<f64>),
    Bool(Vec<bool>),
    Text(Vec<Option<String>>),
}

/// A named column with its null mask (`nulls[i]`: row i has no value).
#[derive(Debug)]
pub struct Column {
    pub name: String,
    pub values: Values,
    pub nulls: Vec<bool>,
}

impl Column {
    pub fn new(name: impl Into<String>, values: Values) -> Self {
        Self {
            name: name.into(),
            values,
            nulls: Vec::new(),
        }
    }

    /// An empty column of a recording table's type.
    pub fn of_type(name: &str, ty: ColumnType) -> Self {
        let values = match ty {
            ColumnType::Uint => Values::U64(Vec::new()),
            ColumnType::Int => Values::I64(Vec::new()),
            ColumnType::Float => Values::F64(Vec::new()),
            ColumnType::Bool => Values::Bool(Vec::new()),
            ColumnType::Text => Values::Text(Vec::new()),
        };
        Self::new(name, values)
    }

    fn len(&self) -> usize {
        match &self.values {
            Values::U64(v) => v.len(),
            Values::I64(v) => v.len(),
            Values::F64(v) => v.len(),
            Values::Bool(v) => v.len(),
            Values::Text(v) => v.len(),
        }
    }

    /// Append one cell of a recording row. A cell of another type than the
    /// column's (never made by `Table::row`) or a null is a gap: a NaN in
    /// a float column, a masked row elsewhere.
    pub fn push(&mut self, cell: Cell) {
        let row = self.len();
        let gap = match (&mut self.values, cell) {
            (Values::U64(v), Cell::Uint(x)) => {
                v.push(x);
                false
            }
            (Values::I64(v), Cell::Int(x)) => {
                v.push(x);
                false
            }
            (Values::F64(v), Cell::Float(x)) => {
                v.push(x);
                false
            }
            (Values::Bool(v), Cell::Bool(x)) => {
                v.push(x);
                false
            }
            (Values::Text(v), Cell::Text(x)) => {
                v.push(Some(x));
                false
            }
            (Values::U64(v), _) => {
                v.push(0);
                true
            }
            (Values::I64(v), _) => {
                v.push(0);
                true
            }
            (Values::F64(v), _) => {
                v.push(f64::NAN);
                false
            }
            (Values::Bool(v), _) => {
                v.push(false);
                true
            }
            (Values::Text(v), _) => {
                v.push(None);
                false
            }
        };
        if gap {
            self.nulls.resize(row, false);
            self.nulls.push(true);
        }
    }

    /// `(name, dtype, data, mask)`: dtype one of `u8`/`i8`/`f8`/`bool`
    /// (data: bytes) or `str` (data: a list of `str` or `None`); mask the
    /// null rows as bytes, or `None` without gaps.
    pub fn into_py<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let rows = self.len();
        let bytes = |b: Vec<u8>| PyBytes::new(py, &b).into_any();
        let (dtype, data) = match self.values {
            Values::U64(v) => (
                "u8",
                bytes(v.iter().flat_map(|x| x.to_le_bytes()).collect()),
            ),
            Values::I64(v) => (
                "i8",
                bytes(v.iter().flat_map(|x| x.to_le_bytes()).collect()),
            ),
            Values::F64(v) => (
                "f8",
                bytes(v.iter().flat_map(|x| x.to_le_bytes()).collect()),
            ),
            Values::Bool(v) => ("bool", bytes(v.iter().map(|&x| u8::from(x)).collect())),
            Values::Text(v) => ("str", PyList::new(py, v)?.into_any()),
        };
        let mask = if self.nulls.iter().any(|&n| n) {
            let mut m = self.nulls;
            m.resize(rows, false);
            Some(PyBytes::new(
                py,
                &m.iter().map(|&x| u8::from(x)).collect::<Vec<_>>(),
            ))
        } else {
            None
        };
        PyTuple::new(
            py,
            [
                self.name.into_pyobject(py)?.into_any(),
                dtype.into_pyobject(py)?.into_any(),
                data,
                mask.into_pyobject(py)?.into_any(),
            ],
        )
    }
}

/// A table as a list of column tuples ([`Column::into_py`]).
pub fn table_into_py<'py>(py: Python<'py>, columns: Vec<Column>) -> PyResult<Bound<'py, PyList>> {
    let cols = columns
        .into_iter()
        .map(|c| c.into_py(py))
        .collect::<PyResult<Vec<_>>>()?;
    PyList::new(py, cols)
}
