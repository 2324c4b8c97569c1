//! The in-process episode simulator.
//!
//! Episode `e` draws all its randomness from `stream_rng(seed, stream, e)`, and
//! episodes are summed in fixed-size chunks merged in index order, so a summary
//! is bit-identical for a given seed whatever the number of threads.

use etp_shared::episode::{
    CompiledScenario, EpisodeObserver, LegMode, LegResult, Outcome, StepEvent,
};
use etp_shared::etkf::Belief;
use etp_shared::rng::{SimRng, stream_rng};
use etp_shared::stats::{Estimate, MeanAccumulator, RatioAccumulator, proportion};
use serde::Serialize;

/// Episodes per work unit: large enough to amortise scheduling, small enough
/// for a smooth progress bar and load balance on 2 cores.
pub(crate) const CHUNK: u64 = 64;

/// `f` of every chunk of [`CHUNK`] episodes of `0..episodes`, in order, on
/// `progress`'s executor (one progress unit per episode): the split that
/// simulation and per-episode records share, so both draw the same streams.
pub(crate) fn map_episode_chunks<T, F>(
    progress: &dyn crate::exec::Work,
    episodes: u64,
    f: F,
) -> Result<Vec<T>, crate::exec::ExecError>
where
    T: serde::Serialize + serde::de::DeserializeOwned + Send,
    F: Fn(std::ops::Range<u64>) -> T + Sync,
{
    let range = |c: usize| {
        let c = c as u64;
        c * CHUNK..((c + 1) * CHUNK).min(episodes)
    };
    crate::exec::map(
        progress,
        episodes.div_ceil(CHUNK) as usize,
        |c| f(range(c)),
        |c| {
            let r = range(c);
            r.end - r.start
        },
    )
}

/// Per-sensor counts over a simulation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct SensorCounts {
    /// Measurement slots the sensor served.
    pub slots: u64,
    /// Transmission attempts (each costs c_m; docs/MODEL.md §8).
    pub transmissions: u64,
    /// Slots whose measurement triggered.
    pub triggers: u64,
    /// Triggers whose measurement reached the agent.
    pub delivered: u64,
    /// Σ γ̄(δ, m) over its slots: the triggers the Gaussian assumption predicts.
    pub expected_triggers: f64,
}

impl SensorCounts {
    /// Attempts lost: `transmissions = delivered + lost`.
    pub fn lost(&self) -> u64 {
        self.transmissions - self.delivered
    }
}

/// Raw sums of a batch of episodes (mergeable).
#[derive(Debug, Clone, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct SimulationTotals {
    pub episodes: u64,
    pub target: u64,
    pub collision: u64,
    pub free: u64,
    pub energy: MeanAccumulator,
    pub steps: MeanAccumulator,
    /// (triggers, slots) per episode.
    pub rate: RatioAccumulator,
    /// (Σ NEES/n of the agent's estimate, slots) per episode.
    pub nees: RatioAccumulator,
    /// (Σ ‖x − x̂‖² of the agent's estimate, slots) per episode.
    pub squared_error: RatioAccumulator,
    /// (expected transmissions Σγ̄, slots) per episode.
    pub expected_rate: RatioAccumulator,
    pub sensors: Vec<SensorCounts>,
}

impl SimulationTotals {
    fn new(num_sensors: usize) -> Self {
        Self {
            sensors: vec![SensorCounts::default(); num_sensors],
            ..Self::default()
        }
    }

    fn merge(&mut self, o: &Self) {
        self.episodes += o.episodes;
        self.target += o.target;
        self.collision += o.collision;
        self.free += o.free;
        self.energy.merge(&o.energy);
        self.steps.merge(&o.steps);
        self.rate.merge(&o.rate);
        self.nees.merge(&o.nees);
        self.squared_error.merge(&o.squared_error);
        self.expected_rate.merge(&o.expected_rate);
        for (a, b) in self.sensors.iter_mut().zip(&o.sensors) {
            a.slots += b.slots;
            a.transmissions += b.transmissions;
            a.triggers += b.triggers;
            a.delivered += b.delivered;
            a.expected_triggers += b.expected_triggers;
        }
    }
}

