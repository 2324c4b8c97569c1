//! The task of docs/MODEL.md §3: legs, controller, collision, leg termination and the
//! end-of-episode classification, over fixed-size state.
//!
//! [`CompiledScenario`] is a [`Scenario`] converted once to stack matrices.
//! [`CompiledScenario::run_leg`] runs one leg from a given (true state, belief)
//! — the unit the Monte Carlo abstraction samples — and
//! [`CompiledScenario::run_episode`] chains legs with a threshold policy.
//!
//! Step order inside leg i (exactly docs/MODEL.md §3 in the general form of §7; a
//! leg always runs at least one step, termination is checked after the step):
//! 1. `u = sat(K (C⁺w_i − x̂), u_max)` (K = C = I: `sat(w_i − x̂, u_max)`)
//! 2. `x ← F x + G u + w`
//! 3. `C x` in a closed obstacle box → collision (terminal, no measurement)
//! 4. the serving sensor measures and triggers; on a trigger its link makes its
//!    attempts (docs/MODEL.md §8); the filter updates (measurement update if
//!    delivered, else the silence update with β, or β_q for the aware estimator)
//! 5. `k_i += 1`; the leg ends if `‖C x̂ − w_i‖ ≤ ε_x` or `k_i ≥ k_max`
//!
//! Random numbers are drawn in a fixed order per step (process noise, then
//! measurement noise), so a seed fixes an episode completely; packet fates come
//! from the [`EpisodeChannels`] of the episode, one stream per link, so an
//! ideal radio draws nothing and leaves every result as it was.
//!
//! The step's order is written once, in [`agent_core::AgentCore`] (over the
//! pieces of [`step`]): the leg loop here drives it, as do the agent
//! process, `etp replay verify` and the sensor's replica.

// Declared before the submodules, which use it too.
/// Apply `$body` to the inner `EtKalmanFilter<N, M>` of a [`SensorFilter`].
macro_rules! on_filter {
    ($sf:expr, $f:ident => $body:expr) => {
        match $sf {
            SensorFilter::M1($f) => $body,
            SensorFilter::M2($f) => $body,
            SensorFilter::M3($f) => $body,
            SensorFilter::M4($f) => $body,
            SensorFilter::M5($f) => $body,
            SensorFilter::M6($f) => $body,
        }
    };
}

pub mod agent_core;
pub mod replica;
pub mod step;

pub use agent_core::{AgentCore, Begun, LegRule, OpenSlot, Plant, Unseen, World, slot_update};
pub use replica::{LegReplica, belief_digest};
pub use step::{RunSlot, ServedSlot, SlotKey, SlotOutcome, serve_slot};

use crate::controller::{FeedbackController, reached};
use crate::etkf::{
    Belief, EtKalmanFilter, Innovation, LinearPlant, Matrix, Threshold, Vector, sample_belief,
};
use crate::gaussian;
use crate::geometry::{StaticBox, WorkspaceMap, first_containing, pad_point};
use crate::linalg::to_static_vec;
use crate::radio::{EpisodeChannels, Estimator, Radio, Transmission};
use crate::scenario::Scenario;
use crate::trigger::{self, TriggerFamily};
use rand::Rng;

/// The ET-KF of one sensor, whatever its measurement dimension.
#[derive(Debug, Clone, Copy)]
pub enum SensorFilter<const N: usize> {
    M1(EtKalmanFilter<N, 1>),
    M2(EtKalmanFilter<N, 2>),
    M3(EtKalmanFilter<N, 3>),
    M4(EtKalmanFilter<N, 4>),
    M5(EtKalmanFilter<N, 5>),
    M6(EtKalmanFilter<N, 6>),
}

impl<const N: usize> SensorFilter<N> {
    pub fn new(scenario: &Scenario, sensor: usize) -> Self {
        let (p, s) = (&scenario.plant, &scenario.sensors[sensor]);
        match s.dim() {
            1 => Self::M1(EtKalmanFilter::new(p, s)),
            2 => Self::M2(EtKalmanFilter::new(p, s)),
            3 => Self::M3(EtKalmanFilter::new(p, s)),
            4 => Self::M4(EtKalmanFilter::new(p, s)),
            5 => Self::M5(EtKalmanFilter::new(p, s)),
            6 => Self::M6(EtKalmanFilter::new(p, s)),
            m => panic!("measurement dimension {m} outside 1..=6 (scenario validation bug)"),
        }
    }

