//! A simulation's episodes one record each, and their legs: the episodes of
//! [`crate::simulate::simulate`] (the same streams `stream_rng(seed, stream,
//! e)` and channels, the same tally), kept row by row instead of summed —
//! the per-episode and per-leg tables of the Python package's
//! `etpareto.simulate`.

use crate::exec::{ExecError, Work};
use crate::simulate::{SensorCounts, SensorTally};
use etp_shared::episode::{
    CompiledScenario, EpisodeObserver, LegEnd, LegMode, LegResult, Outcome, StepEvent,
};
use etp_shared::etkf::Belief;
use etp_shared::rng::{SimRng, stream_rng};
use serde::{Deserialize, Serialize};

/// One episode's totals.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    /// The episode's index (its random stream).
    pub episode: u64,
    pub outcome: Outcome,
    /// Plant moves (the colliding move included).
    pub steps: u32,
    /// Measurement slots.
    pub slots: u32,
    /// Transmission attempts (each costs its sensor's c_m).
    pub transmissions: u32,
    pub triggers: u32,
    pub delivered: u32,
    /// Σ c_m × attempts over the legs.
    pub energy: f64,
    /// Σ γ̄(δ, m) over the slots.
    pub expected_transmissions: f64,
    /// Σ NEES/n of the agent's estimate over the slots.
    pub nees_sum: f64,
    /// Σ ‖x − x̂‖² over the slots.
    pub squared_error_sum: f64,
}

/// One leg of one episode (legs after a collision are not run).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LegRecord {
    pub episode: u64,
    pub leg: u32,
    /// The serving sensor's index.
    pub sensor: u32,
    /// The obstacle hit in this leg, if any.
    pub collision: Option<u32>,
    pub steps: u32,
    pub slots: u32,
    pub transmissions: u32,
    pub triggers: u32,
    pub delivered: u32,
    /// Slots in the enforced δ = 0 phase (`LegMode::KfConvergence`).
    pub kf_slots: u32,
    pub expected_transmissions: f64,
}

/// The records of a simulation, episodes and legs in episode order.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Records {
    pub episodes: Vec<EpisodeRecord>,
    pub legs: Vec<LegRecord>,
}

/// The summary's tally, plus each leg's record.
struct Recorder<'a> {
    tally: SensorTally<'a>,
    episode: u64,
    legs: &'a mut Vec<LegRecord>,
}

impl<const N: usize> EpisodeObserver<N> for Recorder<'_> {
    #[inline]
    fn on_step(&mut self, e: &StepEvent<'_, N>) {
        self.tally.on_step(e);
    }

    #[inline]
    fn on_leg_end(&mut self, leg: usize, sensor: usize, r: &LegResult) {
        <SensorTally<'_> as EpisodeObserver<N>>::on_leg_end(&mut self.tally, leg, sensor, r);
        self.legs.push(LegRecord {
            episode: self.episode,
            leg: leg as u32,
            sensor: sensor as u32,
            collision: match r.end {
                LegEnd::Collision { obstacle } => Some(obstacle as u32),
                LegEnd::Terminated => None,
            },
            steps: r.steps,
            slots: r.slots,
            transmissions: r.transmissions,
            triggers: r.triggers,
            delivered: r.delivered,
            kf_slots: r.kf_slots,
            expected_transmissions: r.expected_transmissions,
        });
    }
}

/// The records of episodes `range` (one thread).
pub fn records_range<const N: usize, P>(
    scenario: &CompiledScenario<N>,
    policy: &P,
    range: std::ops::Range<u64>,
    seed: u64,
    stream: u64,
) -> Records
where
    P: Fn(usize, &Belief<N>, &mut SimRng) -> LegMode<N>,
{
    let mut out = Records::default();
    let mut sensors = vec![SensorCounts::default(); scenario.filters.len()];
    for e in range {
        let mut rng = stream_rng(seed, stream, e);
        let mut channels = scenario.channels(seed, stream, e);
        let mut rec = Recorder {
            tally: SensorTally {
                sensors: &mut sensors,
                nees: 0.0,
                squared_error: 0.0,
            },
            episode: e,
            legs: &mut out.legs,
        };
        let r = scenario.run_episode(policy, &mut rng, &mut channels, &mut rec);
        out.episodes.push(EpisodeRecord {
            episode: e,
            outcome: r.outcome,
            steps: r.steps,
            slots: r.slots,
            transmissions: r.transmissions,
            triggers: r.triggers,
            delivered: r.delivered,
            energy: r.energy,
            expected_transmissions: r.expected_transmissions,
            nees_sum: rec.tally.nees,
            squared_error_sum: rec.tally.squared_error,
        });
    }
    out
}

