//! The magnitude range `[λ_lo, λ_hi]` of the log-uniform bins (docs/MODEL.md §4).
//!
//! * `λ_lo`: the smallest eigenvalue of `P_KF` over the sensors that serve a
//!   leg (the best a filter can do);
//! * `λ_hi`: the largest eigenvalue reached by propagating the covariance with
//!   γ = 0 (silent steps) at the largest δ of the scenario, from `P_KF` and from
//!   `P0`, until it settles or for `k_max` steps (the longest possible leg);
//!   `λmax(P0)` is included so the initial belief is covered.
//!
//! Also the bins of a decision point built from the covariances that arrived
//! there ([`bins_from`]) and the arrivals' range ([`arrival_range`]).

use super::AbstractionParams;
use super::tally::ChunkTally;
use etp_shared::discretization::{DecisionPointBins, WorkspaceMarginal};
use etp_shared::episode::CompiledScenario;
use etp_shared::etkf::Matrix;
use etp_shared::gaussian;
use etp_shared::linalg::to_dynamic;
use etp_shared::trigger::TriggerFamily;
use nalgebra::DMatrix;

/// `[λ_lo, λ_hi]` of the magnitude bins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagnitudeRange {
    pub lambda_lo: f64,
    pub lambda_hi: f64,
}

fn eigenvalues<const N: usize>(m: &Matrix<N, N>) -> (f64, f64) {
    let sym = to_dynamic(&((m + m.transpose()) * 0.5));
    let e = sym.symmetric_eigenvalues();
    let lo = e.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = e.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo, hi)
}

/// The magnitude range of a compiled scenario with thresholds `deltas`;
/// `p_kf[s]` is the steady-state posterior covariance of sensor `s`.
pub fn magnitude_range<const N: usize>(
    cs: &CompiledScenario<N>,
    deltas: &[f64],
    p_kf: &[Matrix<N, N>],
) -> MagnitudeRange {
    let mut lo = f64::INFINITY;
    let mut hi = eigenvalues(&cs.initial.cov).1;
    visit_covariances(cs, deltas, p_kf, |cov, is_kf| {
        let (l, h) = eigenvalues(cov);
        if is_kf {
            lo = lo.min(l);
        }
        hi = hi.max(h);
    });
    if !lo.is_finite() {
        lo = eigenvalues(&cs.initial.cov).0;
    }
    MagnitudeRange {
        lambda_lo: lo,
        lambda_hi: hi,
    }
}

/// The ranges of the workspace-marginal descriptor: eigenvalues of `C P Cᵀ`
/// and `tr(Π P Π)`, over the same covariances as [`magnitude_range`] (lower
/// ends from `P_KF`, upper ends from silent propagation and `P0`).
pub fn workspace_ranges<const N: usize>(
    cs: &CompiledScenario<N>,
    deltas: &[f64],
    p_kf: &[Matrix<N, N>],
    marginal: &dyn Fn(&Matrix<N, N>) -> DMatrix<f64>,
    rest: &dyn Fn(&Matrix<N, N>) -> f64,
) -> (MagnitudeRange, (f64, f64)) {
    let eig = |m: DMatrix<f64>| {
        let e = ((&m + m.transpose()) * 0.5).symmetric_eigenvalues();
        (e.min(), e.max())
    };
    let (mut lo, mut hi) = (f64::INFINITY, eig(marginal(&cs.initial.cov)).1);
    let (mut rlo, mut rhi) = (f64::INFINITY, rest(&cs.initial.cov));
    visit_covariances(cs, deltas, p_kf, |cov, is_kf| {
        let (l, h) = eig(marginal(cov));
        let r = rest(cov);
        if is_kf {
            lo = lo.min(l);
            rlo = rlo.min(r);
        }
        hi = hi.max(h);
        rhi = rhi.max(r);
    });
    if !lo.is_finite() {
        lo = eig(marginal(&cs.initial.cov)).0;
    }
    if !rlo.is_finite() {
        rlo = rest(&cs.initial.cov);
    }
    (
        MagnitudeRange {
            lambda_lo: lo,
            lambda_hi: hi,
        },
        (rlo, rhi),
    )
}

