//! Whether a scenario can work at all (docs/MODEL.md §1.1): every field may be
//! well formed and the whole still be a task no estimator or controller can
//! carry out. Refused here, naming the field:
//!
//! * a direction of the state that no sensor serving a leg ever learns and
//!   that does not decay by itself (the pair (F, stacked H) is not
//!   detectable): its uncertainty only grows, whatever the thresholds;
//! * dynamics whose growth over the episode's horizon is more than f64 and
//!   the filter's covariance can carry;
//! * a controller whose saturated input cannot cover a leg within `k_max`
//!   steps.
//!
//! The noise covariances' own condition is checked with the fields
//! ([`super::fields::spd`], [`CONDITION_MAX`]).

use super::workspace_gain::RANK_RTOL;
use super::{ControllerParams, Leg, Plant, ScenarioError, Sensor};
use nalgebra::{DMatrix, DVector};

type Result<T> = std::result::Result<T, ScenarioError>;

/// The largest condition number (and covariance growth, squared) a scenario
/// may bring: three decimal digits short of f64's `1/ε ≈ 4.5e15`, beyond
/// which the smallest eigenvalue of a covariance is below the rounding of its
/// largest and the matrix is singular in f64 (no Kalman gain, no NEES). The
/// three digits are the margin the filter's arithmetic (prediction, Joseph
/// update, the LDL of NEES) needs to keep a covariance positive definite.
pub(super) const CONDITION_MAX: f64 = 1e-3 / f64::EPSILON;

/// Unobserved modes of modulus at least `1 − DECAY_MARGIN` count as not
/// decaying (a modulus of exactly 1 computes as 1 ± a few ε).
const DECAY_MARGIN: f64 = 1e-9;

/// Every power `F^k` up to this many steps is measured; beyond, the powers of
/// two and the horizon itself.
const GROWTH_STEPS_EACH: u64 = 4096;

/// Steps of the controller's reach summed at most (a larger `k_max` with a
/// reach still short of the leg is accepted: the bound cannot refuse it).
const REACH_STEPS_MAX: u32 = 1 << 16;

/// The checks of this module on a scenario whose fields are valid; the
/// warnings `etp check` shows (a direction no sensor observes but that decays).
pub(super) fn check(
    plant: &Plant,
    workspace: Option<&DMatrix<f64>>,
    controller: &ControllerParams,
    sensors: &[Sensor],
    legs: &[Leg],
    route_start: &DVector<f64>,
) -> Result<Vec<String>> {
    let horizon = legs.len() as u64 * u64::from(controller.k_max);
    horizon_growth(&plant.f, horizon)?;
    let warnings = detectable(&plant.f, sensors, legs)?;
    reach(plant, workspace, controller, legs, route_start)?;
    Ok(warnings)
}

/// `(F, H)` with H the rows of every sensor that serves a leg (a sensor
/// serving none never measures): refused when a direction of the state is
/// never observed and does not decay (undetectable); a warning when it is
/// never observed but decays (its estimate is its prior's prediction).
fn detectable(f: &DMatrix<f64>, sensors: &[Sensor], legs: &[Leg]) -> Result<Vec<String>> {
    let serving: Vec<usize> = (0..sensors.len())
        .filter(|&i| legs.iter().any(|l| l.sensor == i))
        .collect();
    let field = serving
        .iter()
        .map(|&i| format!("sensor[{i}] \"{}\".H", sensors[i].name))
        .collect::<Vec<_>>()
        .join(", ");
    let n = f.nrows();
    let rows: usize = serving.iter().map(|&i| sensors[i].h.nrows()).sum();
    let mut h = DMatrix::zeros(rows, n);
    let mut at = 0;
    for &i in &serving {
        let hi = &sensors[i].h;
        h.view_mut((at, 0), (hi.nrows(), n)).copy_from(hi);
        at += hi.nrows();
    }
    let observed = observable_rows(f, &h).ok_or_else(|| {
        ScenarioError::invalid(&field, "the observability test did not converge (SVD)")
    })?;
    if observed.nrows() == n {
        return Ok(Vec::new());
    }
    // The unobservable subspace is F-invariant: F restricted to it decides.
    let unobserved = complement(&observed);
    let restricted = unobserved.transpose() * f * &unobserved;
    let rho = nalgebra::Schur::try_new(restricted, f64::EPSILON, 10_000)
        .map(|s| {
            s.complex_eigenvalues()
                .iter()
                .map(|c| c.norm())
                .fold(0.0, f64::max)
        })
        .ok_or_else(|| {
            ScenarioError::invalid(&field, "the detectability test did not converge (Schur)")
        })?;
    let directions = unobserved
        .column_iter()
        .map(|c| {
            // Signed so that its largest entry is positive; −0 printed as 0.
            let sign = if c
                .iter()
                .fold(0.0_f64, |m, &x| if x.abs() > m.abs() { x } else { m })
                < 0.0
            {
                -1.0
            } else {
                1.0
            };
            let v: Vec<String> = c
                .iter()
                .map(|x| format!("{:.3}", (sign * x * 1e3).round() / 1e3 + 0.0))
                .collect();
            format!("({})", v.join(", "))
        })
        .collect::<Vec<_>>()
        .join(", ");
    let what = format!(
        "the sensors serving legs, together and through model.F, observe only {} of the \
         {n} state directions (observability rank {} < n); no measurement ever reaches \
         {directions}",
        observed.nrows(),
        observed.nrows()
    );
    if rho.is_nan() || rho >= 1.0 - DECAY_MARGIN {
        Err(ScenarioError::invalid(
            field,
            format!(
                "{what}, and model.F does not damp it (spectral radius {rho:.6} there): its \
                 uncertainty never shrinks (not detectable); measure it with a sensor's H"
            ),
        ))
    } else {
        Ok(vec![format!(
            "{field}: {what}; it decays by itself (spectral radius {rho:.6} there), so its \
             estimate is the prediction from model.x0 and model.P0 alone"
        )])
    }
}