    /// Measurement dimension m.
    pub fn dim(&self) -> usize {
        on_filter!(self, f => f.sensor.h.nrows())
    }

    /// Energy per transmission.
    pub fn cost(&self) -> f64 {
        on_filter!(self, f => f.sensor.cost)
    }

    /// Steady-state posterior covariance of the full Kalman filter (δ = 0).
    pub fn steady_state_posterior(&self) -> Matrix<N, N> {
        on_filter!(self, f => f.steady_state_posterior())
    }

    /// The posterior after a slot of this sensor: the explicit update with the
    /// transmitted `y` (its first m entries; `y.len() >= m`), else the
    /// implicit update with factor β. The one slot update shared by the
    /// agent process and `etp replay verify`, so both compute the same bits.
    pub fn posterior(&self, prior: &Belief<N>, y: Option<&[f64]>, beta: f64) -> Belief<N> {
        on_filter!(self, f => {
            let inn = f.innovation(prior);
            let y = y.map(|y| Vector::from_fn(|i, _| y[i]));
            slot_update(f, prior, &inn, y.as_ref(), beta)
        })
    }

    /// One prediction with a zero input and an implicit update with factor β —
    /// the covariance recursion of a silent step (used to bound eigenvalues).
    pub fn silent_covariance_step(&self, cov: &Matrix<N, N>, beta: f64) -> Matrix<N, N> {
        on_filter!(self, f => {
            let prior = f.predict(&Belief { mean: Vector::<N>::zeros(), cov: *cov }, &Vector::<N>::zeros());
            let inn = f.innovation(&prior);
            f.update_implicit(&prior, &inn, beta).cov
        })
    }
}

/// How thresholds are applied inside a leg.
#[derive(Debug, Clone, Copy)]
pub enum LegMode<const N: usize> {
    /// Method 2 and constant-δ runs: one threshold for the whole leg.
    EventTriggered(Threshold),
    /// Method 1 (docs/MODEL.md §4): `threshold` until the estimate comes within
    /// `eps_kf` of the waypoint, then δ = 0 (sticky) and the leg ends only once
    /// `‖P − P_KF‖max ≤ eps_p` and the mean criterion hold (or at `k_max`).
    KfConvergence {
        threshold: Threshold,
        eps_kf: f64,
        eps_p: f64,
        p_kf: Matrix<N, N>,
    },
}

/// The agent's state: true plant state and the filter's posterior.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AgentState<const N: usize> {
    pub x: Vector<N>,
    pub belief: Belief<N>,
}

/// How a leg ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LegEnd {
    /// The true state entered obstacle `obstacle` (index into the scenario's list).
    Collision { obstacle: usize },
    /// The termination rule fired (waypoint reached or `k_max`).
    Terminated,
}

/// Counts of one leg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegResult {
    pub end: LegEnd,
    /// Plant moves in this leg (the colliding move included).
    pub steps: u32,
    /// Measurement slots (steps that reached the sensor: all but a colliding one).
    pub slots: u32,
    /// Transmission attempts (each costs c_m; = triggers on an ideal radio).
    pub transmissions: u32,
    /// Slots whose measurement triggered (‖ε‖∞ > δ).
    pub triggers: u32,
    /// Triggers whose measurement reached the agent.
    pub delivered: u32,
    /// Slots spent in the enforced δ = 0 phase of [`LegMode::KfConvergence`].
    pub kf_slots: u32,
    /// Σ over slots of γ̄(δ, m): the transmissions the Gaussian assumption predicts.
    pub expected_transmissions: f64,
}

impl LegResult {
    /// One measurement slot: `sent` triggered, `sending` is what the link
    /// did with it, `kf` whether it was in the enforced δ = 0 phase,
    /// `expected` the transmissions the model expected of it.
    #[inline(always)]
    fn count_slot(&mut self, sent: bool, sending: Transmission, kf: bool, expected: f64) {
        self.slots += 1;
        self.transmissions += sending.attempts;
        self.triggers += u32::from(sent);
        self.delivered += u32::from(sending.delivered);
        self.kf_slots += u32::from(kf);
        self.expected_transmissions += expected;
    }
}