/// Call `visit(cov, is_kf)` on `P_KF` of every sensor serving a leg (`is_kf`)
/// and on every covariance of the silent propagation (γ = 0 at the largest δ)
/// from `P_KF` and from `P0`, until it settles or for `k_max` steps.
fn visit_covariances<const N: usize>(
    cs: &CompiledScenario<N>,
    deltas: &[f64],
    p_kf: &[Matrix<N, N>],
    mut visit: impl FnMut(&Matrix<N, N>, bool),
) {
    let delta_max = deltas.iter().copied().fold(0.0_f64, f64::max);
    // The family's silence factor at the largest δ (docs/MODEL.md §9; at
    // q = 0 it does not depend on m). Send-on-delta's pseudo-measurement
    // and the silence of variance and periodic count as no information:
    // the widest range.
    let beta = match cs.trigger {
        TriggerFamily::Box => gaussian::beta(delta_max),
        family => family.lossy_silence_factor(delta_max, 1, 0.0),
    };
    let mut used: Vec<usize> = cs.legs.iter().map(|l| l.sensor).collect();
    used.sort_unstable();
    used.dedup();
    for &s in &used {
        let f = &cs.filters[s];
        let p_kf = p_kf[s];
        visit(&p_kf, true);
        for start in [p_kf, cs.initial.cov] {
            let mut cov = start;
            for _ in 0..cs.k_max {
                let next = f.silent_covariance_step(&cov, beta);
                let change = (next - cov).amax();
                cov = next;
                visit(&cov, false);
                if change <= 1e-12 * cov.amax().max(f64::MIN_POSITIVE) {
                    break;
                }
            }
        }
    }
}

/// Bins of a decision point from the covariances that arrived there (their
/// mean's eigenvectors are the nominal axes; with the workspace descriptor,
/// the eigenvectors of the mean's workspace marginal `C P̄ Cᵀ`).
pub(super) fn bins_from<const N: usize>(
    params: &AbstractionParams,
    lambda: (f64, f64),
    workspace: Option<&WorkspaceMarginal>,
    covs: impl Iterator<Item = Matrix<N, N>>,
) -> DecisionPointBins {
    let mut sum = Matrix::<N, N>::zeros();
    let mut n = 0u64;
    for c in covs {
        sum += c;
        n += 1;
    }
    let mean = (n > 0).then(|| {
        let m = to_dynamic(&(sum / n as f64));
        match workspace {
            Some(w) => w.marginal(&m),
            None => m,
        }
    });
    let mut b = DecisionPointBins::from_samples(lambda.0, lambda.1, params.bins, mean.iter());
    b.workspace = workspace.cloned();
    b
}

/// The quantile of the arrivals' largest workspace eigenvalue that closes the
/// magnitude range of [`super::RangeRule::Arrivals`] (the top 0.5 % share the last bin).
pub const ARRIVAL_QUANTILE: f64 = 0.995;

/// The magnitude range of a decision point's workspace bins under
/// [`super::RangeRule::Arrivals`]: from the smallest eigenvalue of the arrivals'
/// marginals (not below the `P_KF` floor) to the [`ARRIVAL_QUANTILE`] of
/// their largest. `None` (keep the propagation range) without arrivals or
/// for a degenerate range. Main-sample arrivals only, so the held-out set
/// stays independent of the states.
///
/// The eigenvalues go through the executor (each rank a slice of the
/// chunks): on several ranks no rank decomposes every arrival.
pub(super) fn arrival_range<const N: usize>(
    results: &[ChunkTally<N>],
    workspace: &WorkspaceMarginal,
    floor: f64,
    progress: &dyn crate::exec::Work,
) -> Result<Option<(f64, f64)>, crate::exec::ExecError> {
    let per_chunk: Vec<Vec<(f64, f64)>> = crate::exec::map(
        progress,
        results.len(),
        |i| {
            results[i]
                .arrivals
                .iter()
                .map(|a| {
                    let m = workspace.marginal(&to_dynamic(&a.belief.cov));
                    let e = ((&m + m.transpose()) * 0.5).symmetric_eigenvalues();
                    (e.min(), e.max())
                })
                .collect()
        },
        |_| 0,
    )?;
    let mut pairs: Vec<(f64, f64)> = per_chunk.into_iter().flatten().collect();
    if pairs.is_empty() {
        return Ok(None);
    }
    let lo = pairs
        .iter()
        .map(|p| p.0)
        .fold(f64::INFINITY, f64::min)
        .max(floor);
    pairs.sort_by(|a, b| a.1.total_cmp(&b.1));
    let k = ((pairs.len() as f64 * ARRIVAL_QUANTILE) as usize).min(pairs.len() - 1);
    let hi = pairs[k].1;
    Ok((lo.is_finite() && hi > lo * (1.0 + 1e-6)).then_some((lo, hi)))
}
