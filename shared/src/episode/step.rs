//! THE step of docs/MODEL.md §3 (general form §7), written once: [`AgentCore`],
//! the agent's estimator and leg rule from a decision point on, as a pure
//! state machine driven step by step.
//!
//! ```text
//! u      = input(leg, posterior mean)                   1
//! k += 1; driver.advance(k, u) → collision? (ends)      2–3  the world moves
//! prior  = F x̂ + G u, F P Fᵀ + Q;  innovation of prior
//! outcome = driver.slot(OpenSlot)                       4    the sensor's side
//! posterior = update(prior, outcome)                         Delivered(y) | Silent (β) | Dead
//! leg end?  (ε_x or k_max; Method 1's δ = 0 phase)      5
//! ```
//!
//! Four drivers run it, each supplying only what differs ([`StepDriver`]):
//! the in-process simulation (`CompiledScenario::run_leg`: the true plant and
//! an in-process sensor, including the AVX2 build of the leg loop), the agent
//! process (the true plant, the slot served by a sensor process), `etp replay
//! --verify` (no true state: collisions and slots come from the recording)
//! and the serving sensor's replica ([`super::LegReplica`]: the plant moved
//! without collision, the sensor decides the slot itself). So the bit-for-bit
//! guarantees (replica digests, `--verify`) rest on this one piece of code.
//!
//! Extending the step (the lossy radio of MODEL §8) is a change here: the
//! slot's outcome is [`SlotOutcome`] (what reached the agent), the silence
//! update's factor comes from one place ([`CompiledScenario::silence_beta`]),
//! and the sensor's side of a slot is the driver's.

use super::{CompiledScenario, LegEnd, LegMode, LegResult};
use crate::etkf::{Belief, EtKalmanFilter, Innovation, SensorModel, Threshold, Vector};
use crate::gaussian;

/// What the serving sensor's slot brought the agent (`Y`: the measurement,
/// `()` for just the kind, see [`SlotKind`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlotOutcome<Y> {
    /// A measurement reached the agent: the explicit update.
    Delivered(Y),
    /// The slot closed without a measurement from a live sensor: silence is
    /// information, the implicit update with the leg's silence factor
    /// ([`CompiledScenario::silence_beta`]).
    Silent,
    /// A dead link: no information at all, prediction only (never "silence
    /// means a small innovation").
    Dead,
}

/// The kind of a slot's outcome, without its measurement.
pub type SlotKind = SlotOutcome<()>;

impl<Y> SlotOutcome<Y> {
    /// The outcome without its payload.
    #[inline(always)]
    pub fn kind(&self) -> SlotKind {
        match self {
            Self::Delivered(_) => SlotOutcome::Delivered(()),
            Self::Silent => SlotOutcome::Silent,
            Self::Dead => SlotOutcome::Dead,
        }
    }
}

/// The slot the serving sensor is asked to close, with everything its side
/// decides from: the agent's prior (the sensor triggers on it, §3.2), its
/// innovation statistics, the sensor's model and the leg's threshold.
#[derive(Debug, Clone, Copy)]
pub struct OpenSlot<'a, const N: usize, const M: usize> {
    pub leg: usize,
    /// The step k of the episode this slot belongs to.
    pub step: u32,
    pub prior: &'a Belief<N>,
    pub innovation: &'a Innovation<N, M>,
    pub sensor: &'a SensorModel<N, M>,
    pub delta: f64,
}

impl<const N: usize, const M: usize> OpenSlot<'_, N, M> {
    /// The trigger of docs/MODEL.md §2 on measurement `y`: transmit iff ‖ε‖∞ > δ.
    #[inline(always)]
    pub fn triggers(&self, y: &Vector<M>) -> bool {
        self.innovation.triggers(y, self.delta)
    }
}

