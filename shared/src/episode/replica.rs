//! The agent's estimator as the serving sensor replays it (docs/MODEL.md
//! §3.2): handed the agent's belief once at the start of a leg, the sensor
//! runs the agent's own step ([`AgentCore::step`]) on every slot it serves:
//! the plant moved without collision (the agent sent the truth), and the
//! slot's outcome is what the sensor itself decided (transmitted y, or
//! stayed silent). No per-step downlink is needed, and the replica's priors
//! are the agent's bit for bit (checked by the agent on every slot through
//! [`belief_digest`], and by `etp replay --verify`).
//!
//! The replica is exact only while every slot of the leg reached the agent as
//! the sensor closed it; a slot the agent took as dead (a dead link) breaks
//! it, and the next handover (next leg) restores it.

use super::{AgentCore, CompiledScenario, OpenSlot, SlotOutcome, StepDriver};
use crate::etkf::{Belief, EtKalmanFilter, Vector};

/// The agent's estimate within one leg, as the serving sensor tracks it.
#[derive(Debug, Clone, Copy)]
pub struct LegReplica<const N: usize> {
    core: AgentCore<N>,
}

/// One slot as the replica served it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Served<const M: usize> {
    /// What the sensor decided (and the replica applied).
    pub outcome: SlotOutcome<Vector<M>>,
    /// [`belief_digest`] of the prior the sensor decided on.
    pub prior_digest: u64,
}

impl<const N: usize> LegReplica<N> {
    /// The replica handed over at step `step` (steps so far in the episode)
    /// of leg `leg` under threshold δ = `delta`, with the agent's belief.
    pub fn handed_over(
        c: &CompiledScenario<N>,
        leg: usize,
        delta: f64,
        belief: Belief<N>,
        step: u32,
    ) -> Self {
        Self {
            core: AgentCore::event_triggered(c, leg, delta, belief, step),
        }
    }

    /// The step k the next slot will have.
    pub fn next_step(&self) -> u32 {
        self.core.step + 1
    }

    /// The agent's posterior after the last closed slot.
    pub fn posterior(&self) -> &Belief<N> {
        &self.core.belief
    }

