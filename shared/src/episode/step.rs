//! The pieces of one step of docs/MODEL.md §3 (general form §7), split
//! where the runtime splits it: the agent's estimator side (input, prior,
//! slot update, leg end) and the world's side (the plant's move and the
//! collision test).
//!
//! Only [`super::AgentCore`] puts them in order (the one definition of the
//! step, driven by the in-process leg loop, the agent process,
//! `etp replay verify` and the sensor's replica), so the bit-for-bit
//! guarantee of `--verify` rests on one piece of code:
//!
//! ```text
//! u      = input(leg, posterior mean)               step 1 (CompiledScenario::input)
//! x      ← move_plant(x, u)  → collision? (ends)    steps 2–3
//! prior  = prior(posterior, u)
//! post   = close_slot(leg, prior, slot, β)          step 4: Transmitted(y) | Silent | Dead
//! end?   = leg_ends(leg, post, steps in leg)        step 5
//! ```

use super::{CompiledScenario, Outcome, SensorFilter};
use crate::etkf::{Belief, EtKalmanFilter, Innovation, Threshold, Vector};
use crate::radio::Transmission;
use rand::Rng;

/// The serving sensor's side of step 4 (docs/MODEL.md §2, §8): what it
/// measured, the innovation it triggered on, and what its link did.
#[derive(Debug, Clone, Copy)]
pub struct ServedSlot<const N: usize, const M: usize> {
    /// `y = H x + v`.
    pub y: Vector<M>,
    /// The prior's innovation (its whitening also serves the update).
    pub innovation: Innovation<N, M>,
    /// The trigger fired: ‖ε‖∞ > δ.
    pub fired: bool,
    /// The link's attempts (none without a trigger).
    pub sending: Transmission,
}

impl<const N: usize, const M: usize> ServedSlot<N, M> {
    /// The measurement the agent receives, if an attempt was delivered.
    #[inline(always)]
    pub fn delivered(&self) -> Option<&Vector<M>> {
        self.sending.delivered.then_some(&self.y)
    }
}

/// The serving sensor's slot as the sensor process runs it (the in-process
/// leg loop writes the same lines inline, for its speed: see there): measure `y = H x + v` (noise from `rng`), trigger
/// on the prior's innovation, and on a trigger make the link's attempts
/// (`link` is called only then; an ideal link delivers the first). The
/// agent's update of what was delivered is [`super::slot_update`] (or, at
/// the sensor, its replica's close).
#[inline(always)]
pub fn serve_slot<const N: usize, const M: usize, R: Rng + ?Sized>(
    filter: &EtKalmanFilter<N, M>,
    prior: &Belief<N>,
    x: &Vector<N>,
    delta: f64,
    rng: &mut R,
    link: impl FnOnce() -> Transmission,
) -> ServedSlot<N, M> {
    let y = filter.sensor.measure(x, rng);
    let innovation = filter.innovation(prior);
    let fired = innovation.triggers(&y, delta);
    let sending = if fired {
        link()
    } else {
        Transmission {
            attempts: 0,
            delivered: false,
        }
    };
    ServedSlot {
        y,
        innovation,
        fired,
        sending,
    }
}

/// What the serving sensor's slot brought the agent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlotOutcome<'a> {
    /// A transmitted measurement (its first m entries are y): explicit update.
    Transmitted(&'a [f64]),
    /// The slot closed without a transmission from a live sensor: silence is
    /// information, the implicit update with β(δ).
    Silent,
    /// A dead link: no information at all, prediction only (never "silence
    /// means a small innovation").
    Dead,
}

impl<const N: usize> CompiledScenario<N> {
    /// Steps 2–3: move the true state; `Some(obstacle)` if it collided (the
    /// episode ends before any measurement).
    #[inline(always)]
    pub fn move_plant<R: Rng + ?Sized>(
        &self,
        x: &mut Vector<N>,
        u: &Vector<N>,
        rng: &mut R,
    ) -> Option<usize> {
        *x = self.plant.step(x, u, rng);
        self.collision(x)
    }

    /// The slot's prior `x̂⁻ = F x̂ + G u`, `P⁻ = F P Fᵀ + Q`.
    #[inline(always)]
    pub fn prior(&self, posterior: &Belief<N>, u: &Vector<N>) -> Belief<N> {
        self.plant.predict(posterior, u)
    }

    /// Step 4, the estimator's side: the posterior after leg `leg`'s slot.
    #[inline(always)]
    pub fn close_slot(
        &self,
        leg: usize,
        prior: &Belief<N>,
        slot: SlotOutcome<'_>,
        beta: f64,
    ) -> Belief<N> {
        let filter = &self.filters[self.legs[leg].sensor];
        match slot {
            SlotOutcome::Transmitted(y) => filter.posterior(prior, Some(y), beta),
            SlotOutcome::Silent => filter.posterior(prior, None, beta),
            SlotOutcome::Dead => *prior,
        }
    }

    /// The factor β of the silence update (`Silent` in [`Self::close_slot`])
    /// at sensor `sensor` with threshold δ: β(δ) on an ideal link (§2), the
    /// radio's on a lossy one (§8: β_q(δ) for the aware estimator, β(δ) for
    /// the naive one). The agent process, the sensor's replica and
    /// `replay verify` all take it from here, as the in-process leg loop
    /// does (same operations, same bits).
    pub fn silence_beta(&self, sensor: usize, delta: f64) -> f64 {
        if self.radio.link(sensor).is_ideal() {
            Threshold::new(delta).beta
        } else {
            let m = match &self.filters[sensor] {
                SensorFilter::M1(_) => 1,
                SensorFilter::M2(_) => 2,
                SensorFilter::M3(_) => 3,
                SensorFilter::M4(_) => 4,
                SensorFilter::M5(_) => 5,
                SensorFilter::M6(_) => 6,
            };
            self.radio.silence_beta(sensor, delta, m)
        }
    }

    /// Step 5: the leg ends when `‖x̂ − w_i‖ ≤ ε_x` or after `k_max` steps.
    #[inline(always)]
    pub fn leg_ends(&self, leg: usize, posterior: &Belief<N>, steps_in_leg: u32) -> bool {
        self.near_waypoint(leg, &posterior.mean, self.eps_x) || steps_in_leg >= self.k_max
    }

    /// After the last leg: target if the true state is in the target box.
    #[inline(always)]
    pub fn classify_end(&self, x: &Vector<N>) -> Outcome {
        if self.in_target(x) {
            Outcome::Target
        } else {
            Outcome::Free
        }
    }
}