/// What a driver supplies to [`AgentCore::step`]: the world's move and the
/// sensor's side of the slot. `Stop` ends the leg early (an I/O error, a
/// stop request, a recording that differs); drivers that cannot stop use
/// [`std::convert::Infallible`].
pub trait StepDriver<const N: usize, const M: usize> {
    type Stop;
    /// Steps 2–3 for step `step` with input `u`: move the world;
    /// `Some(obstacle)` if it collided (the episode ends, no slot).
    fn advance(&mut self, step: u32, u: &Vector<N>) -> Result<Option<usize>, Self::Stop>;
    /// Step 4, the sensor's side: what reached the agent.
    fn slot(&mut self, slot: &OpenSlot<'_, N, M>) -> Result<SlotOutcome<Vector<M>>, Self::Stop>;
}

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// The world collided with `obstacle` (no slot): the episode ends.
    Collided { obstacle: usize },
    /// The slot closed with `slot`, under threshold `delta`; `leg_ends`: the
    /// leg's end rule fired after this step.
    Closed {
        slot: SlotKind,
        delta: f64,
        leg_ends: bool,
    },
}

/// The agent's estimator over one leg: the posterior, the step count of the
/// episode, the leg's threshold rule and its counts.
#[derive(Debug, Clone, Copy)]
pub struct AgentCore<const N: usize> {
    /// The posterior after the last closed slot (at the start: the belief at
    /// the decision point).
    pub belief: Belief<N>,
    /// Steps of the episode so far (the step k of the last step).
    pub step: u32,
    leg: usize,
    sensor: usize,
    mode: LegMode<N>,
    threshold: Threshold,
    /// The implicit update's factor under `threshold` (one place: [`CompiledScenario::silence_beta`]).
    silence_beta: f64,
    /// Method 1: the enforced δ = 0 phase has begun.
    in_kf_phase: bool,
    /// γ̄(δ, m) of the current threshold.
    expected_rate: f64,
    counts: LegResult,
}

impl<const N: usize> CompiledScenario<N> {
    /// The factor β of the implicit (silence) update under threshold `th` at
    /// `sensor`: the one place it comes from (today β(δ) of docs/MODEL.md §2).
    #[inline(always)]
    pub fn silence_beta(&self, _sensor: usize, th: Threshold) -> f64 {
        th.beta
    }
}

impl<const N: usize> AgentCore<N> {
    /// Leg `leg` starts at step `step` of the episode from `belief`, under `mode`.
    #[inline(always)]
    pub fn at_leg(
        c: &CompiledScenario<N>,
        leg: usize,
        mode: LegMode<N>,
        belief: Belief<N>,
        step: u32,
    ) -> Self {
        let sensor = c.legs[leg].sensor;
        let threshold = match mode {
            LegMode::EventTriggered(t) | LegMode::KfConvergence { threshold: t, .. } => t,
        };
        Self {
            belief,
            step,
            leg,
            sensor,
            mode,
            threshold,
            silence_beta: c.silence_beta(sensor, threshold),
            in_kf_phase: false,
            expected_rate: gaussian::expected_rate(threshold.delta, c.filters[sensor].dim()),
            counts: LegResult {
                end: LegEnd::Terminated,
                steps: 0,
                slots: 0,
                transmissions: 0,
                kf_slots: 0,
                expected_transmissions: 0.0,
            },
        }
    }

    /// Leg `leg` under threshold δ = `delta` for the whole leg (the runtime's
    /// legs: agent, replica, `replay --verify`).
    pub fn event_triggered(
        c: &CompiledScenario<N>,
        leg: usize,
        delta: f64,
        belief: Belief<N>,
        step: u32,
    ) -> Self {
        Self::at_leg(
            c,
            leg,
            LegMode::EventTriggered(Threshold::new(delta)),
            belief,
            step,
        )
    }

    /// The leg (decision point) index.
    pub fn leg(&self) -> usize {
        self.leg
    }

    /// The serving sensor.
    pub fn sensor(&self) -> usize {
        self.sensor
    }

    /// The threshold δ of the next slot.
    #[inline(always)]
    pub fn delta(&self) -> f64 {
        self.threshold.delta
    }

    /// The leg's counts so far (`end` is `Collision` after a collision).
    #[inline(always)]
    pub fn counts(&self) -> LegResult {
        self.counts
    }

