//! What a sensor does with each message, as pure functions of its state: no
//! ports, no clock. [`crate::node`] is the thin iceoryx2 adapter around it
//! (receive, call, publish), so every decision here is unit-tested without
//! processes.
//!
//! The sensor knows the agent's estimate without a per-step downlink: at the
//! start of each leg it serves the agent hands its belief over (`handover`),
//! and from then on a [`LegReplica`] runs the agent's own step
//! (`episode::AgentCore`) on every slot, with what the sensor itself did
//! (transmitted y, or stayed silent). The slot carries the replica prior's
//! digest; the agent checks it.

use etp_runtime::wire::agent_to_sensor::{Handover, Truth};
use etp_runtime::wire::coordinator_to_all::Threshold;
use etp_runtime::wire::{ThresholdKind, WireVec, belief_from_wire, to_wire_vec, vec_from_wire};
use etp_shared::episode::{CompiledScenario, LegReplica, SlotOutcome};
use etp_shared::etkf::{EtKalmanFilter, Vector};
use etp_shared::rng::{stream_rng, streams};

/// What the sensor spent on one leg.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LegLedger {
    pub episode: u64,
    pub leg: u32,
    pub slots: u32,
    pub transmissions: u32,
}

/// Totals of a sensor process (logged at exit).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SensorStats {
    pub slots: u64,
    pub transmissions: u64,
    pub handovers: u64,
    pub wakeups: u64,
}

/// What the adapter must do after a `threshold` message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ControlAction {
    /// Nothing to send (a leg opened, or a message of another run).
    None,
    /// Publish this ledger to the coordinator (the leg was closed).
    Ledger { ledger: LegLedger, energy: f64 },
    /// The coordinator said stop.
    Stop,
}

/// The outcome of one slot: always a `slot` message, and a `measurement`
/// (costed) when the trigger fired.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlotDecision {
    pub episode: u64,
    pub leg: u32,
    pub step: u32,
    /// `Some((y, n))`: transmit y, the n-th transmission of this episode.
    pub transmit: Option<(WireVec, u32)>,
    /// `belief_digest` of the replica's prior this slot triggered on.
    pub prior_digest: u64,
}

/// Why a message cannot be served (yet).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SlotError {
    /// The leg is not (yet) open here. The adapter drains `threshold` once
    /// more before calling it a protocol error: the OPEN is published before
    /// the agent can hand over or send the leg's first truth, but they may
    /// arrive in one wake-up.
    #[error("message for episode {episode} leg {leg} but the open leg is {open:?}")]
    LegNotOpen {
        episode: u64,
        leg: u32,
        open: Option<(u64, u32)>,
    },
    /// A truth of an open leg whose handover has not been read yet.
    #[error("truth of episode {episode} leg {leg} before the leg's handover")]
    NoHandover { episode: u64, leg: u32 },
    /// The replica is at another step (a slot lost or repeated).
    #[error("truth of episode {episode} step {step}, the replica is at step {expected}")]
    StepGap {
        episode: u64,
        step: u32,
        expected: u32,
    },
}

/// The open leg: its threshold, its ledger so far and, once handed over,
/// the replica of the agent's estimate.
#[derive(Debug, Clone, Copy)]
struct OpenLeg<const N: usize> {
    delta: f64,
    ledger: LegLedger,
    replica: Option<LegReplica<N>>,
}

/// One sensor's state between messages.
pub struct SensorCore<const N: usize, const M: usize> {
    scenario: CompiledScenario<N>,
    filter: EtKalmanFilter<N, M>,
    cost: f64,
    index: u32,
    seed: u64,
    tag: u64,
    open: Option<OpenLeg<N>>,
    /// The latest (episode, leg) closed here: a handover of it or of an
    /// earlier leg is stale (a leg can close before its handover is read,
    /// e.g. when it ends by a collision on its first step).
    closed: Option<(u64, u32)>,
    /// (episode, transmissions in it) for the `sequence` field.
    episode_count: (u64, u32),
    pub stats: SensorStats,
}

impl<const N: usize, const M: usize> SensorCore<N, M> {
    /// Sensor `index` of `scenario` (its filter, the agent's controller and
    /// plant for the replica), cost per transmission `cost`, run seed and
    /// run tag (messages of other runs are ignored).
    pub fn new(
        scenario: CompiledScenario<N>,
        filter: EtKalmanFilter<N, M>,
        cost: f64,
        index: u32,
        seed: u64,
        tag: u64,
    ) -> Self {
        Self {
            scenario,
            filter,
            cost,
            index,
            seed,
            tag,
            open: None,
            closed: None,
            episode_count: (u64::MAX, 0),
            stats: SensorStats::default(),
        }
    }