    /// Serve the next slot with the agent's step: `decide` is the sensor's
    /// side (measure, trigger) on the prior the agent has; the replica then
    /// applies what the agent will apply.
    pub fn serve<const M: usize>(
        &mut self,
        c: &CompiledScenario<N>,
        filter: &EtKalmanFilter<N, M>,
        decide: impl FnOnce(&OpenSlot<'_, N, M>) -> SlotOutcome<Vector<M>>,
    ) -> Served<M> {
        let mut driver = Replay {
            decide: Some(decide),
            served: None,
        };
        let step = self.core.step(c, filter, &mut driver);
        match (step, driver.served) {
            (Ok(_), Some(served)) => served,
            // `advance` never collides and `slot` never stops.
            _ => unreachable!("the replica's driver neither collides nor stops"),
        }
    }
}

/// The replica's driver: the world moved without collision; the slot is the
/// sensor's decision.
struct Replay<F, const M: usize> {
    decide: Option<F>,
    served: Option<Served<M>>,
}

impl<const N: usize, const M: usize, F> StepDriver<N, M> for Replay<F, M>
where
    F: FnOnce(&OpenSlot<'_, N, M>) -> SlotOutcome<Vector<M>>,
{
    type Stop = std::convert::Infallible;

    fn advance(&mut self, _step: u32, _u: &Vector<N>) -> Result<Option<usize>, Self::Stop> {
        Ok(None)
    }

    fn slot(&mut self, slot: &OpenSlot<'_, N, M>) -> Result<SlotOutcome<Vector<M>>, Self::Stop> {
        let outcome = match self.decide.take() {
            Some(decide) => decide(slot),
            None => SlotOutcome::Dead,
        };
        self.served = Some(Served {
            outcome,
            prior_digest: belief_digest(slot.prior),
        });
        Ok(outcome)
    }
}

/// A 64-bit fingerprint of a belief's exact bits (FNV-1a over the IEEE bits
/// of the mean, then the covariance row by row): equal beliefs give equal
/// digests; a differing bit changes it (up to 2⁻⁶⁴ collisions).
pub fn belief_digest<const N: usize>(b: &Belief<N>) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut h = OFFSET;
    let mut eat = |x: f64| {
        for byte in x.to_bits().to_le_bytes() {
            h ^= u64::from(byte);
            h = h.wrapping_mul(PRIME);
        }
    };
    for r in 0..N {
        eat(b.mean[r]);
    }
    for r in 0..N {
        for col in 0..N {
            eat(b.cov[(r, col)]);
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::etkf::Threshold;
    use crate::etkf::Vector;
    use crate::rng::{stream_rng, streams};
    use crate::scenario::Scenario;

    /// The replica, serving the slots itself, reproduces the priors and
    /// posteriors of an agent computed independently with the filter's own
    /// functions (predict, innovation, explicit/implicit update) bit for bit,
    /// on a single integrator and on a double integrator (n = 4, LQR gain).
    fn replica_matches_the_agent<const N: usize>(name: &str) {
        let s = Scenario::builtin(name).expect("built-in");
        let c = CompiledScenario::<N>::new(&s);
        let filter = EtKalmanFilter::<N, 2>::new(&s.plant, &s.sensors[c.legs[0].sensor]);
        let mut rng = stream_rng(5, streams::AGENT, 0);
        let mut state = c.initial_state(&mut rng);
        let delta = 1.2;
        let beta = Threshold::new(delta).beta;
        let leg = 0;
        let mut replica = LegReplica::handed_over(&c, leg, delta, state.belief, 0);
        let mut checked = 0;
        for k in 1..=c.k_max {
            assert_eq!(replica.next_step(), k);
            let u = c.input(leg, &state.belief.mean);
            if c.move_plant(&mut state.x, &u, &mut rng).is_some() {
                break;
            }
            let prior = filter.predict(&state.belief, &u);
            let inn = filter.innovation(&prior);
            // Alternate transmissions and silences.
            let y = Vector::<2>::new(state.x[0], state.x[1]);
            let sent = k % 3 == 0;
            let served = replica.serve(&c, &filter, |slot| {
                assert_eq!(slot.prior, &prior);
                if sent {
                    SlotOutcome::Delivered(y)
                } else {
                    SlotOutcome::Silent
                }
            });
            assert_eq!(served.prior_digest, belief_digest(&prior), "step {k}");
            checked += 1;
            state.belief = if sent {
                filter.update_explicit(&prior, &inn, &y)
            } else {
                filter.update_implicit(&prior, &inn, beta)
            };
            assert_eq!(replica.posterior(), &state.belief);
            if c.leg_ends(leg, &state.belief, k) {
                break;
            }
        }
        assert!(checked >= 5, "{checked}");
    }

    #[test]
    fn the_replica_reproduces_the_agents_priors_bit_for_bit() {
        replica_matches_the_agent::<2>("winding-2d");
        replica_matches_the_agent::<4>("inertia-2d");
    }

    #[test]
    fn the_digest_sees_one_flipped_bit_anywhere() {
        let s = Scenario::builtin("inertia-2d").expect("built-in");
        let c = CompiledScenario::<4>::new(&s);
        let mut rng = stream_rng(1, streams::AGENT, 0);
        let b = c.initial_state(&mut rng).belief;
        let d = belief_digest(&b);
        for i in 0..4 {
            let mut m = b;
            m.mean[i] = f64::from_bits(m.mean[i].to_bits() ^ 1);
            assert_ne!(belief_digest(&m), d);
            for j in 0..4 {
                let mut p = b;
                p.cov[(i, j)] = f64::from_bits(p.cov[(i, j)].to_bits() ^ (1 << 40));
                assert_ne!(belief_digest(&p), d);
            }
        }
    }
}
