//! The constant-threshold simulation `etp simulate` prints and `etp bench`
//! times, written once. It stays in this crate: a build with it in
//! `etp-synthesis` (and the leg loop through `episode::serve_slot`) ran the
//! bench of winding-2d at 0.55–0.65 of its speed (interleaved medians);
//! which of the two cost it was not isolated.

use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::Threshold;
use etp_shared::rng::streams;
use etp_shared::scenario::Scenario;
use etp_shared::with_dim;
use etp_synthesis::simulate::{SimulationSummary, simulate};

/// Simulate `episodes` episodes of `scenario` with the constant threshold
/// `delta` on every leg, on stream `SIMULATE` of `seed` (all threads, and the ranks of the
/// progress's executor).
pub fn simulate_constant(
    scenario: &Scenario,
    delta: f64,
    episodes: u64,
    seed: u64,
    progress: &dyn etp_synthesis::exec::Work,
) -> Result<SimulationSummary, etp_synthesis::exec::ExecError> {
    let t = Threshold::new(delta);
    with_dim!(scenario.dim, N => {
        let c = CompiledScenario::<N>::new(scenario);
        let policy = move |_: usize, _: &_, _: &mut _| LegMode::<N>::EventTriggered(t);
        Ok(simulate(&c, &policy, episodes, seed, streams::SIMULATE, progress)?.summary())
    })
}