/// Counts per sensor as legs end, and the episode's consistency sum (also
/// the tally of `crate::records`, so a record's sums are the summary's).
pub(crate) struct SensorTally<'a> {
    pub(crate) sensors: &'a mut [SensorCounts],
    /// Σ over slots of (x − x̂)ᵀ P⁻¹ (x − x̂) / n.
    pub(crate) nees: f64,
    /// Σ over slots of ‖x − x̂‖².
    pub(crate) squared_error: f64,
}

impl<const N: usize> EpisodeObserver<N> for SensorTally<'_> {
    #[inline]
    fn on_step(&mut self, e: &StepEvent<'_, N>) {
        if !e.collided {
            self.nees += normalized_error(e.x, e.belief);
            self.squared_error += (e.x - e.belief.mean).norm_squared();
        }
    }

    #[inline]
    fn on_leg_end(&mut self, _leg: usize, sensor: usize, r: &LegResult) {
        let c = &mut self.sensors[sensor];
        c.slots += u64::from(r.slots);
        c.transmissions += u64::from(r.transmissions);
        c.triggers += u64::from(r.triggers);
        c.delivered += u64::from(r.delivered);
        c.expected_triggers += r.expected_transmissions;
    }
}

/// NEES/n: `(x − x̂)ᵀ P⁻¹ (x − x̂) / n`, ≈ 1 on average for a consistent filter
/// (0 if rounding ever made P not positive definite).
///
/// By P = L D Lᵀ (L unit lower triangular, no square roots): with y = L⁻¹ e,
/// eᵀ P⁻¹ e = Σ yᵢ² / dᵢ. It runs at every simulated step; nalgebra's
/// Cholesky and triangular solves cost a third of the whole step of
/// winding-2d (`etp bench`: 10.1 against 15.0 M steps/s without the NEES).
#[inline]
pub fn normalized_error<const N: usize>(x: &etp_shared::etkf::Vector<N>, b: &Belief<N>) -> f64 {
    let e = x - b.mean;
    let p = &b.cov;
    let mut l = [[0.0_f64; N]; N];
    let mut d = [0.0_f64; N];
    let mut y = [0.0_f64; N];
    let mut q = 0.0;
    for j in 0..N {
        let mut dj = p[(j, j)];
        for k in 0..j {
            dj -= l[j][k] * l[j][k] * d[k];
        }
        if dj.is_nan() || dj <= 0.0 {
            return 0.0;
        }
        d[j] = dj;
        for i in j + 1..N {
            let mut v = p[(i, j)];
            for k in 0..j {
                v -= l[i][k] * l[j][k] * d[k];
            }
            l[i][j] = v / dj;
        }
        let mut yj = e[j];
        for k in 0..j {
            yj -= l[j][k] * y[k];
        }
        y[j] = yj;
        q += yj * yj / dj;
    }
    q / N as f64
}

/// The estimates of a simulation, each with a 95 % half-width.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimulationSummary {
    pub episodes: u64,
    pub p_target: Estimate,
    pub p_collision: Estimate,
    pub p_free: Estimate,
    pub energy_mean: Estimate,
    pub steps_mean: Estimate,
    /// Measured triggers per measurement slot.
    pub trigger_rate: Estimate,
    /// γ̄(δ, m) averaged over the same slots (the filter's Gaussian prediction).
    pub trigger_rate_expected: Estimate,
    pub sensors: Vec<SensorCounts>,
    /// Total plant steps simulated (for throughput figures).
    pub total_steps: u64,
    /// Mean NEES/n of the agent's estimate over the slots (≈ 1: consistent).
    pub nees: Estimate,
    /// Root mean squared estimation error `√(mean over the slots of
    /// ‖x − x̂‖²)` (full state, the scenario's units), its ± by the delta
    /// method from the mean's.
    pub rmse: Estimate,
}