/// What the serving link does with a slot's measurement: nothing unless it
/// `sent`; one delivered attempt on an ideal link; a lossy link's fate from
/// `channels`.
#[inline(always)]
fn transmission(
    sent: bool,
    lossy: bool,
    channels: &mut EpisodeChannels,
    sensor: usize,
) -> Transmission {
    if !sent {
        Transmission {
            attempts: 0,
            delivered: false,
        }
    } else if lossy {
        channels.transmit(sensor)
    } else {
        Transmission {
            attempts: 1,
            delivered: true,
        }
    }
}

/// A leg's opening threshold and its end rule under `mode`; `silence` gives
/// a threshold its silence factor (the enforced δ = 0 phase's among them).
#[inline(always)]
fn leg_rule<const N: usize>(
    mode: &LegMode<N>,
    silence: impl Fn(Threshold) -> Threshold,
) -> (Threshold, LegRule<N>) {
    match *mode {
        LegMode::EventTriggered(t) => (t, LegRule::Waypoint),
        LegMode::KfConvergence {
            threshold,
            eps_kf,
            eps_p,
            p_kf,
        } => (
            threshold,
            LegRule::KfConvergence {
                eps_kf,
                eps_p,
                p_kf,
                full_kf: silence(Threshold::new(0.0)),
            },
        ),
    }
}

/// Terminal classification of an episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Outcome {
    Target,
    Collision,
    Free,
}

/// Totals of one episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeResult {
    pub outcome: Outcome,
    pub steps: u32,
    pub slots: u32,
    /// Transmission attempts.
    pub transmissions: u32,
    pub triggers: u32,
    pub delivered: u32,
    /// Σ c_m × attempts over the episode.
    pub energy: f64,
    /// Σ γ̄(δ, m) over the episode's slots.
    pub expected_transmissions: f64,
}

/// What happened at one step, for observers (trajectories, plots, per-sensor counts).
#[derive(Debug, Clone, Copy)]
pub struct StepEvent<'a, const N: usize> {
    pub leg: usize,
    /// True state after the move.
    pub x: &'a Vector<N>,
    /// Posterior after the update (the previous posterior on a colliding step).
    pub belief: &'a Belief<N>,
    pub delta: f64,
    /// The measurement triggered (the sensor transmitted at least once).
    pub transmitted: bool,
    /// Attempts made this step (0 without a trigger).
    pub attempts: u32,
    /// The measurement reached the agent.
    pub delivered: bool,
    pub collided: bool,
}

/// Hooks into a running episode; `()` observes nothing and compiles away.
pub trait EpisodeObserver<const N: usize> {
    #[inline]
    fn on_step(&mut self, _event: &StepEvent<'_, N>) {}
    #[inline]
    fn on_leg_end(&mut self, _leg: usize, _sensor: usize, _result: &LegResult) {}
}

impl<const N: usize> EpisodeObserver<N> for () {}

/// One leg of the route in fixed-size form.
#[derive(Debug, Clone, Copy)]
pub struct CompiledLeg<const N: usize> {
    /// The workspace waypoint w_i, padded to N (zero past d).
    pub waypoint: Vector<N>,
    /// The controller's reference `C⁺ w_i` (= w_i when C = I).
    pub reference: Vector<N>,
    pub sensor: usize,
}

/// A scenario in fixed-size form, ready for the hot loop.
#[derive(Debug, Clone)]
pub struct CompiledScenario<const N: usize> {
    pub plant: LinearPlant<N>,
    pub initial: Belief<N>,
    pub filters: Vec<SensorFilter<N>>,
    pub legs: Vec<CompiledLeg<N>>,
    pub obstacles: Vec<StaticBox<N>>,
    pub target: StaticBox<N>,
    pub u_max: f64,
    pub eps_x: f64,
    pub k_max: u32,
    /// `u = sat(K (r − x̂), u_max)` (MODEL.md §7).
    pub controller: FeedbackController<N>,
    /// `q = C x`: collisions, leg ends and the target are decided on it.
    pub workspace: WorkspaceMap<N>,
    /// The radio: one link per sensor, the agent's estimator (docs/MODEL.md §8).
    pub radio: Radio,
    /// How the sensors decide to transmit (docs/MODEL.md §9).
    pub trigger: TriggerFamily,
}

/// One leg's call, from [`CompiledScenario::run_leg`] through the
/// instruction-set dispatch to the leg loop.
pub(crate) struct LegCall<'a, const N: usize, R: ?Sized, O> {
    leg: usize,
    state: &'a mut AgentState<N>,
    mode: &'a LegMode<N>,
    rng: &'a mut R,
    channels: &'a mut EpisodeChannels,
    observer: &'a mut O,
}