/// An orthonormal basis (rows) of the observable subspace of (F, H): the
/// smallest subspace holding H's rows and closed under `v ↦ v F`, grown a
/// block at a time (the staircase form, orthogonal at every step rather than
/// the ill-scaled powers of `[H; H F; …; H F^{n−1}]`). A new direction counts
/// when its component outside the basis exceeds `RANK_RTOL` of the scale of
/// what produced it (‖H‖, then ‖F‖ times a unit row). `None`: an SVD did not
/// converge.
fn observable_rows(f: &DMatrix<f64>, h: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = f.ncols();
    let f_scale = f
        .clone()
        .try_svd(false, false, f64::EPSILON, 10_000)?
        .singular_values
        .max();
    let h_scale = h
        .clone()
        .try_svd(false, false, f64::EPSILON, 10_000)?
        .singular_values
        .max();
    let mut basis = DMatrix::<f64>::zeros(0, n);
    let (mut candidates, mut scale) = (h.clone(), h_scale);
    while basis.nrows() < n && candidates.nrows() > 0 && scale > 0.0 {
        // Outside the basis (projected twice: once is not orthogonal enough
        // after cancellation).
        let mut rest = candidates;
        for _ in 0..2 {
            rest = &rest - &rest * basis.transpose() * &basis;
        }
        let svd = rest.try_svd(false, true, f64::EPSILON, 10_000)?;
        let v_t = svd.v_t?;
        let new: Vec<usize> = (0..svd.singular_values.len())
            .filter(|&i| svd.singular_values[i] > RANK_RTOL * scale)
            .take(n - basis.nrows())
            .collect();
        if new.is_empty() {
            break;
        }
        let added = DMatrix::from_fn(new.len(), n, |i, j| v_t[(new[i], j)]);
        candidates = &added * f;
        scale = f_scale;
        basis = stack(&basis, &added);
    }
    Some(basis)
}

fn stack(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(a.nrows() + b.nrows(), a.ncols());
    m.view_mut((0, 0), a.shape()).copy_from(a);
    m.view_mut((a.nrows(), 0), b.shape()).copy_from(b);
    m
}

/// An orthonormal basis (columns) of the orthogonal complement of the rows
/// of `rows` (themselves orthonormal): the eigenvectors of `I − rowsᵀ rows`
/// of eigenvalue ≈ 1.
fn complement(rows: &DMatrix<f64>) -> DMatrix<f64> {
    let n = rows.ncols();
    let projector = DMatrix::identity(n, n) - rows.transpose() * rows;
    let eig = projector.symmetric_eigen();
    let keep: Vec<usize> = (0..n).filter(|&i| eig.eigenvalues[i] > 0.5).collect();
    DMatrix::from_fn(n, keep.len(), |i, j| eig.eigenvectors[(i, keep[j])])
}