impl SimulationTotals {
    pub fn summary(&self) -> SimulationSummary {
        let n = self.episodes;
        SimulationSummary {
            episodes: n,
            p_target: proportion(self.target, n),
            p_collision: proportion(self.collision, n),
            p_free: proportion(self.free, n),
            energy_mean: self.energy.estimate(),
            steps_mean: self.steps.estimate(),
            trigger_rate: self.rate.estimate(),
            trigger_rate_expected: self.expected_rate.estimate(),
            sensors: self.sensors.clone(),
            total_steps: self.steps.sum as u64,
            nees: self.nees.estimate(),
            rmse: root(self.squared_error.estimate()),
        }
    }
}

/// `√m` of a mean `m` with its ± by the delta method (`h / (2√m)`).
fn root(m: Estimate) -> Estimate {
    let value = m.value.max(0.0).sqrt();
    Estimate {
        value,
        ci95: if value > 0.0 {
            m.ci95 / (2.0 * value)
        } else {
            m.ci95.sqrt()
        },
    }
}

/// Simulate `episodes` episodes under `policy` (called at each leg start with the
/// belief; may draw from the episode's RNG), on random stream `stream` of `seed`.
/// `progress(k)` is called as batches of `k` episodes finish. The chunks run
/// on the progress's executor ([`crate::exec`]): on several ranks each
/// simulates a contiguous slice of them, and every rank gets the same total.
pub fn simulate<const N: usize, P>(
    scenario: &CompiledScenario<N>,
    policy: &P,
    episodes: u64,
    seed: u64,
    stream: u64,
    progress: &dyn crate::exec::Work,
) -> Result<SimulationTotals, crate::exec::ExecError>
where
    P: Fn(usize, &Belief<N>, &mut SimRng) -> LegMode<N> + Sync,
{
    let parts: Vec<SimulationTotals> = map_episode_chunks(progress, episodes, |r| {
        simulate_range(scenario, policy, r, seed, stream)
    })?;
    let mut total = SimulationTotals::new(scenario.filters.len());
    for p in &parts {
        total.merge(p);
    }
    Ok(total)
}

