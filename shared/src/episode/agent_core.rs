//! The one step of docs/MODEL.md §3 (general form §7), written once: the
//! agent's estimator over one leg as a pure state machine, [`AgentCore`].
//!
//! ```text
//! begin:  u = input(leg, x̂)                 step 1
//!         world moves under u → collision?  steps 2–3 (ends the episode, no slot)
//!         prior = predict(posterior, u)     the slot opens on this prior
//! close:  posterior = update(prior, slot)   step 4 (explicit | silence with β | dead: prior)
//!         k_i += 1 … leg end?               step 5 (‖C x̂ − w_i‖ ≤ ε_x or k_i ≥ k_max;
//!                                           method 1: the KF-convergence rule)
//! ```
//!
//! Between [`AgentCore::begin`] and [`AgentCore::close`] the slot is served
//! (measure, trigger, radio), which is what the drivers do differently; the
//! core hands out an [`OpenSlot`] that only `close` consumes, so no driver
//! can reorder or skip a part of the step. The drivers:
//!
//! * the in-process leg loop ([`CompiledScenario::run_leg`], both builds,
//!   AVX2 and baseline): the world is the simulated plant ([`Plant`]); the
//!   slot is served inline with the serving sensor's typed filter, which
//!   computes the innovation once for trigger and update
//!   ([`slot_update`], then [`AgentCore::close_with`]);
//! * the agent process (`agent`): the world is the simulated plant; the
//!   slot is served by a sensor process over IPC;
//! * `etp replay verify`: no true state; the world is the recording (a
//!   collision is where the recorded outcome says), the slot's outcome is
//!   the recorded one;
//! * the sensor's replica ([`super::LegReplica`]): no world at all (a slot
//!   the sensor serves followed a move that did not collide).
//!
//! The pieces the step is made of (`input`, `move_plant`, `prior`,
//! `close_slot`, `leg_ends`) are the functions of [`super::step`]; only this
//! module puts them in order.

use super::{CompiledScenario, SlotOutcome};
use crate::etkf::{Belief, EtKalmanFilter, Innovation, Matrix, Threshold, Vector};
use crate::trigger::TriggerFamily;
use rand::Rng;
use std::convert::Infallible;

/// Where a step's move happens (steps 2–3 of the step).
pub trait World<const N: usize> {
    /// What a collision tells the driver (the obstacle, or nothing).
    type Collision;
    /// The plant moves under input `u` at episode step `step`; `Some` if the
    /// move collided (the episode ends before any measurement).
    fn moved(
        &mut self,
        c: &CompiledScenario<N>,
        u: &Vector<N>,
        step: u32,
    ) -> Option<Self::Collision>;
}

/// The simulated plant: the true state and the random numbers of its
/// process noise (the simulator's and the agent process's world).
pub struct Plant<'a, const N: usize, R: Rng + ?Sized> {
    pub x: &'a mut Vector<N>,
    pub rng: &'a mut R,
}

impl<const N: usize, R: Rng + ?Sized> World<N> for Plant<'_, N, R> {
    /// The obstacle the true state entered.
    type Collision = usize;
    #[inline(always)]
    fn moved(&mut self, c: &CompiledScenario<N>, u: &Vector<N>, _step: u32) -> Option<usize> {
        c.move_plant(self.x, u, self.rng)
    }
}

/// No world: the estimator alone. The sensor's replica runs only steps
/// whose move did not collide (a collision sends no truth to the sensor).
pub struct Unseen;

impl<const N: usize> World<N> for Unseen {
    type Collision = Infallible;
    #[inline(always)]
    fn moved(&mut self, _: &CompiledScenario<N>, _: &Vector<N>, _: u32) -> Option<Infallible> {
        None
    }
}

/// How the leg ends (step 5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LegRule<const N: usize> {
    /// `‖C x̂ − w_i‖ ≤ ε_x` or `k_i ≥ k_max` (MODEL.md §3).
    Waypoint,
    /// Method 1 (MODEL.md §4): once the estimate is within `eps_kf` of the
    /// waypoint the threshold becomes `full_kf` (δ = 0, sticky), and the leg
    /// ends only once `‖P − P_KF‖max ≤ eps_p` and the mean criterion hold
    /// (or at `k_max`).
    KfConvergence {
        eps_kf: f64,
        eps_p: f64,
        p_kf: Matrix<N, N>,
        full_kf: Threshold,
    },
}

