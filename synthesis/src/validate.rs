//! In-process simulation of a strategy: at each decision point the belief's
//! covariance is classified into its region and δ is drawn from ω (docs/MODEL.md §5,
//! "Validation"). Also collects sample trajectories for the map plot.

use crate::simulate::{SimulationTotals, simulate};
use etp_shared::episode::{CompiledScenario, EpisodeObserver, LegMode, Outcome, StepEvent};
use etp_shared::etkf::{Belief, Threshold};
use etp_shared::gaussian::expected_rate;
use etp_shared::linalg::to_dynamic;
use etp_shared::rng::{SimRng, stream_rng, streams};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Policy;
use etp_shared::with_dim;
use rand::RngExt;

/// The leg policy of a strategy's policy: classify, draw δ with one uniform from the episode's RNG.
fn strategy_policy<const N: usize>(
    policy: &Policy,
) -> impl Fn(usize, &Belief<N>, &mut SimRng) -> LegMode<N> + Sync + '_ {
    let thresholds: Vec<Threshold> = policy.deltas.iter().map(|&d| Threshold::new(d)).collect();
    move |leg, belief, rng| {
        let u: f64 = rng.random();
        let k = policy.draw(leg, &to_dynamic(&belief.cov), u);
        LegMode::EventTriggered(thresholds[k])
    }
}

/// Simulate `episodes` episodes of a strategy's `policy` on `scenario` (all threads, and
/// the ranks of the progress's executor; reproducible).
pub fn simulate_strategy(
    scenario: &Scenario,
    policy: &Policy,
    episodes: u64,
    seed: u64,
    progress: &dyn crate::exec::Work,
) -> Result<SimulationTotals, crate::exec::ExecError> {
    with_dim!(scenario.dim, N => {
        let c = CompiledScenario::<N>::new(scenario);
        simulate(&c, &strategy_policy::<N>(policy), episodes, seed, streams::VALIDATE, progress)
    })
}

/// One point of a sampled trajectory, in the workspace (MODEL.md §7: `C x`,
/// d entries; the state itself when there is no workspace map).
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPoint {
    /// True workspace point `C x`.
    pub x: Vec<f64>,
    /// Estimated workspace point `C x̂`.
    pub mean: Vec<f64>,
    /// γ̄(δ) of the threshold in force (the colour of the paper's Fig. 4).
    pub expected_rate: f64,
    pub transmitted: bool,
}

/// A sampled episode.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    pub points: Vec<TrajectoryPoint>,
    pub outcome: Outcome,
}

struct Recorder<'a, const N: usize> {
    points: Vec<TrajectoryPoint>,
    scenario: &'a CompiledScenario<N>,
    /// Workspace dimension d.
    d: usize,
}

impl<const N: usize> EpisodeObserver<N> for Recorder<'_, N> {
    fn on_step(&mut self, e: &StepEvent<'_, N>) {
        let m = self.scenario.filters[self.scenario.legs[e.leg].sensor].dim();
        let w = &self.scenario.workspace;
        self.points.push(TrajectoryPoint {
            x: w.point(e.x).iter().take(self.d).copied().collect(),
            mean: w
                .point(&e.belief.mean)
                .iter()
                .take(self.d)
                .copied()
                .collect(),
            expected_rate: expected_rate(e.delta, m),
            transmitted: e.transmitted,
        });
    }
}

/// The first `count` validation episodes of a strategy's `policy` from a seed, step by step.
pub fn sample_trajectories(
    scenario: &Scenario,
    policy: &Policy,
    count: u64,
    seed: u64,
) -> Vec<Trajectory> {
    with_dim!(scenario.dim, N => {
        let c = CompiledScenario::<N>::new(scenario);
        let policy = strategy_policy::<N>(policy);
        (0..count)
            .map(|e| {
                let mut rng = stream_rng(seed, streams::VALIDATE, e);
                let mut rec = Recorder { points: Vec::new(), scenario: &c, d: scenario.workspace_dim() };
                let start = scenario.route_start.as_slice().to_vec();
                rec.points.push(TrajectoryPoint { x: start.clone(), mean: start, expected_rate: 1.0, transmitted: false });
                let mut channels = c.channels(seed, streams::VALIDATE, e);
                let r = c.run_episode(&policy, &mut rng, &mut channels, &mut rec);
                Trajectory { points: rec.points, outcome: r.outcome }
            })
            .collect()
    })
}