/// Simulate episodes `range` sequentially (one thread).
pub fn simulate_range<const N: usize, P>(
    scenario: &CompiledScenario<N>,
    policy: &P,
    range: std::ops::Range<u64>,
    seed: u64,
    stream: u64,
) -> SimulationTotals
where
    P: Fn(usize, &Belief<N>, &mut SimRng) -> LegMode<N>,
{
    let mut t = SimulationTotals::new(scenario.filters.len());
    for e in range {
        let mut rng = stream_rng(seed, stream, e);
        let mut channels = scenario.channels(seed, stream, e);
        let mut tally = SensorTally {
            sensors: &mut t.sensors,
            nees: 0.0,
            squared_error: 0.0,
        };
        let r = scenario.run_episode(policy, &mut rng, &mut channels, &mut tally);
        let (nees, squared_error) = (tally.nees, tally.squared_error);
        t.episodes += 1;
        match r.outcome {
            Outcome::Target => t.target += 1,
            Outcome::Collision => t.collision += 1,
            Outcome::Free => t.free += 1,
        }
        t.energy.push(r.energy);
        t.steps.push(f64::from(r.steps));
        t.rate.push(f64::from(r.triggers), f64::from(r.slots));
        t.nees.push(nees, f64::from(r.slots));
        t.squared_error.push(squared_error, f64::from(r.slots));
        t.expected_rate
            .push(r.expected_transmissions, f64::from(r.slots));
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_shared::etkf::Threshold;
    use etp_shared::rng::streams;
    use etp_shared::scenario::Scenario;

    fn constant(delta: f64) -> impl Fn(usize, &Belief<2>, &mut SimRng) -> LegMode<2> + Sync {
        let t = Threshold::new(delta);
        move |_, _, _| LegMode::EventTriggered(t)
    }

    #[test]
    fn summary_does_not_depend_on_thread_count() {
        let s = Scenario::builtin("winding-2d").expect("built-in");
        let c = CompiledScenario::<2>::new(&s);
        let par = simulate(
            &c,
            &constant(1.4986),
            300,
            5,
            streams::SIMULATE,
            &|_: u64| {},
        )
        .expect("simulates");
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool")
            .install(|| {
                simulate(
                    &c,
                    &constant(1.4986),
                    300,
                    5,
                    streams::SIMULATE,
                    &|_: u64| {},
                )
                .expect("simulates")
            });
        assert_eq!(par, one);
        assert_eq!(par.target + par.collision + par.free, 300);
        let per_sensor: u64 = par.sensors.iter().map(|s| s.transmissions).sum();
        assert_eq!(per_sensor as f64, par.rate.sum_a);
    }

    /// Golden numbers: the exact outcome of a seed on the reference scenarios.
    /// They change only if the episode rules, the RNG streams or the filter
    /// change — any such change must be deliberate (update them and say why).
    #[test]
    fn golden_numbers_on_the_reference_scenarios() {
        let w = Scenario::builtin("winding-2d").expect("built-in");
        let c = CompiledScenario::<2>::new(&w);
        let t = simulate(&c, &constant(0.0), 3000, 0, streams::SIMULATE, &|_: u64| {})
            .expect("simulates");
        assert_eq!(
            (t.target, t.collision, t.free),
            (2885, 108, 7),
            "winding-2d δ = 0"
        );
        let t = simulate(
            &c,
            &constant(2.2365),
            3000,
            0,
            streams::SIMULATE,
            &|_: u64| {},
        )
        .expect("simulates");
        assert_eq!(
            (t.target, t.collision, t.free),
            (587, 615, 1798),
            "winding-2d δ = 2.2365"
        );
    }

    /// The LDLᵀ quadratic form against nalgebra's Cholesky solve, on random
    /// positive definite matrices of every dimension the scenarios allow.
    #[test]
    fn nees_by_ldl_matches_a_cholesky_solve() {
        fn check<const N: usize>(rng: &mut SimRng) {
            use rand::RngExt;
            for _ in 0..200 {
                let a = nalgebra::SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
                let cov = a * a.transpose() + nalgebra::SMatrix::<f64, N, N>::identity() * 1e-3;
                let mean =
                    etp_shared::etkf::Vector::<N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
                let x = etp_shared::etkf::Vector::<N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
                let b = Belief { mean, cov };
                let e = x - mean;
                let want = cov.cholesky().expect("SPD").solve(&e).dot(&e) / N as f64;
                let got = normalized_error(&x, &b);
                assert!(
                    (got - want).abs() <= 1e-9 * want.abs().max(1.0),
                    "N = {N}: {got} vs {want}"
                );
            }
            // Not positive definite: 0, as before.
            let b = Belief {
                mean: etp_shared::etkf::Vector::<N>::zeros(),
                cov: nalgebra::SMatrix::<f64, N, N>::zeros(),
            };
            assert_eq!(
                normalized_error(&etp_shared::etkf::Vector::<N>::zeros(), &b),
                0.0
            );
        }
        let mut rng = stream_rng(7, 0, 0);
        check::<1>(&mut rng);
        check::<2>(&mut rng);
        check::<3>(&mut rng);
        check::<4>(&mut rng);
        check::<6>(&mut rng);
    }

    #[test]
    fn full_kf_rate_is_one() {
        let s = Scenario::builtin("open-2d").expect("built-in");
        let c = CompiledScenario::<2>::new(&s);
        let t = simulate(&c, &constant(0.0), 50, 1, streams::SIMULATE, &|_: u64| {})
            .expect("simulates")
            .summary();
        assert_eq!(t.trigger_rate.value, 1.0);
        assert_eq!(t.trigger_rate_expected.value, 1.0);
        assert!((t.energy_mean.value - t.steps_mean.value).abs() < 2.0);
    }
}
