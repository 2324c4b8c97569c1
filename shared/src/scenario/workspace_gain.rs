//! Validation of the fields of MODEL.md §7 (linear agents of higher dimension):
//! the workspace map `[model] C`, the feedback gain `[controller] K` or its LQR
//! weights `[controller.lqr]`, and the rest-point warning for `C⁺ w`.

use super::fields::{matrix, spd};
use super::raw::{RawController, RawMatrix};
use super::{Leg, Plant, ScenarioError};
use crate::lqr::{LqrError, lqr_gain};
use nalgebra::{DMatrix, DVector};

type Result<T> = std::result::Result<T, ScenarioError>;

/// Singular-value ratio under which a matrix counts as rank deficient (C,
/// and the observability test of `workable`).
pub(super) const RANK_RTOL: f64 = 1e-9;
/// Relative tolerance of the rest-point check `F C⁺ w = C⁺ w`.
const REST_RTOL: f64 = 1e-9;

/// `[model] C`: d×n with 1 ≤ d ≤ n, full row rank.
pub(super) fn workspace_map(raw: &RawMatrix, n: usize) -> Result<DMatrix<f64>> {
    let d = raw.len();
    if d == 0 || d > n {
        return Err(ScenarioError::invalid(
            "model.C",
            format!("must be d×n with n = dim = {n} and 1 <= d <= n, got {d} rows"),
        ));
    }
    let c = matrix("model.C", raw, Some(d), n)?;
    let sv = c.clone().svd(false, false).singular_values;
    let (lo, hi) = (sv.min(), sv.max());
    if !(hi > 0.0 && lo > RANK_RTOL * hi) {
        return Err(ScenarioError::invalid(
            "model.C",
            format!(
                "must have full row rank d = {d} (smallest singular value {lo:e}, largest {hi:e})"
            ),
        ));
    }
    Ok(c)
}

/// `C⁺ = Cᵀ (C Cᵀ)⁻¹`: the least-norm state with `C x = w` (zero velocity for
/// C = [I 0]). C has full row rank, so C Cᵀ is invertible.
pub fn pseudo_inverse(c: &DMatrix<f64>) -> DMatrix<f64> {
    let cct = c * c.transpose();
    let inv = cct
        .clone()
        .try_inverse()
        .unwrap_or_else(|| DMatrix::zeros(cct.nrows(), cct.ncols()));
    c.transpose() * inv
}

/// K from `[controller] K` or `[controller.lqr]`; `None` = K = I (needs p = n).
pub(super) fn feedback_gain(raw: &RawController, plant: &Plant) -> Result<Option<DMatrix<f64>>> {
    let (n, p) = (plant.f.nrows(), plant.g.ncols());
    match (&raw.k, &raw.lqr) {
        (Some(_), Some(_)) => Err(ScenarioError::invalid(
            "controller.K",
            "give either [controller] K or [controller.lqr], not both",
        )),
        (Some(k), None) => Ok(Some(matrix("controller.K", k, Some(p), n)?)),
        (None, Some(lqr)) => {
            let q = psd("controller.lqr.state", &lqr.state, n)?;
            let r = spd("controller.lqr.input", &lqr.input, p)?;
            match lqr_gain(&plant.f, &plant.g, &q, &r) {
                Ok(k) => Ok(Some(k)),
                Err(e @ (LqrError::NoStabilisingSolution(_) | LqrError::Unstable(_))) => Err(
                    ScenarioError::invalid("controller.lqr", format!("{e} for (model.F, model.G)")),
                ),
            }
        }
        (None, None) if p != n => Err(ScenarioError::invalid(
            "controller.K",
            format!(
                "model.G has p = {p} columns but dim = {n}: the default gain K = I needs p = n; \
                 give [controller] K ({p}×{n}) or [controller.lqr]"
            ),
        )),
        (None, None) => Ok(None),
    }
}

/// A symmetric positive semi-definite `n × n` matrix.
fn psd(field: &str, raw: &RawMatrix, n: usize) -> Result<DMatrix<f64>> {
    let a = matrix(field, raw, Some(n), n)?;
    let scale = a.amax().max(f64::MIN_POSITIVE);
    if (&a - a.transpose()).amax() > 1e-9 * scale {
        return Err(ScenarioError::invalid(field, "not symmetric"));
    }
    let sym = (&a + a.transpose()) * 0.5;
    let smallest = sym.clone().symmetric_eigenvalues().min();
    if smallest < -1e-12 * scale {
        return Err(ScenarioError::invalid(
            field,
            format!("not positive semi-definite: smallest eigenvalue is {smallest:e}"),
        ));
    }
    Ok(sym)
}

/// One warning per waypoint whose reference `C⁺ w` is not a rest point of F
/// (the agent then cannot stay there with u = 0; MODEL.md §7).
pub(super) fn rest_point_warnings(c: &DMatrix<f64>, f: &DMatrix<f64>, legs: &[Leg]) -> Vec<String> {
    let pinv = pseudo_inverse(c);
    legs.iter()
        .enumerate()
        .filter_map(|(i, l)| {
            let r: DVector<f64> = &pinv * &l.to;
            let drift = (f * &r - &r).amax();
            (drift > REST_RTOL * r.amax().max(1.0)).then(|| {
                format!(
                    "leg[{i}].to: the reference C⁺w is not a rest point of model.F \
                     (‖F C⁺w − C⁺w‖max = {drift:.3e}); the agent cannot hold it with u = 0"
                )
            })
        })
        .collect()
}