    /// A `threshold` message of this sensor's service.
    pub fn on_threshold(&mut self, t: &Threshold) -> ControlAction {
        if t.header.run != self.tag {
            return ControlAction::None;
        }
        match ThresholdKind::try_from(t.kind) {
            Ok(ThresholdKind::Stop) => ControlAction::Stop,
            Ok(ThresholdKind::Open) if t.sensor == self.index => {
                self.open = Some(OpenLeg {
                    delta: t.delta,
                    ledger: LegLedger {
                        episode: t.header.episode,
                        leg: t.header.leg,
                        slots: 0,
                        transmissions: 0,
                    },
                    replica: None,
                });
                ControlAction::None
            }
            Ok(ThresholdKind::Close) if t.sensor == self.index => {
                let key = (t.header.episode, t.header.leg);
                self.closed = Some(self.closed.map_or(key, |c| c.max(key)));
                let ledger = match self.open.take() {
                    Some(o)
                        if o.ledger.episode == t.header.episode && o.ledger.leg == t.header.leg =>
                    {
                        o.ledger
                    }
                    // A leg that never reached this sensor (e.g. ended by a
                    // collision on its first step) spent nothing.
                    other => {
                        self.open = other;
                        LegLedger {
                            episode: t.header.episode,
                            leg: t.header.leg,
                            ..LegLedger::default()
                        }
                    }
                };
                ControlAction::Ledger {
                    ledger,
                    energy: f64::from(ledger.transmissions) * self.cost,
                }
            }
            _ => ControlAction::None,
        }
    }

    /// The open leg of (episode, leg), if it is the one open.
    fn open_leg(&mut self, episode: u64, leg: u32) -> Result<&mut OpenLeg<N>, SlotError> {
        let open = self.open.map(|o| (o.ledger.episode, o.ledger.leg));
        self.open
            .as_mut()
            .filter(|o| o.ledger.episode == episode && o.ledger.leg == leg)
            .ok_or(SlotError::LegNotOpen { episode, leg, open })
    }

    /// Has leg (episode, leg) been closed here (a message of it is stale)?
    pub fn is_closed(&self, episode: u64, leg: u32) -> bool {
        self.closed.is_some_and(|c| (episode, leg) <= c)
    }

    /// The agent's belief at the start of the open leg: start the replica.
    pub fn on_handover(&mut self, h: &Handover) -> Result<(), SlotError> {
        if h.header.run != self.tag {
            return Ok(());
        }
        let (episode, leg) = (h.header.episode, h.header.leg);
        if self.is_closed(episode, leg) {
            return Ok(());
        }
        let delta = self.open_leg(episode, leg)?.delta;
        let belief = belief_from_wire::<N>(&h.mean, &h.cov);
        let replica =
            LegReplica::handed_over(&self.scenario, leg as usize, delta, belief, h.header.step);
        self.open_leg(episode, leg)?.replica = Some(replica);
        self.stats.handovers += 1;
        Ok(())
    }

