//! The checked fields of a scenario file: finite and positive numbers,
//! vectors, matrices of a shape, symmetric positive definite matrices. Every
//! error names the field and the reason; [`super::validate`] and
//! [`super::workspace_gain`] build on them.

use super::ScenarioError;
use super::raw::RawMatrix;
use super::workable::CONDITION_MAX;
use nalgebra::{DMatrix, DVector};

type Result<T> = std::result::Result<T, ScenarioError>;

pub(super) fn finite(field: &str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be a finite number, got {v}"),
        ))
    }
}

pub(super) fn positive(field: &str, v: f64) -> Result<f64> {
    finite(field, v)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(ScenarioError::invalid(
            field,
            format!("must be > 0, got {v}"),
        ))
    }
}

pub(super) fn vector(field: &str, raw: &[f64], n: usize) -> Result<DVector<f64>> {
    if raw.len() != n {
        return Err(ScenarioError::invalid(
            field,
            format!("must have dim = {n} entries, got {}", raw.len()),
        ));
    }
    for (i, &v) in raw.iter().enumerate() {
        finite(&format!("{field}[{i}]"), v)?;
    }
    Ok(DVector::from_column_slice(raw))
}

/// A `rows × cols` matrix (rows `None`: any non-zero count).
pub(super) fn matrix(
    field: &str,
    raw: &RawMatrix,
    rows: Option<usize>,
    cols: usize,
) -> Result<DMatrix<f64>> {
    let r = raw.len();
    if let Some(want) = rows
        && r != want
    {
        return Err(ScenarioError::invalid(
            field,
            format!("wrong shape: must be {want}x{cols}, got {r} rows"),
        ));
    }
    for (i, row) in raw.iter().enumerate() {
        if row.len() != cols {
            return Err(ScenarioError::invalid(
                field,
                format!(
                    "wrong shape: must be {r}x{cols}, row {i} has {} entries",
                    row.len()
                ),
            ));
        }
        for (j, &v) in row.iter().enumerate() {
            finite(&format!("{field}[{i}][{j}]"), v)?;
        }
    }
    Ok(DMatrix::from_fn(r, cols, |i, j| raw[i][j]))
}

/// A symmetric positive definite `n × n` matrix.
pub(super) fn spd(field: &str, raw: &RawMatrix, n: usize) -> Result<DMatrix<f64>> {
    let a = matrix(field, raw, Some(n), n)?;
    let scale = a.amax().max(f64::MIN_POSITIVE);
    for i in 0..n {
        for j in 0..i {
            if (a[(i, j)] - a[(j, i)]).abs() > 1e-9 * scale {
                return Err(ScenarioError::invalid(
                    field,
                    format!(
                        "not symmetric: [{i}][{j}] = {} but [{j}][{i}] = {}",
                        a[(i, j)],
                        a[(j, i)]
                    ),
                ));
            }
        }
    }
    let sym = (&a + a.transpose()) * 0.5;
    let eigenvalues = sym.clone().symmetric_eigenvalues();
    let (smallest, largest) = (eigenvalues.min(), eigenvalues.max());
    if smallest <= 0.0 || nalgebra::Cholesky::new(sym.clone()).is_none() {
        return Err(ScenarioError::invalid(
            field,
            format!("not positive definite: smallest eigenvalue is {smallest:e}"),
        ));
    }
    // Singular in all but name: the filter inverts covariances built from
    // it (Kalman gain, NEES), which rounding would make indefinite.
    if largest / smallest > CONDITION_MAX {
        return Err(ScenarioError::invalid(
            field,
            format!(
                "numerically singular: condition number {:.3e} (eigenvalues {smallest:e} to \
                 {largest:e}) above 1e-3/ε = {CONDITION_MAX:.3e}, where rounding makes the \
                 filter's covariances indefinite and NEES undefined (docs/MODEL.md §1.1)",
                largest / smallest
            ),
        ));
    }
    Ok(sym)
}