/// The agent's estimator within one leg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AgentCore<const N: usize> {
    leg: usize,
    /// δ and the silence update's factor (β(δ), or the radio's β_q).
    threshold: Threshold,
    rule: LegRule<N>,
    in_kf_phase: bool,
    /// After the last closed slot (at the start: the belief at the decision point).
    posterior: Belief<N>,
    /// Steps begun in this leg (k_i).
    steps: u32,
    /// Episode step k of the step last begun.
    step: u32,
    /// The last measurement delivered in this leg (its first m entries):
    /// the send-on-delta family's reference (docs/MODEL.md §9), kept by
    /// [`Self::close`] for that family only (the leg loop keeps its own).
    reference: Option<[f64; 6]>,
}

/// A slot opened by [`AgentCore::begin`]: its prior, to be served and then
/// closed by [`AgentCore::close`] (or [`AgentCore::close_with`]).
#[must_use = "a step ends by closing its slot"]
#[derive(Debug)]
pub struct OpenSlot<const N: usize> {
    prior: Belief<N>,
}

impl<const N: usize> OpenSlot<N> {
    /// The prior `x̂⁻, P⁻` the serving sensor triggers on.
    #[inline(always)]
    pub fn prior(&self) -> &Belief<N> {
        &self.prior
    }
}

/// How [`AgentCore::begin`] went.
#[derive(Debug)]
pub enum Begun<const N: usize, C> {
    /// The move collided: the step (and the episode) ends here.
    Collided(C),
    /// The slot is open.
    Slot(OpenSlot<N>),
}

impl<const N: usize> AgentCore<N> {
    /// Leg `leg` from `posterior` (the belief at its decision point), which
    /// episode step `step` reached, under `threshold` (its β already the
    /// serving link's) and `rule`.
    pub fn open(
        leg: usize,
        threshold: Threshold,
        rule: LegRule<N>,
        posterior: Belief<N>,
        step: u32,
    ) -> Self {
        Self {
            leg,
            threshold,
            rule,
            in_kf_phase: false,
            posterior,
            steps: 0,
            step,
            reference: None,
        }
    }

    /// Leg `leg` at threshold δ = `delta` with the waypoint rule, β from the
    /// serving link ([`CompiledScenario::silence_beta`]): the leg as the
    /// coordinator opens it for the agent process, `replay verify` and the
    /// sensor's replica.
    pub fn for_delta(
        c: &CompiledScenario<N>,
        leg: usize,
        delta: f64,
        posterior: Belief<N>,
        step: u32,
    ) -> Self {
        let beta = c.silence_beta(c.legs[leg].sensor, delta);
        Self::open(
            leg,
            Threshold { delta, beta },
            LegRule::Waypoint,
            posterior,
            step,
        )
    }

    pub fn leg(&self) -> usize {
        self.leg
    }

    /// The threshold now (method 1 switches to δ = 0 within the leg).
    #[inline(always)]
    pub fn threshold(&self) -> Threshold {
        self.threshold
    }

    /// In the enforced δ = 0 phase of [`LegRule::KfConvergence`].
    #[inline(always)]
    pub fn in_kf_phase(&self) -> bool {
        self.in_kf_phase
    }

    /// The posterior after the last closed slot.
    #[inline(always)]
    pub fn posterior(&self) -> &Belief<N> {
        &self.posterior
    }

    /// Steps begun in this leg.
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// Episode step k of the step last begun (at the start: the decision
    /// point's).
    pub fn step(&self) -> u32 {
        self.step
    }

    /// Steps 1–3 and the prior: the input from the posterior, the world's
    /// move (a collision ends the step), the slot's prior.
    #[inline(always)]
    pub fn begin<W: World<N>>(
        &mut self,
        c: &CompiledScenario<N>,
        world: &mut W,
    ) -> Begun<N, W::Collision> {
        let u = c.input(self.leg, &self.posterior.mean);
        self.step += 1;
        self.steps += 1;
        if let Some(collision) = world.moved(c, &u, self.step) {
            return Begun::Collided(collision);
        }
        Begun::Slot(OpenSlot {
            prior: c.prior(&self.posterior, &u),
        })
    }