impl<const N: usize> CompiledScenario<N> {
    /// Convert a validated scenario; `N` must equal `scenario.dim`
    /// (use [`crate::with_dim!`]).
    pub fn new(scenario: &Scenario) -> Self {
        assert_eq!(
            scenario.dim, N,
            "CompiledScenario<{N}> for a {}-D scenario",
            scenario.dim
        );
        Self {
            plant: LinearPlant::new(&scenario.plant),
            initial: LinearPlant::<N>::initial_belief(&scenario.plant),
            filters: (0..scenario.sensors.len())
                .map(|s| SensorFilter::new(scenario, s))
                .collect(),
            legs: scenario
                .legs
                .iter()
                .map(|l| CompiledLeg {
                    waypoint: pad_point(l.to.as_slice()),
                    reference: to_static_vec(&scenario.reference(&l.to)),
                    sensor: l.sensor,
                })
                .collect(),
            obstacles: scenario
                .obstacles
                .iter()
                .map(|o| o.bounds.to_static())
                .collect(),
            target: scenario.target.to_static(),
            u_max: scenario.controller.u_max,
            eps_x: scenario.controller.eps_x,
            k_max: scenario.controller.k_max,
            controller: FeedbackController::new(scenario),
            workspace: WorkspaceMap::new(scenario.workspace.as_ref()),
            radio: scenario.radio.clone(),
            trigger: scenario.trigger,
        }
    }

    /// The factor of the silence update of sensor `sensor`'s slot at δ for a
    /// family other than `box` (docs/MODEL.md §9): the family's own on an
    /// ideal link or for the naive estimator, the aware mixture of §8.3 with
    /// the family's moments on a lossy link (0 where silence is read as
    /// uninformative). Send-on-delta's ideal silence is its pseudo-measurement,
    /// applied by the leg loop; the factor here is its lossy fallback, 0.
    pub fn silence_factor(&self, sensor: usize, delta: f64, m: usize) -> f64 {
        let link = self.radio.link(sensor);
        let q = if link.is_ideal() || self.radio.estimator == Estimator::Naive {
            0.0
        } else {
            link.residual_loss()
        };
        self.trigger.lossy_silence_factor(delta, m, q)
    }

    /// The family's expected rate at δ for measurement dimension m, where
    /// it has a closed form ([`TriggerFamily::expected_rate`]); 0 otherwise
    /// (the leg loop then counts the decisions instead).
    fn expected_rate(&self, delta: f64, m: usize) -> f64 {
        self.trigger.expected_rate(delta, m).unwrap_or(0.0)
    }

