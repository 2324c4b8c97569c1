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
use crate::rng::{SimRng, stream_rng, streams, trigger_rng};
use crate::trigger::{TriggerFamily, send_on_delta_noise_scale};
use rand::{Rng, RngExt};

/// The serving sensor's side of step 4 (docs/MODEL.md §2, §8): what it
/// measured, the innovation it triggered on, and what its link did.
#[derive(Debug, Clone, Copy)]
pub struct ServedSlot<const N: usize, const M: usize> {
    /// `y = H x + v`.
    pub y: Vector<M>,
    /// The prior's innovation (its whitening also serves the update).
    pub innovation: Innovation<N, M>,
    /// The family's decision sent (box: ‖ε‖∞ > δ).
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
/// leg loop writes the same lines inline, for its speed: see there): measure
/// `y = H x + v` (noise from `rng`), decide on the prior's innovation with
/// `decides` (the family's decision, [`CompiledScenario::decides`]), and on
/// a send make the link's attempts (`link` is called only then; an ideal
/// link delivers the first). The agent's update of what was delivered is
/// [`super::slot_update`] (or, at the sensor, its replica's close).
#[inline(always)]
pub fn serve_slot<const N: usize, const M: usize, R: Rng + ?Sized>(
    filter: &EtKalmanFilter<N, M>,
    prior: &Belief<N>,
    x: &Vector<N>,
    rng: &mut R,
    decides: impl FnOnce(&Innovation<N, M>, &Vector<M>) -> bool,
    link: impl FnOnce() -> Transmission,
) -> ServedSlot<N, M> {
    let y = filter.sensor.measure(x, rng);
    let innovation = filter.innovation(prior);
    let fired = decides(&innovation, &y);
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

/// Where a run's sensor process takes the random numbers of a slot: keyed
/// by (seed, episode, step), so that they do not depend on timing and
/// `etp replay verify` draws them again from what the recording holds (the
/// run's seed, the true state of the step).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlotKey {
    /// The run's seed.
    pub seed: u64,
    pub episode: u64,
    /// The episode's step (from 1).
    pub step: u32,
    /// The serving sensor's index.
    pub sensor: u32,
}

impl SlotKey {
    fn index(&self) -> u64 {
        (self.episode << 32) | u64::from(self.step)
    }

    /// The measurement noise's generator (stream `SENSOR`).
    pub fn noise_rng(&self) -> SimRng {
        stream_rng(self.seed, streams::SENSOR, self.index())
    }

    /// The stochastic family's uniform draw (docs/MODEL.md §9): a stream of
    /// its own ([`crate::rng::trigger_rng`] under stream `SENSOR`), so that
    /// the noise and the radio of every family keep their bits.
    pub fn trigger_uniform(&self) -> f64 {
        trigger_rng(
            self.seed,
            streams::SENSOR,
            self.index(),
            u64::from(self.sensor),
        )
        .random::<f64>()
    }
}

/// A slot of a run as its serving sensor sees it: the agent's prior, the
/// true state, the leg's threshold, the slot's number in the leg (from 0),
/// for send-on-delta the leg's last delivered measurement
/// ([`super::AgentCore::reference`]), and the keys of its draws.
#[derive(Debug, Clone, Copy)]
pub struct RunSlot<'a, const N: usize> {
    pub prior: &'a Belief<N>,
    pub x: &'a Vector<N>,
    pub delta: f64,
    pub slot_in_leg: u32,
    pub reference: Option<&'a [f64]>,
    pub key: SlotKey,
}

impl<const N: usize> CompiledScenario<N> {
    /// A run's slot at the serving sensor: [`serve_slot`] with the noise and
    /// the trigger draw of `slot.key`, deciding with the scenario's family.
    /// The sensor process and `etp replay verify` ([`Self::redecide_slot`])
    /// both serve it here.
    #[inline]
    pub fn serve_run_slot<const M: usize>(
        &self,
        filter: &EtKalmanFilter<N, M>,
        slot: RunSlot<'_, N>,
        link: impl FnOnce() -> Transmission,
    ) -> ServedSlot<N, M> {
        let mut rng = slot.key.noise_rng();
        let reference = slot.reference.map(|r| Vector::<M>::from_fn(|i, _| r[i]));
        serve_slot(
            filter,
            slot.prior,
            slot.x,
            &mut rng,
            |inn, y| {
                self.decides(
                    filter,
                    inn,
                    y,
                    slot.delta,
                    slot.slot_in_leg,
                    reference.as_ref(),
                    || Some(slot.key.trigger_uniform()),
                )
            },
            link,
        )
    }

    /// The decision a run's sensor made in `slot` of leg `leg`, again from
    /// the recorded true state: whether it sent, and the measurement `y`
    /// (its first m entries; the rest 0).
    pub fn redecide_slot(&self, leg: usize, slot: RunSlot<'_, N>) -> (bool, [f64; 6]) {
        let delivered = || Transmission {
            attempts: 1,
            delivered: true,
        };
        let mut y = [0.0; 6];
        let sensor = self.legs[leg].sensor;
        let fired = on_filter!(&self.filters[sensor], f => {
            let served = self.serve_run_slot(f, slot, delivered);
            for (o, v) in y.iter_mut().zip(served.y.iter()) {
                *o = *v;
            }
            served.fired
        });
        (fired, y)
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

    /// Step 4's silence of the send-on-delta family (docs/MODEL.md §9): on
    /// an ideal link, the leg's last delivered measurement `reference` as a
    /// pseudo-measurement with noise `(1 + δ²/3) R`, as the leg loop updates;
    /// on a lossy one the silence update with `beta` (the family's lossy
    /// factor, 0: silence is no information).
    pub fn close_silent_on_delta(
        &self,
        leg: usize,
        prior: &Belief<N>,
        reference: &[f64],
        delta: f64,
        beta: f64,
    ) -> Belief<N> {
        let sensor = self.legs[leg].sensor;
        if !self.radio.link(sensor).is_ideal() {
            return self.close_slot(leg, prior, SlotOutcome::Silent, beta);
        }
        on_filter!(&self.filters[sensor], f => {
            let inn = f.innovation(prior);
            f.update_pseudo_measurement(
                prior,
                &inn,
                &Vector::from_fn(|i, _| reference[i]),
                send_on_delta_noise_scale(delta),
            )
        })
    }

    /// The factor β of the silence update (`Silent` in [`Self::close_slot`])
    /// at sensor `sensor` with threshold δ: β(δ) on an ideal link (§2), the
    /// radio's on a lossy one (§8: β_q(δ) for the aware estimator, β(δ) for
    /// the naive one); for a family other than box, the family's own
    /// (docs/MODEL.md §9). The agent process, the sensor's replica and
    /// `replay verify` all take it from here, as the in-process leg loop
    /// does (same operations, same bits).
    pub fn silence_beta(&self, sensor: usize, delta: f64) -> f64 {
        if self.trigger != TriggerFamily::Box {
            // The family's own factor (docs/MODEL.md §9), as the leg loop
            // takes it.
            return self.silence_factor(sensor, delta, self.filters[sensor].dim());
        }
        if self.radio.link(sensor).is_ideal() {
            Threshold::new(delta).beta
        } else {
            let m = self.filters[sensor].dim();
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