    /// The last measurement delivered in this leg, for the send-on-delta
    /// family (its decision's and its silence's reference); `None` for the
    /// other families and before the leg's first delivery.
    pub fn reference(&self) -> Option<[f64; 6]> {
        self.reference
    }

    /// Steps 4–5: the posterior from what the slot brought (with the
    /// threshold's β for a silence; for send-on-delta on an ideal link the
    /// pseudo-measurement of the leg's last delivered y,
    /// [`CompiledScenario::close_silent_on_delta`]), then the leg-end rule.
    /// `true` if the leg ended.
    #[inline(always)]
    pub fn close(
        &mut self,
        c: &CompiledScenario<N>,
        slot: OpenSlot<N>,
        outcome: SlotOutcome<'_>,
    ) -> bool {
        let posterior = match (outcome, self.reference.as_ref()) {
            (SlotOutcome::Silent, Some(reference)) if c.trigger == TriggerFamily::SendOnDelta => c
                .close_silent_on_delta(
                    self.leg,
                    &slot.prior,
                    reference,
                    self.threshold.delta,
                    self.threshold.beta,
                ),
            _ => c.close_slot(self.leg, &slot.prior, outcome, self.threshold.beta),
        };
        if let SlotOutcome::Transmitted(y) = outcome
            && c.trigger == TriggerFamily::SendOnDelta
        {
            let mut r = [0.0; 6];
            for (o, v) in r.iter_mut().zip(y) {
                *o = *v;
            }
            self.reference = Some(r);
        }
        self.settle(c, posterior)
    }

    /// Steps 4–5 when the driver updated `slot`'s prior itself with the
    /// serving sensor's filter ([`slot_update`], the in-process leg loop:
    /// its innovation serves the trigger and the update). `true` if the leg
    /// ended.
    #[inline(always)]
    pub fn close_with(
        &mut self,
        c: &CompiledScenario<N>,
        slot: OpenSlot<N>,
        posterior: Belief<N>,
    ) -> bool {
        let OpenSlot { prior: _ } = slot;
        self.settle(c, posterior)
    }

    #[inline(always)]
    fn settle(&mut self, c: &CompiledScenario<N>, posterior: Belief<N>) -> bool {
        self.posterior = posterior;
        match self.rule {
            LegRule::Waypoint => c.leg_ends(self.leg, &self.posterior, self.steps),
            LegRule::KfConvergence {
                eps_kf,
                eps_p,
                p_kf,
                full_kf,
            } => {
                let mean = &self.posterior.mean;
                let near = c.near_waypoint(self.leg, mean, c.eps_x);
                if !self.in_kf_phase && c.near_waypoint(self.leg, mean, eps_kf) {
                    self.in_kf_phase = true;
                    self.threshold = full_kf;
                }
                (self.in_kf_phase && near && (self.posterior.cov - p_kf).amax() <= eps_p)
                    || self.steps >= c.k_max
            }
        }
    }
}