    /// The serving sensor's decision with the scenario's family
    /// (docs/MODEL.md §9) at the leg's slot number `slot` (from 0): `inn` the
    /// prior's innovation, `y` the measurement, `last_delivered` the last
    /// measurement the agent received on this leg (send-on-delta), `draw`
    /// the stochastic family's uniform (called only by it; `None`: send, the
    /// safe side). The one definition of the decision: the in-process leg
    /// loop, the sensor process and `etp replay verify` call it.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn decides<const M: usize>(
        &self,
        filter: &EtKalmanFilter<N, M>,
        inn: &Innovation<N, M>,
        y: &Vector<M>,
        delta: f64,
        slot: u32,
        last_delivered: Option<&Vector<M>>,
        draw: impl FnOnce() -> Option<f64>,
    ) -> bool {
        match self.trigger {
            TriggerFamily::Box => inn.triggers(y, delta),
            TriggerFamily::Stochastic => {
                let Some(u) = draw() else {
                    return true;
                };
                let z = y - inn.predicted;
                let norm2 = inn
                    .cov_inv
                    .map_or(f64::INFINITY, |z_inv| z.dot(&(z_inv * z)));
                trigger::stochastic_sends(norm2, delta, u)
            }
            TriggerFamily::SendOnDelta => {
                trigger::send_on_delta_sends(y, last_delivered, filter.sensor.r_chol(), delta)
            }
            TriggerFamily::Variance => {
                trigger::variance_sends(&(inn.cov - filter.sensor.r), filter.sensor.r_chol(), delta)
            }
            TriggerFamily::Periodic => {
                trigger::periodic_sends(u64::from(slot), gaussian::expected_rate(delta, M))
            }
        }
    }

    /// The radio channels of episode (or segment) `index` of stream `stream`
    /// under `seed`: every run of a leg or episode takes them, so a lossy
    /// radio is never simulated as an ideal one by accident.
    pub fn channels(&self, seed: u64, stream: u64, index: u64) -> EpisodeChannels {
        let channels = if self.radio.is_ideal() {
            EpisodeChannels::ideal()
        } else {
            EpisodeChannels::new(&self.radio, seed, stream, index)
        };
        if self.trigger.draws() {
            channels.with_trigger_draws(seed, stream, index, self.filters.len())
        } else {
            channels
        }
    }

    /// The input at step k of leg `leg` for estimate `mean` (MODEL.md §7 step 1).
    #[inline(always)]
    pub fn input(&self, leg: usize, mean: &Vector<N>) -> Vector<N> {
        self.controller.input(&self.legs[leg].reference, mean)
    }

    /// The obstacle the true state `x` lies in, judged on `C x`.
    #[inline(always)]
    pub fn collision(&self, x: &Vector<N>) -> Option<usize> {
        first_containing(&self.obstacles, &self.workspace.point(x))
    }

    /// `‖C x̂ − w_leg‖₂ ≤ eps` (the leg-end test with `eps = eps_x`).
    #[inline(always)]
    pub fn near_waypoint(&self, leg: usize, mean: &Vector<N>, eps: f64) -> bool {
        reached(&self.workspace.point(mean), &self.legs[leg].waypoint, eps)
    }

    /// The end-of-episode test: `C x` in the target box.
    #[inline(always)]
    pub fn in_target(&self, x: &Vector<N>) -> bool {
        self.target.contains(&self.workspace.point(x))
    }

    /// Draw the initial true state `x0 ~ N(x̂0, P0)`; the belief is `(x̂0, P0)`.
    pub fn initial_state<R: Rng + ?Sized>(&self, rng: &mut R) -> AgentState<N> {
        AgentState {
            x: sample_belief(&self.initial, rng),
            belief: self.initial,
        }
    }

    /// Run leg `leg` from `state` (updated in place) under `mode`; the
    /// serving link's attempts go through `channels` (from [`Self::channels`]).
    pub fn run_leg<R: Rng + ?Sized, O: EpisodeObserver<N>>(
        &self,
        leg: usize,
        state: &mut AgentState<N>,
        mode: &LegMode<N>,
        rng: &mut R,
        channels: &mut EpisodeChannels,
        observer: &mut O,
    ) -> LegResult {
        let sensor = self.legs[leg].sensor;
        let call = LegCall {
            leg,
            state,
            mode,
            rng,
            channels,
            observer: &mut *observer,
        };
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        let result = if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above), the one
            // requirement of calling a `#[target_feature]` function.
            unsafe { self.run_leg_avx2(sensor, call) }
        } else {
            on_filter!(&self.filters[sensor], f => self.run_leg_portable(f, call))
        };
        #[cfg(not(target_arch = "x86_64"))]
        let result = on_filter!(&self.filters[sensor], f => self.run_leg_portable(f, call));
        observer.on_leg_end(leg, sensor, &result);
        result
    }

    /// [`Self::run_leg_with`] compiled for AVX2: the fixed-size products of
    /// the step ([`crate::dense`]) run four lanes wide instead of two. Same
    /// bits: AVX2 alone brings no fused multiply-add, and Rust never contracts
    /// `a * b + c`, so every operation rounds as in the baseline build (the
    /// golden numbers and the `simulate` outputs are compared in the tests).
    /// Callable only where AVX2 is known to be present ([`Self::run_leg`]
    /// checks at run time). The six loops (one per measurement dimension)
    /// are inlined here: split into one function per M, winding-2d ran 23 %
    /// slower per thread (`etp bench`, interleaved medians).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_leg_avx2<R: Rng + ?Sized, O: EpisodeObserver<N>>(
        &self,
        sensor: usize,
        call: LegCall<'_, N, R, O>,
    ) -> LegResult {
        on_filter!(&self.filters[sensor], f => self.run_leg_with(f, call))
    }

    /// [`Self::run_leg_with`] in the baseline instruction set, one function
    /// per measurement dimension M: a function (or a test) that inlined the
    /// loops of every M and every N it dispatches over costs the optimiser
    /// super-linear time (the AVX2 comparison test held 36 of them: 31
    /// CPU-minutes of one rustc).
    #[inline(never)]
    pub(crate) fn run_leg_portable<const M: usize, R: Rng + ?Sized, O: EpisodeObserver<N>>(
        &self,
        filter: &EtKalmanFilter<N, M>,
        call: LegCall<'_, N, R, O>,
    ) -> LegResult {
        self.run_leg_with(filter, call)
    }

    /// The threshold a leg's silences update with: β_q(δ) for the aware
    /// estimator; the family's own for the others (docs/MODEL.md §9); on a
    /// lossy link, the radio's.
    #[inline(always)]
    fn silence_threshold(&self, sensor: usize, lossy: bool, t: Threshold, m: usize) -> Threshold {
        if self.trigger != TriggerFamily::Box {
            Threshold {
                delta: t.delta,
                beta: self.silence_factor(sensor, t.delta, m),
            }
        } else if lossy {
            Threshold {
                delta: t.delta,
                beta: self.radio.silence_beta(sensor, t.delta, m),
            }
        } else {
            t
        }
    }

    /// The leg loop: [`AgentCore`]'s step (the one order of the step) with
    /// the world the simulated plant and the slot served inline by the
    /// serving sensor's typed filter (`M` known here: one innovation for
    /// trigger and update; the radio's fate from `channels`).
    #[inline(always)]
    fn run_leg_with<const M: usize, R: Rng + ?Sized, O: EpisodeObserver<N>>(
        &self,
        filter: &EtKalmanFilter<N, M>,
        call: LegCall<'_, N, R, O>,
    ) -> LegResult {
        let LegCall {
            leg,
            state,
            mode,
            rng,
            channels,
            observer,
        } = call;
        let sensor = self.legs[leg].sensor;
        // A lossy serving link takes the lossy step; an ideal one the step of
        // §2 exactly (same operations, same bits).
        let lossy = !self.radio.link(sensor).is_ideal();
        let family = self.trigger;
        // The silence update's factor: β_q(δ) for the aware estimator; the
        // family's own for the others (docs/MODEL.md §9).
        let silence = |t: Threshold| self.silence_threshold(sensor, lossy, t, M);
        // Send-on-delta's reference: the last measurement the agent received
        // on this leg (none yet: the next slot sends).
        let mut last_delivered: Option<Vector<M>> = None;
        let counted_rate = !family.has_model_rate();
        let (threshold, rule) = leg_rule(mode, silence);
        let mut core = AgentCore::open(leg, silence(threshold), rule, state.belief, 0);
        let mut r = LegResult {
            end: LegEnd::Terminated,
            steps: 0,
            slots: 0,
            transmissions: 0,
            triggers: 0,
            delivered: 0,
            kf_slots: 0,
            expected_transmissions: 0.0,
        };
        let mut expected_rate = self.expected_rate(core.threshold().delta, M);
        loop {
            let begun = core.begin(
                self,
                &mut Plant {
                    x: &mut state.x,
                    rng: &mut *rng,
                },
            );
            channels.start_step();
            r.steps += 1;
            let slot = match begun {
                Begun::Slot(slot) => slot,
                Begun::Collided(obstacle) => {
                    observer.on_step(&StepEvent {
                        leg,
                        x: &state.x,
                        belief: core.posterior(),
                        delta: core.threshold().delta,
                        transmitted: false,
                        attempts: 0,
                        delivered: false,
                        collided: true,
                    });
                    state.belief = *core.posterior();
                    r.end = LegEnd::Collision { obstacle };
                    return r;
                }
            };
            // The serving sensor's slot (docs/MODEL.md §2, §8): measure,
            // trigger on the prior's innovation, transmit over the link —
            // `step::serve_slot` written inline: a build with this loop
            // through it (a closure for the link), and `simulate_constant`
            // moved into etp-synthesis, ran winding-2d at 0.55–0.65 of this
            // speed (`etp bench`, interleaved medians; which of the two cost
            // it was not isolated).
            let threshold = core.threshold();
            let y = filter.sensor.measure(&state.x, rng);
            let inn = filter.innovation(slot.prior());
            let sent = match family {
                TriggerFamily::Box => inn.triggers(&y, threshold.delta),
                // Every episode's channels carry the draws of a drawing
                // family (`Self::channels`).
                _ => self.decides(
                    filter,
                    &inn,
                    &y,
                    threshold.delta,
                    r.slots,
                    last_delivered.as_ref(),
                    || channels.trigger_uniform(sensor),
                ),
            };
            let sending = transmission(sent, lossy, channels, sensor);
            let delivered = sending.delivered.then_some(&y);
            let post = match (family, delivered, last_delivered.as_ref()) {
                // Send-on-delta's silence on a link that loses nothing: the
                // last delivered measurement as a pseudo-measurement.
                (TriggerFamily::SendOnDelta, None, Some(reference)) if !lossy => filter
                    .update_pseudo_measurement(
                        slot.prior(),
                        &inn,
                        reference,
                        trigger::send_on_delta_noise_scale(threshold.delta),
                    ),
                _ => slot_update(filter, slot.prior(), &inn, delivered, threshold.beta),
            };
            if family == TriggerFamily::SendOnDelta && sending.delivered {
                last_delivered = Some(y);
            }
            r.count_slot(
                sent,
                sending,
                core.in_kf_phase(),
                if counted_rate {
                    // Variance and periodic decide deterministically (given
                    // P⁻, given the slot number), so a slot's expectation is
                    // its decision; send-on-delta has no model rate
                    // (docs/MODEL.md §9): the count stands in.
                    f64::from(u8::from(sent))
                } else {
                    expected_rate
                },
            );
            observer.on_step(&StepEvent {
                leg,
                x: &state.x,
                belief: &post,
                delta: threshold.delta,
                transmitted: sent,
                attempts: sending.attempts,
                delivered: sending.delivered,
                collided: false,
            });
            let done = core.close_with(self, slot, post);
            if done {
                state.belief = *core.posterior();
                return r;
            }
            if core.in_kf_phase() {
                expected_rate = 1.0;
            }
        }
    }

    /// Run a whole episode: draw `x0`, then for each leg ask `policy(leg, belief)`
    /// for the leg's mode, run it, stop at a collision; classify at the end.
    /// Packet fates come from `channels` (from [`Self::channels`]).
    pub fn run_episode<R, P, O>(
        &self,
        mut policy: P,
        rng: &mut R,
        channels: &mut EpisodeChannels,
        observer: &mut O,
    ) -> EpisodeResult
    where
        R: Rng + ?Sized,
        P: FnMut(usize, &Belief<N>, &mut R) -> LegMode<N>,
        O: EpisodeObserver<N>,
    {
        let mut state = self.initial_state(rng);
        let mut total = EpisodeResult {
            outcome: Outcome::Free,
            steps: 0,
            slots: 0,
            transmissions: 0,
            triggers: 0,
            delivered: 0,
            energy: 0.0,
            expected_transmissions: 0.0,
        };
        for leg in 0..self.legs.len() {
            let mode = policy(leg, &state.belief, rng);
            let r = self.run_leg(leg, &mut state, &mode, rng, channels, observer);
            crate::add_fields!(total, r; steps, slots, transmissions, triggers, delivered, expected_transmissions);
            total.energy += f64::from(r.transmissions) * self.filters[self.legs[leg].sensor].cost();
            if let LegEnd::Collision { .. } = r.end {
                total.outcome = Outcome::Collision;
                return total;
            }
        }
        total.outcome = self.classify_end(&state.x);
        total
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod higher_tests;
