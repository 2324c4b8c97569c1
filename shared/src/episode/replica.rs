//! The agent's estimator as the serving sensor replays it (docs/MODEL.md
//! §3.2): handed the agent's belief once at the start of a leg, the sensor
//! computes every prior of the leg itself, with the agent's own step
//! ([`AgentCore`], without a world: the sensor serves only slots whose move
//! did not collide), from what it knows: its own transmissions and silent
//! slots. No per-step downlink is needed, and the replica's priors are the
//! agent's bit for bit (checked by the agent on every slot through
//! [`belief_digest`], and by `etp replay verify`).
//!
//! The replica is exact only while every slot of the leg reached the agent as
//! the sensor closed it; a slot the agent took as dead (a dead link) breaks
//! it, and the next handover (next leg) restores it.

use super::{AgentCore, Begun, CompiledScenario, OpenSlot, SlotOutcome, Unseen};
use crate::etkf::Belief;

/// The agent's estimate within one leg, as the serving sensor tracks it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegReplica<const N: usize> {
    core: AgentCore<N>,
}

impl<const N: usize> LegReplica<N> {
    /// The replica handed over at step `step` (slots so far in the episode)
    /// of leg `leg` at threshold `delta` with belief `belief` (β from the
    /// serving link, as the agent takes it).
    pub fn handed_over(
        c: &CompiledScenario<N>,
        leg: usize,
        delta: f64,
        belief: Belief<N>,
        step: u32,
    ) -> Self {
        Self {
            core: AgentCore::for_delta(c, leg, delta, belief, step),
        }
    }

    /// The step k the next slot will have.
    pub fn next_step(&self) -> u32 {
        self.core.step() + 1
    }

    /// The agent's posterior after the last closed slot (at the handover:
    /// its belief at the decision point).
    pub fn posterior(&self) -> &Belief<N> {
        self.core.posterior()
    }

    /// The leg's last delivered measurement, for the send-on-delta family
    /// ([`AgentCore::reference`]).
    pub fn reference(&self) -> Option<[f64; 6]> {
        self.core.reference()
    }

    /// Open the next slot: its prior is the agent's (`u = input(leg, x̂)`,
    /// then the prediction), exactly as the agent computes it.
    pub fn open(&mut self, c: &CompiledScenario<N>) -> OpenSlot<N> {
        let Begun::Slot(slot) = self.core.begin(c, &mut Unseen);
        slot
    }

    /// Close the slot: the agent's update of its prior with what the sensor
    /// did (transmitted y, or stayed silent).
    pub fn close(&mut self, c: &CompiledScenario<N>, slot: OpenSlot<N>, outcome: SlotOutcome<'_>) {
        // The leg's end is the agent's to tell (the coordinator closes it).
        let _leg_ended = self.core.close(c, slot, outcome);
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
    use crate::rng::{stream_rng, streams};
    use crate::scenario::Scenario;

    /// The replica, fed only the slots' outcomes, reproduces the agent's
    /// priors of a whole simulated leg bit for bit, on a single integrator
    /// and on a double integrator (n = 4, LQR gain).
    fn replica_matches_the_agent<const N: usize>(name: &str) {
        let s = Scenario::builtin(name).expect("built-in");
        let c = CompiledScenario::<N>::new(&s);
        let mut rng = stream_rng(5, streams::AGENT, 0);
        let mut state = c.initial_state(&mut rng);
        let delta = 1.2;
        let beta = Threshold::new(delta).beta;
        let leg = 0;
        let mut replica = LegReplica::handed_over(&c, leg, delta, state.belief, 0);
        let mut checked = 0;
        for k in 1..=c.k_max {
            let u = c.input(leg, &state.belief.mean);
            if c.move_plant(&mut state.x, &u, &mut rng).is_some() {
                break;
            }
            let prior = c.prior(&state.belief, &u);
            assert_eq!(replica.next_step(), k);
            let mine = replica.open(&c);
            assert_eq!(
                belief_digest(mine.prior()),
                belief_digest(&prior),
                "step {k}"
            );
            assert_eq!(mine.prior(), &prior);
            checked += 1;
            // Alternate transmissions and silences.
            let y = [state.x[0], state.x[1], 0.0, 0.0, 0.0, 0.0];
            let slot = if k % 3 == 0 {
                SlotOutcome::Transmitted(&y[..])
            } else {
                SlotOutcome::Silent
            };
            state.belief = c.close_slot(leg, &prior, slot, beta);
            replica.close(&c, mine, slot);
            assert_eq!(replica.next_step(), k + 1);
            if c.leg_ends(leg, &state.belief, k) {
                break;
            }
        }
        assert!(checked >= 5, "{checked}");
        assert_eq!(replica.posterior(), &state.belief);
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