/// Step 4's update with the serving sensor's filter: the measurement update
/// with a delivered `y`, else the silence update with factor `beta`. The
/// one formula of the slot update ([`super::SensorFilter::posterior`] and the
/// in-process leg loop call it).
#[inline(always)]
pub fn slot_update<const N: usize, const M: usize>(
    filter: &EtKalmanFilter<N, M>,
    prior: &Belief<N>,
    inn: &Innovation<N, M>,
    delivered: Option<&Vector<M>>,
    beta: f64,
) -> Belief<N> {
    match delivered {
        Some(y) => filter.update_explicit(prior, inn, y),
        None => filter.update_implicit(prior, inn, beta),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::episode::{EpisodeObserver, LegEnd, LegMode, StepEvent};
    use crate::radio::EpisodeChannels;
    use crate::rng::{stream_rng, streams};
    use crate::scenario::Scenario;

    /// Every step of a simulated leg, recorded: (belief after, transmitted, collided).
    #[derive(Default)]
    struct Steps(Vec<(Belief<2>, bool, bool)>);
    impl EpisodeObserver<2> for Steps {
        fn on_step(&mut self, e: &StepEvent<'_, 2>) {
            self.0.push((*e.belief, e.transmitted, e.collided));
        }
    }

    /// Driven from outside with the slots the simulator's leg loop served
    /// (measured y if transmitted, else silence), the core reproduces the
    /// leg loop's posteriors bit for bit and ends the leg at the same step.
    #[test]
    fn the_core_driven_from_outside_is_the_leg_loop() {
        let s = Scenario::builtin("winding-2d").expect("built-in");
        let c = CompiledScenario::<2>::new(&s);
        for episode in 0..5 {
            let delta = 1.2;
            let mut rng = stream_rng(3, streams::SIMULATE, episode);
            let mut state = c.initial_state(&mut rng);
            let start = state;
            let mut seen = Steps::default();
            let mode = LegMode::EventTriggered(Threshold::new(delta));
            let r = c.run_leg(
                0,
                &mut state,
                &mode,
                &mut rng,
                &mut EpisodeChannels::ideal(),
                &mut seen,
            );
            // Drive the core with the same random stream (plant noise, then
            // measurement noise, as the leg loop draws them) and, as what
            // the slot brought, the leg loop's trigger decisions.
            let mut rng = stream_rng(3, streams::SIMULATE, episode);
            let mut x = c.initial_state(&mut rng).x;
            assert_eq!(x, start.x);
            let mut core = AgentCore::for_delta(&c, 0, delta, start.belief, 0);
            let filter = match &c.filters[c.legs[0].sensor] {
                crate::episode::SensorFilter::M2(f) => *f,
                _ => panic!("winding-2d measures 2-D"),
            };
            for (i, (belief, transmitted, collided)) in seen.0.iter().enumerate() {
                let begun = core.begin(
                    &c,
                    &mut Plant {
                        x: &mut x,
                        rng: &mut rng,
                    },
                );
                let slot = match begun {
                    Begun::Collided(_) => {
                        assert!(*collided);
                        assert!(matches!(r.end, LegEnd::Collision { .. }));
                        break;
                    }
                    Begun::Slot(slot) => slot,
                };
                let y = filter.sensor.measure(&x, &mut rng);
                let outcome = if *transmitted {
                    SlotOutcome::Transmitted(y.as_slice())
                } else {
                    SlotOutcome::Silent
                };
                let ended = core.close(&c, slot, outcome);
                assert_eq!(core.posterior(), belief, "episode {episode} step {i}");
                assert_eq!(ended, i + 1 == seen.0.len(), "episode {episode} step {i}");
            }
            assert_eq!(core.steps(), r.steps);
            assert_eq!(core.posterior(), &state.belief);
        }
    }

    #[test]
    fn a_dead_slot_is_prediction_only_and_the_rules_end_legs() {
        let s = Scenario::builtin("winding-2d").expect("built-in");
        let c = CompiledScenario::<2>::new(&s);
        let b = c.initial;
        let mut core = AgentCore::for_delta(&c, 0, 1.0, b, 7);
        let Begun::Slot(slot) = core.begin(&c, &mut Unseen);
        let prior = *slot.prior();
        let ended = core.close(&c, slot, SlotOutcome::Dead);
        assert_eq!(core.posterior(), &prior);
        assert_eq!((core.step(), core.steps()), (8, 1));
        assert!(!ended);
        // A leg ends at k_max whatever the estimate.
        let mut core = AgentCore::for_delta(&c, 0, 1.0, b, 0);
        let mut ends = 0;
        for _ in 0..c.k_max {
            let Begun::Slot(slot) = core.begin(&c, &mut Unseen);
            ends += u32::from(core.close(&c, slot, SlotOutcome::Dead));
        }
        assert!(ends >= 1);
        // Method 1 switches to δ = 0 once near the waypoint (eps_kf huge)
        // and ends only when P is within eps_p of P_KF.
        let full_kf = Threshold::new(0.0);
        let rule = LegRule::KfConvergence {
            eps_kf: f64::INFINITY,
            eps_p: -1.0,
            p_kf: Matrix::<2, 2>::zeros(),
            full_kf,
        };
        let mut core = AgentCore::open(0, Threshold::new(2.0), rule, b, 0);
        let Begun::Slot(slot) = core.begin(&c, &mut Unseen);
        assert!(!core.close(&c, slot, SlotOutcome::Silent));
        assert!(core.in_kf_phase());
        assert_eq!(core.threshold(), full_kf);
    }
}