/// The records of `episodes` episodes under `policy` on stream `stream` of
/// `seed`: the episodes [`crate::simulate::simulate`] sums, in the same
/// chunks on the progress's executor.
pub fn records<const N: usize, P>(
    scenario: &CompiledScenario<N>,
    policy: &P,
    episodes: u64,
    seed: u64,
    stream: u64,
    progress: &dyn Work,
) -> Result<Records, ExecError>
where
    P: Fn(usize, &Belief<N>, &mut SimRng) -> LegMode<N> + Sync,
{
    let parts: Vec<Records> = crate::simulate::map_episode_chunks(progress, episodes, |r| {
        records_range(scenario, policy, r, seed, stream)
    })?;
    let mut out = Records::default();
    for mut p in parts {
        out.episodes.append(&mut p.episodes);
        out.legs.append(&mut p.legs);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::simulate;
    use etp_shared::etkf::Threshold;
    use etp_shared::rng::streams;
    use etp_shared::scenario::Scenario;

    /// The records are the summed episodes: every total of the summary
    /// from them, exactly (same streams, same tally), on a lossy radio so
    /// that attempts, deliveries and losses differ.
    #[test]
    fn records_sum_to_the_simulation_totals() {
        let s = Scenario::builtin("winding-2d")
            .expect("built-in")
            .with_radio_override(&etp_shared::radio::RadioOverride {
                loss: Some(0.2),
                retries: Some(1),
                ..Default::default()
            })
            .expect("a lossy channel");
        let c = CompiledScenario::<2>::new(&s);
        let t = Threshold::new(1.0);
        let policy = move |_: usize, _: &_, _: &mut _| LegMode::<2>::EventTriggered(t);
        let tot = simulate(&c, &policy, 150, 7, streams::SIMULATE, &|_: u64| {}).expect("sim");
        let rec = records(&c, &policy, 150, 7, streams::SIMULATE, &|_: u64| {}).expect("rec");
        assert_eq!(rec.episodes.len(), 150);
        let count = |o: Outcome| rec.episodes.iter().filter(|e| e.outcome == o).count() as u64;
        assert_eq!(
            (
                count(Outcome::Target),
                count(Outcome::Collision),
                count(Outcome::Free)
            ),
            (tot.target, tot.collision, tot.free)
        );
        let steps: u64 = rec.episodes.iter().map(|e| u64::from(e.steps)).sum();
        assert_eq!(steps as f64, tot.steps.sum);
        let energy: f64 = rec.episodes.iter().map(|e| e.energy).sum();
        assert!((energy - tot.energy.sum).abs() <= 1e-9 * tot.energy.sum);
        let nees: f64 = rec.episodes.iter().map(|e| e.nees_sum).sum();
        assert!((nees - tot.nees.sum_a).abs() <= 1e-9 * tot.nees.sum_a);
        for (i, want) in tot.sensors.iter().enumerate() {
            let mut got = SensorCounts::default();
            for l in rec.legs.iter().filter(|l| l.sensor as usize == i) {
                got.slots += u64::from(l.slots);
                got.transmissions += u64::from(l.transmissions);
                got.triggers += u64::from(l.triggers);
                got.delivered += u64::from(l.delivered);
                got.expected_triggers += l.expected_transmissions;
            }
            assert_eq!(
                (got.slots, got.transmissions, got.triggers, got.delivered),
                (
                    want.slots,
                    want.transmissions,
                    want.triggers,
                    want.delivered
                ),
                "sensor {i}"
            );
        }
        // Each episode's legs add up to it.
        for e in &rec.episodes {
            let legs: u32 = rec
                .legs
                .iter()
                .filter(|l| l.episode == e.episode)
                .map(|l| l.transmissions)
                .sum();
            assert_eq!(legs, e.transmissions, "episode {}", e.episode);
        }
        assert!(
            tot.sensors.iter().any(|c| c.lost() > 0),
            "a lossy radio loses"
        );
    }
}