    /// One slot, opened by the truth of step k: the replica's prior,
    /// y = H x + v (noise keyed by episode and step, so independent of
    /// timing), the whitened innovation and the trigger ‖ε‖∞ > δ
    /// (docs/MODEL.md §2); then the replica's update with what was done.
    pub fn on_slot(&mut self, t: &Truth) -> Result<SlotDecision, SlotError> {
        let (episode, leg, step) = (t.header.episode, t.header.leg, t.header.step);
        let seed = self.seed;
        let filter = self.filter;
        let scenario = &self.scenario;
        let open = self
            .open
            .as_mut()
            .filter(|o| o.ledger.episode == episode && o.ledger.leg == leg);
        let Some(open) = open else {
            return Err(SlotError::LegNotOpen {
                episode,
                leg,
                open: self.open.map(|o| (o.ledger.episode, o.ledger.leg)),
            });
        };
        let Some(replica) = open.replica.as_mut() else {
            return Err(SlotError::NoHandover { episode, leg });
        };
        if replica.next_step() != step {
            return Err(SlotError::StepGap {
                episode,
                step,
                expected: replica.next_step(),
            });
        }
        let mut rng = stream_rng(seed, streams::SENSOR, (episode << 32) | u64::from(step));
        let x: Vector<N> = vec_from_wire(&t.x);
        let served = replica.serve(scenario, &filter, |slot| {
            let y = slot.sensor.measure(&x, &mut rng);
            if slot.triggers(&y) {
                SlotOutcome::Delivered(y)
            } else {
                SlotOutcome::Silent
            }
        });
        open.ledger.slots += 1;
        self.stats.slots += 1;
        if self.episode_count.0 != episode {
            self.episode_count = (episode, 0);
        }
        let transmit = match &served.outcome {
            SlotOutcome::Delivered(y) => {
                open.ledger.transmissions += 1;
                self.stats.transmissions += 1;
                self.episode_count.1 += 1;
                // What the agent will receive: the wire copy of y (same bits).
                Some((to_wire_vec(y.as_slice()), self.episode_count.1))
            }
            SlotOutcome::Silent | SlotOutcome::Dead => None,
        };
        Ok(SlotDecision {
            episode,
            leg,
            step,
            transmit,
            prior_digest: served.prior_digest,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::wire::{Header, belief_to_wire};
    use etp_shared::episode::belief_digest;
    use etp_shared::etkf::{Belief, Matrix};
    use etp_shared::scenario::Scenario;

    const TAG: u64 = 7;

    fn core() -> SensorCore<2, 2> {
        let s = Scenario::builtin("open-2d").expect("built-in");
        let f = EtKalmanFilter::<2, 2>::new(&s.plant, &s.sensors[0]);
        SensorCore::new(CompiledScenario::new(&s), f, 1.5, 0, 3, TAG)
    }

    fn header(episode: u64, leg: u32, step: u32) -> Header {
        Header {
            run: TAG,
            episode,
            leg,
            step,
            ..Header::default()
        }
    }

    fn th(kind: u32, episode: u64, leg: u32, delta: f64) -> Threshold {
        Threshold {
            header: header(episode, leg, 0),
            kind,
            sensor: 0,
            delta,
            ..Threshold::default()
        }
    }

    fn belief() -> Belief<2> {
        Belief {
            mean: Vector::<2>::new(0.0, 0.0),
            cov: Matrix::<2, 2>::identity() * 0.01,
        }
    }

    /// Hand `b` over at the start of (episode, leg) after `step` steps.
    fn hand_over(c: &mut SensorCore<2, 2>, episode: u64, leg: u32, step: u32, b: &Belief<2>) {
        let (mean, cov) = belief_to_wire(b);
        c.on_handover(&Handover {
            header: header(episode, leg, step),
            dim: 2,
            mean,
            cov,
            ..Handover::default()
        })
        .expect("handover");
    }

    fn truth(episode: u64, leg: u32, step: u32) -> Truth {
        Truth {
            header: header(episode, leg, step),
            dim: 2,
            x: to_wire_vec(&[0.5, 0.0]),
            ..Truth::default()
        }
    }

    fn slot(c: &mut SensorCore<2, 2>, episode: u64, leg: u32, step: u32) -> SlotDecision {
        c.on_slot(&truth(episode, leg, step)).expect("slot")
    }

    #[test]
    fn a_closed_leg_yields_its_ledger_priced_at_the_cost() {
        let mut c = core();
        assert_eq!(
            c.on_threshold(&th(Threshold::OPEN, 4, 1, 0.0)),
            ControlAction::None
        );
        hand_over(&mut c, 4, 1, 0, &belief());
        // δ = 0 transmits every slot.
        for k in 1..=3 {
            assert!(slot(&mut c, 4, 1, k).transmit.is_some());
        }
        let ControlAction::Ledger { ledger, energy } =
            c.on_threshold(&th(Threshold::CLOSE, 4, 1, 0.0))
        else {
            panic!("no ledger")
        };
        assert_eq!((ledger.slots, ledger.transmissions), (3, 3));
        assert_eq!(energy, 4.5);
        // Transmissions are numbered per episode.
        c.on_threshold(&th(Threshold::OPEN, 4, 3, 0.0));
        hand_over(&mut c, 4, 3, 8, &belief());
        assert_eq!(slot(&mut c, 4, 3, 9).transmit.map(|t| t.1), Some(4));
        assert_eq!(c.stats.handovers, 2);
    }

    #[test]
    fn a_huge_threshold_is_silent_and_costs_nothing() {
        let mut c = core();
        c.on_threshold(&th(Threshold::OPEN, 0, 0, 1e9));
        hand_over(&mut c, 0, 0, 0, &belief());
        assert!(slot(&mut c, 0, 0, 1).transmit.is_none());
        let a = c.on_threshold(&th(Threshold::CLOSE, 0, 0, 0.0));
        assert!(
            matches!(a, ControlAction::Ledger { ledger, energy } if ledger.slots == 1 && ledger.transmissions == 0 && energy == 0.0)
        );
    }

    #[test]
    fn a_leg_that_never_reached_the_sensor_has_an_empty_ledger_and_keeps_the_open_one() {
        let mut c = core();
        c.on_threshold(&th(Threshold::OPEN, 1, 2, 0.0));
        hand_over(&mut c, 1, 2, 4, &belief());
        let a = c.on_threshold(&th(Threshold::CLOSE, 1, 0, 0.0));
        assert!(
            matches!(a, ControlAction::Ledger { ledger, .. } if ledger.leg == 0 && ledger.slots == 0)
        );
        // Leg 2 is still open.
        assert_eq!(slot(&mut c, 1, 2, 5).leg, 2);
    }

    #[test]
    fn a_truth_of_an_unopened_or_unhanded_leg_or_out_of_step_is_reported_not_served() {
        let mut c = core();
        assert_eq!(
            c.on_slot(&truth(2, 1, 1)),
            Err(SlotError::LegNotOpen {
                episode: 2,
                leg: 1,
                open: None
            })
        );
        c.on_threshold(&th(Threshold::OPEN, 2, 1, 1.0));
        assert_eq!(
            c.on_slot(&truth(2, 1, 1)),
            Err(SlotError::NoHandover { episode: 2, leg: 1 })
        );
        hand_over(&mut c, 2, 1, 0, &belief());
        assert_eq!(
            c.on_slot(&truth(2, 1, 2)),
            Err(SlotError::StepGap {
                episode: 2,
                step: 2,
                expected: 1
            })
        );
        assert_eq!(c.stats.slots, 0);
        slot(&mut c, 2, 1, 1);
        assert_eq!(c.stats.slots, 1);
    }

    /// A leg can close (collision on its first step) before its handover is
    /// read: the late handover is stale, not an error.
    #[test]
    fn a_handover_of_a_closed_leg_is_ignored() {
        let mut c = core();
        c.on_threshold(&th(Threshold::OPEN, 3, 0, 1.0));
        c.on_threshold(&th(Threshold::CLOSE, 3, 0, 1.0));
        hand_over(&mut c, 3, 0, 0, &belief());
        assert_eq!(c.stats.handovers, 0);
        // A handover of a leg not yet opened waits for its OPEN.
        let (mean, cov) = belief_to_wire(&belief());
        let early = Handover {
            header: header(3, 1, 4),
            dim: 2,
            mean,
            cov,
            ..Handover::default()
        };
        assert!(matches!(
            c.on_handover(&early),
            Err(SlotError::LegNotOpen { .. })
        ));
    }

    #[test]
    fn messages_of_another_run_and_stop() {
        let mut c = core();
        let mut t = th(Threshold::OPEN, 0, 0, 0.0);
        t.header.run = TAG + 1;
        assert_eq!(c.on_threshold(&t), ControlAction::None);
        assert_eq!(
            c.on_threshold(&th(Threshold::STOP, 0, 0, 0.0)),
            ControlAction::Stop
        );
    }

    /// The replica's priors are the agent's: the slot digests equal those of
    /// the priors an agent computes independently with the filter's own
    /// functions (predict, innovation, explicit/implicit update) from the
    /// same slot outcomes.
    #[test]
    fn the_slot_digest_is_the_agents_prior() {
        let s = Scenario::builtin("open-2d").expect("built-in");
        let compiled = CompiledScenario::<2>::new(&s);
        let filter = EtKalmanFilter::<2, 2>::new(&s.plant, &s.sensors[0]);
        let mut c = core();
        c.on_threshold(&th(Threshold::OPEN, 0, 0, 1.0));
        let mut agent = belief();
        hand_over(&mut c, 0, 0, 0, &agent);
        let beta = etp_shared::gaussian::beta(1.0);
        let mut sent = 0;
        for k in 1..=10 {
            let d = slot(&mut c, 0, 0, k);
            let u = compiled.input(0, &agent.mean);
            let prior = filter.predict(&agent, &u);
            assert_eq!(d.prior_digest, belief_digest(&prior), "step {k}");
            let inn = filter.innovation(&prior);
            agent = match &d.transmit {
                Some((y, _)) => {
                    sent += 1;
                    filter.update_explicit(&prior, &inn, &Vector::<2>::new(y[0], y[1]))
                }
                None => filter.update_implicit(&prior, &inn, beta),
            };
        }
        assert!(sent > 0 && sent < 10, "{sent}");
    }

    #[test]
    fn the_measurement_noise_is_keyed_by_episode_and_step() {
        let mut a = core();
        let mut b = core();
        for c in [&mut a, &mut b] {
            c.on_threshold(&th(Threshold::OPEN, 5, 0, 0.0));
        }
        hand_over(&mut a, 5, 0, 0, &belief());
        hand_over(&mut b, 5, 0, 6, &belief());
        // The same (episode, step) measures the same y, whatever the leg's history.
        let ya: Vec<_> = (1..=12).map(|k| slot(&mut a, 5, 0, k).transmit).collect();
        let yb: Vec<_> = (7..=12).map(|k| slot(&mut b, 5, 0, k).transmit).collect();
        for (x, y) in ya[6..].iter().zip(&yb) {
            assert_eq!(x.map(|t| t.0), y.map(|t| t.0));
        }
    }
}