/// `‖F^k‖_F` (≥ the spectral norm: the growth of every direction) for every
/// `k ≤ T` that matters (each up to
/// [`GROWTH_STEPS_EACH`], then powers of two and T), T = legs × k_max the
/// longest episode: over it the agent may predict without a measurement (a
/// dead link predicts for the rest of the run), so its covariance grows by
/// up to `‖F^k‖²`, and the next measurement cancels a prior that much larger
/// than what remains, at a relative rounding cost of `ε ‖F^k‖²`. Refused
/// when `‖F^k‖² > CONDITION_MAX`.
fn horizon_growth(f: &DMatrix<f64>, horizon: u64) -> Result<()> {
    let limit = CONDITION_MAX.sqrt();
    let refuse = |k: u64, g: f64| {
        Err(ScenarioError::invalid(
            "model.F",
            format!(
                "grows too fast for the episode's horizon: ‖F^{k}‖ = {g:.3e} within the \
                 longest episode (legs × controller.k_max = {horizon} steps), above \
                 √(1e-3/ε) = {limit:.3e}; a covariance propagated that far (a silent or dead \
                 link) is {:.1e} times larger than after a measurement, more than f64 resolves \
                 (docs/MODEL.md §1.1)",
                g * g
            ),
        ))
    };
    let mut power = f.clone();
    for k in 1..=horizon.min(GROWTH_STEPS_EACH) {
        let g = power.norm();
        if g.is_nan() || g > limit {
            return refuse(k, g);
        }
        power = &power * f;
    }
    if horizon <= GROWTH_STEPS_EACH {
        return Ok(());
    }
    // F^{2^j} by squaring; F^T as the product over T's bits (every partial
    // product is a power ≤ T, so each is checked too).
    let (mut square, mut exponent) = (f.clone(), 1_u64);
    let (mut acc, mut acc_exponent) = (DMatrix::<f64>::identity(f.nrows(), f.ncols()), 0_u64);
    loop {
        if horizon & exponent != 0 {
            acc = &acc * &square;
            acc_exponent += exponent;
            let g = acc.norm();
            if g.is_nan() || g > limit {
                return refuse(acc_exponent, g);
            }
        }
        match exponent.checked_mul(2) {
            Some(e) if e <= horizon => exponent = e,
            _ => return Ok(()),
        }
        square = &square * &square;
        let g = square.norm();
        if g.is_nan() || g > limit {
            return refuse(exponent, g);
        }
    }
}

/// Within a leg of `k_max` steps the saturated input (`‖u‖ ≤ u_max`) moves the
/// workspace point by at most `u_max Σ_{j<k_max} ‖C F^j G‖₂`. A leg longer than that plus `ε_x` cannot
/// be flown: refused on `controller.u_max`. The free motion of F is not
/// counted: a waypoint is a reference for the controller to fly to.
fn reach(
    plant: &Plant,
    workspace: Option<&DMatrix<f64>>,
    controller: &ControllerParams,
    legs: &[Leg],
    route_start: &DVector<f64>,
) -> Result<()> {
    let lengths: Vec<f64> = legs
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let from = if i == 0 { route_start } else { &legs[i - 1].to };
            (&l.to - from).norm()
        })
        .collect();
    let Some((longest, need)) = lengths
        .iter()
        .enumerate()
        .map(|(i, &l)| (i, l - controller.eps_x))
        .max_by(|a, b| a.1.total_cmp(&b.1))
    else {
        return Ok(());
    };
    if need <= 0.0 {
        return Ok(());
    }
    let steps = controller.k_max;
    if steps > REACH_STEPS_MAX {
        return Ok(());
    }
    let mut moved = plant.g.clone(); // F^j G
    let mut reach = 0.0;
    for _ in 0..steps {
        let to_workspace = spectral_norm(&match workspace {
            Some(c) => c * &moved,
            None => moved.clone(),
        });
        reach += controller.u_max * to_workspace;
        if reach >= need {
            return Ok(());
        }
        moved = &plant.f * &moved;
    }
    Err(ScenarioError::invalid(
        "controller.u_max",
        format!(
            "the controller cannot move the agent along the route: with ‖u‖ ≤ u_max = {:e} it \
             moves the workspace point by at most {reach:.3e} in a leg of controller.k_max = \
             {steps} steps (u_max Σ_j ‖C F^j G‖₂), but leg[{longest}] is {:.3} long and ends \
             only within controller.eps_x = {} of its waypoint",
            controller.u_max, lengths[longest], controller.eps_x
        ),
    ))
}

/// The largest singular value (Frobenius, an upper bound, if the SVD does
/// not converge).
fn spectral_norm(m: &DMatrix<f64>) -> f64 {
    m.clone()
        .try_svd(false, false, f64::EPSILON, 10_000)
        .map_or_else(|| m.norm(), |svd| svd.singular_values.max())
}