    /// One step (docs/MODEL.md §3/§7) with the serving sensor's filter
    /// `filter` (the leg's sensor, [`Self::sensor`]); the driver moves the
    /// world and serves the slot.
    #[inline(always)]
    pub fn step<const M: usize, D: StepDriver<N, M>>(
        &mut self,
        c: &CompiledScenario<N>,
        filter: &EtKalmanFilter<N, M>,
        driver: &mut D,
    ) -> Result<Step, D::Stop> {
        let leg = self.leg;
        let u = c.input(leg, &self.belief.mean);
        self.step += 1;
        self.counts.steps += 1;
        if let Some(obstacle) = driver.advance(self.step, &u)? {
            self.counts.end = LegEnd::Collision { obstacle };
            return Ok(Step::Collided { obstacle });
        }
        let prior = c.prior(&self.belief, &u);
        let inn = filter.innovation(&prior);
        let delta = self.threshold.delta;
        let outcome = driver.slot(&OpenSlot {
            leg,
            step: self.step,
            prior: &prior,
            innovation: &inn,
            sensor: &filter.sensor,
            delta,
        })?;
        self.belief = match &outcome {
            SlotOutcome::Delivered(y) => filter.update_explicit(&prior, &inn, y),
            SlotOutcome::Silent => filter.update_implicit(&prior, &inn, self.silence_beta),
            SlotOutcome::Dead => prior,
        };
        let slot = outcome.kind();
        let r = &mut self.counts;
        r.slots += 1;
        r.transmissions += u32::from(slot == SlotOutcome::Delivered(()));
        r.kf_slots += u32::from(self.in_kf_phase);
        r.expected_transmissions += self.expected_rate;
        let leg_ends = self.leg_ends(c);
        Ok(Step::Closed {
            slot,
            delta,
            leg_ends,
        })
    }

    /// Step 5 after a closed slot: the leg ends when `‖C x̂ − w_i‖ ≤ ε_x` or
    /// after `k_max` steps; under Method 1 the δ = 0 phase begins within
    /// `eps_kf` and the leg ends only once P has converged (docs/MODEL.md §4).
    #[inline(always)]
    fn leg_ends(&mut self, c: &CompiledScenario<N>) -> bool {
        let (leg, steps) = (self.leg, self.counts.steps);
        match &self.mode {
            LegMode::EventTriggered(_) => c.leg_ends(leg, &self.belief, steps),
            LegMode::KfConvergence {
                eps_kf,
                eps_p,
                p_kf,
                ..
            } => {
                let near = c.near_waypoint(leg, &self.belief.mean, c.eps_x);
                if !self.in_kf_phase && c.near_waypoint(leg, &self.belief.mean, *eps_kf) {
                    self.in_kf_phase = true;
                    self.threshold = Threshold::new(0.0);
                    self.silence_beta = c.silence_beta(self.sensor, self.threshold);
                    self.expected_rate = 1.0;
                }
                (self.in_kf_phase && near && (self.belief.cov - p_kf).amax() <= *eps_p)
                    || steps >= c.k_max
            }
        }
    }
}

impl<const N: usize> CompiledScenario<N> {
    /// Steps 2–3 on the true state: move it; `Some(obstacle)` if it collided.
    #[inline(always)]
    pub fn move_plant<R: rand::Rng + ?Sized>(
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

    /// The leg-end rule: `‖C x̂ − w_i‖ ≤ ε_x` or `k_max` steps in the leg.
    #[inline(always)]
    pub fn leg_ends(&self, leg: usize, posterior: &Belief<N>, steps_in_leg: u32) -> bool {
        self.near_waypoint(leg, &posterior.mean, self.eps_x) || steps_in_leg >= self.k_max
    }

    /// After the last leg: target if the true state is in the target box.
    #[inline(always)]
    pub fn classify_end(&self, x: &Vector<N>) -> super::Outcome {
        if self.in_target(x) {
            super::Outcome::Target
        } else {
            super::Outcome::Free
        }
    }
}
