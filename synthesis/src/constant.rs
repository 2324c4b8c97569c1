//! The constant-threshold simulation, written once: `etp simulate` prints
//! it, `etp bench` and `etp trigger-curves` time and sweep it, and the
//! Python package's `etpareto.simulate` returns it (with its episodes one
//! row each, [`constant_records`]).
//!
//! The functions are `#[inline]`: their bodies, and so the instantiation of
//! the generic leg loop, are compiled in the calling crate, as they were
//! when this code lived in `etp` (a build with the simulation compiled in
//! this crate, and the leg loop through `episode::serve_slot`, once ran the
//! bench of winding-2d at 0.55–0.65 of its speed; which of the two cost it
//! was not isolated).

use crate::exec::{ExecError, Work};
use crate::records::{Records, records};
use crate::simulate::{SimulationSummary, simulate};
use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::Threshold;
use etp_shared::rng::streams;
use etp_shared::scenario::Scenario;
use etp_shared::with_dim;

/// A threshold that is not a finite number ≥ 0 (the message `etp simulate
/// --delta` prints).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("--delta must be a finite number ≥ 0, got {0}")]
pub struct DeltaError(pub f64);

/// `delta` if it is a threshold: finite and ≥ 0 (0 = full Kalman filter).
pub fn check_delta(delta: f64) -> Result<f64, DeltaError> {
    if delta.is_finite() && delta >= 0.0 {
        // −0 as +0: the same threshold, and one the recording's protobuf
        // (proto3 drops zero scalars) can keep bit for bit.
        Ok(delta + 0.0)
    } else {
        Err(DeltaError(delta))
    }
}

/// Simulate `episodes` episodes of `scenario` with the constant threshold
/// `delta` on every leg, on stream `SIMULATE` of `seed` (all threads, and the ranks of the
/// progress's executor).
#[inline]
pub fn simulate_constant(
    scenario: &Scenario,
    delta: f64,
    episodes: u64,
    seed: u64,
    progress: &dyn Work,
) -> Result<SimulationSummary, ExecError> {
    let t = Threshold::new(delta);
    with_dim!(scenario.dim, N => {
        let c = CompiledScenario::<N>::new(scenario);
        let policy = move |_: usize, _: &_, _: &mut _| LegMode::<N>::EventTriggered(t);
        Ok(simulate(&c, &policy, episodes, seed, streams::SIMULATE, progress)?.summary())
    })
}

/// The episodes of [`simulate_constant`] with the same arguments (the same
/// streams, so the same episodes), one record per episode and per leg.
#[inline]
pub fn constant_records(
    scenario: &Scenario,
    delta: f64,
    episodes: u64,
    seed: u64,
    progress: &dyn Work,
) -> Result<Records, ExecError> {
    let t = Threshold::new(delta);
    with_dim!(scenario.dim, N => {
        let c = CompiledScenario::<N>::new(scenario);
        let policy = move |_: usize, _: &_, _: &mut _| LegMode::<N>::EventTriggered(t);
        records(&c, &policy, episodes, seed, streams::SIMULATE, progress)
    })
}

#[cfg(test)]
mod tests {
    use super::check_delta;

    #[test]
    fn a_threshold_is_finite_and_non_negative_and_minus_zero_is_plus_zero() {
        assert_eq!(check_delta(1.5), Ok(1.5));
        assert_eq!(check_delta(-0.0).map(f64::to_bits), Ok(0.0f64.to_bits()));
        assert_eq!(check_delta(-0.5), Err(super::DeltaError(-0.5)));
        assert!(check_delta(f64::NAN).is_err() && check_delta(f64::INFINITY).is_err());
    }
}
