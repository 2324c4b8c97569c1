//! What a sensor does with each message, as pure functions of its state: no
//! ports, no clock. [`crate::node`] is the thin iceoryx2 adapter around it
//! (receive, call, publish), so every decision here is unit-tested without
//! processes.
//!
//! The sensor knows the agent's estimate without a per-step downlink: at the
//! start of each leg it serves the agent hands its belief over (`handover`),
//! and from then on a [`LegReplica`] computes each prior with the agent's own
//! step functions from what the sensor itself did (transmitted y, or stayed
//! silent). The slot carries the replica prior's digest; the agent checks it.
//!
//! The radio (docs/MODEL.md §8) is simulated here, at its sender: when the
//! trigger fires, the fate of each attempt is drawn from the link's own
//! stream (`LinkChannel::of_episode` with stream `AGENT`, the channel of
//! the in-process simulation's episodes), retries follow a lost attempt
//! within the step, and only a delivered attempt is published to the agent.
//! The link is acknowledged: the agent ACKs each measurement it received,
//! and [`SensorCore::on_ack`] checks every ACK against a delivery made here.
//! A lost attempt's missing ACK is known at once (the ether is simulated
//! here; no timeout is waited for). The replica applies what the agent
//! applied: the measurement if delivered, else the silence update with the
//! radio's factor ([`CompiledScenario::silence_beta`]).

use etp_runtime::wire::agent_to_sensor::{Ack, Handover, Truth};
use etp_runtime::wire::coordinator_to_sensor::Threshold;
use etp_runtime::wire::{ThresholdKind, WireVec, belief_from_wire, to_wire_vec, vec_from_wire};
use etp_shared::episode::{
    CompiledScenario, LegReplica, RunSlot, SlotKey, SlotOutcome, belief_digest,
};
use etp_shared::etkf::{EtKalmanFilter, Vector};
use etp_shared::radio::LinkChannel;
use etp_shared::radio::schedule::ChannelSchedule;
use etp_shared::rng::streams;
use std::collections::VecDeque;

/// What the sensor spent on one leg.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LegLedger {
    pub episode: u64,
    pub leg: u32,
    pub slots: u32,
    /// Slots in which the trigger fired.
    pub triggers: u32,
    /// Attempts (each costs c_m) = delivered + lost.
    pub transmissions: u32,
    pub delivered: u32,
    pub lost: u32,
}

/// Totals of a sensor process (logged at exit).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SensorStats {
    pub slots: u64,
    pub transmissions: u64,
    pub delivered: u64,
    pub lost: u64,
    /// ACKs received (each matched a delivery).
    pub acks: u64,
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
/// when the trigger fired and an attempt was delivered.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlotDecision {
    pub episode: u64,
    pub leg: u32,
    pub step: u32,
    /// `Some((y, n))`: publish y, delivered by the n-th attempt of this
    /// episode.
    pub transmit: Option<(WireVec, u32)>,
    /// Attempts made in this slot (0: no trigger; each costs c_m).
    pub attempts: u32,
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
    /// A message about a leg the scenario does not have.
    #[error("message for episode {episode} leg {leg}, beyond the scenario's {legs} legs")]
    NoSuchLeg { episode: u64, leg: u32, legs: usize },
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
    /// An ACK of a measurement this sensor did not deliver (or out of order).
    #[error(
        "ack of episode {episode} step {step} (sequence {sequence}) matches no delivery; the next unacknowledged is {expected:?}"
    )]
    UnexpectedAck {
        episode: u64,
        step: u32,
        sequence: u32,
        expected: Option<(u64, u32, u32)>,
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

/// Which sensor of which run this is: its index, the run's seed (its noise
/// and its link's losses) and the run's tag (messages of other runs are
/// ignored).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorId {
    pub index: u32,
    pub seed: u64,
    pub tag: u64,
}

/// One sensor's state between messages.
pub struct SensorCore<const N: usize, const M: usize> {
    scenario: CompiledScenario<N>,
    filter: EtKalmanFilter<N, M>,
    cost: f64,
    id: SensorId,
    open: Option<OpenLeg<N>>,
    /// This sensor's radio channel in the episode it last transmitted in.
    channel: Option<(u64, LinkChannel)>,
    /// Changes of the channel during the run (`etp run --channel-schedule`).
    schedule: ChannelSchedule,
    /// Deliveries not acknowledged yet: (episode, step, sequence), in order.
    unacked: VecDeque<(u64, u32, u32)>,
    /// The latest (episode, leg) closed here: a handover of it or of an
    /// earlier leg is stale (a leg can close before its handover is read,
    /// e.g. when it ends by a collision on its first step).
    closed: Option<(u64, u32)>,
    /// (episode, transmissions in it) for the `sequence` field.
    episode_count: (u64, u32),
    pub stats: SensorStats,
}

impl<const N: usize, const M: usize> SensorCore<N, M> {
    /// Sensor `id.index` of `scenario` (its filter, the agent's controller
    /// and plant for the replica), cost per transmission `cost`.
    pub fn new(
        scenario: CompiledScenario<N>,
        filter: EtKalmanFilter<N, M>,
        cost: f64,
        id: SensorId,
    ) -> Self {
        Self {
            scenario,
            filter,
            cost,
            id,
            open: None,
            channel: None,
            schedule: ChannelSchedule::default(),
            unacked: VecDeque::new(),
            closed: None,
            episode_count: (u64::MAX, 0),
            stats: SensorStats::default(),
        }
    }

    /// The run's channel changes: from a change's episode on, this sensor's
    /// attempts meet its link (the scenario's channel stays the agent's
    /// model; docs/MODEL.md §8.8).
    pub fn with_schedule(mut self, schedule: ChannelSchedule) -> Self {
        self.schedule = schedule;
        self
    }

    /// A `threshold` message of this sensor's service.
    pub fn on_threshold(&mut self, t: &Threshold) -> ControlAction {
        if t.header.run != self.id.tag {
            return ControlAction::None;
        }
        match ThresholdKind::try_from(t.kind) {
            Ok(ThresholdKind::Stop) => ControlAction::Stop,
            Ok(ThresholdKind::Open) if t.sensor == self.id.index => {
                self.open = Some(OpenLeg {
                    delta: t.delta,
                    ledger: LegLedger {
                        episode: t.header.episode,
                        leg: t.header.leg,
                        ..LegLedger::default()
                    },
                    replica: None,
                });
                ControlAction::None
            }
            Ok(ThresholdKind::Close) if t.sensor == self.id.index => {
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
        if h.header.run != self.id.tag {
            return Ok(());
        }
        let (episode, leg) = (h.header.episode, h.header.leg);
        if self.is_closed(episode, leg) {
            return Ok(());
        }
        let delta = self.open_leg(episode, leg)?.delta;
        let legs = self.scenario.legs.len();
        if leg as usize >= legs {
            return Err(SlotError::NoSuchLeg { episode, leg, legs });
        }
        let belief = belief_from_wire::<N>(&h.mean, &h.cov);
        let replica =
            LegReplica::handed_over(&self.scenario, leg as usize, delta, belief, h.header.step);
        self.open_leg(episode, leg)?.replica = Some(replica);
        self.stats.handovers += 1;
        Ok(())
    }

    /// One slot, opened by the truth of step k: the replica's prior,
    /// y = H x + v (noise keyed by episode and step, so independent of
    /// timing), the whitened innovation and the family's decision (box:
    /// ‖ε‖∞ > δ, docs/MODEL.md §2, §9); then the replica's update with what
    /// was done.
    pub fn on_slot(&mut self, t: &Truth) -> Result<SlotDecision, SlotError> {
        let (episode, leg, step) = (t.header.episode, t.header.leg, t.header.step);
        let seed = self.id.seed;
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
        let slot_open = replica.open(scenario);
        let prior = *slot_open.prior();
        let x: Vector<N> = vec_from_wire(&t.x);
        // The slot (measure, decide with the scenario's trigger family, the
        // attempts' fate on this link: the ideal link draws nothing), as the
        // in-process leg loop serves it; noise and trigger draw keyed by
        // (seed, episode, step), so `replay verify` draws them again.
        let channel = &mut self.channel;
        let schedule = &self.schedule;
        let key = SlotKey {
            seed,
            episode,
            step,
            sensor: self.id.index,
        };
        let slot_in_leg = open.ledger.slots;
        let reference = replica.reference();
        let reference = reference.as_ref().map(|r| &r[..]);
        let slot = RunSlot {
            prior: &prior,
            x: &x,
            delta: open.delta,
            slot_in_leg,
            reference,
            key,
        };
        let served = scenario.serve_run_slot(&filter, slot, || {
            let channel = match channel {
                Some((e, c)) if *e == episode => c,
                slot => {
                    let sensor = self.id.index as usize;
                    let c = LinkChannel::of_link(
                        schedule.link(&scenario.radio, sensor, episode),
                        seed,
                        streams::AGENT,
                        episode,
                        sensor,
                    );
                    &mut slot.insert((episode, c)).1
                }
            };
            channel.advance_to(u64::from(step));
            channel.transmit()
        });
        let (y, fired, sent) = (served.y, served.fired, served.sending);
        // What the agent will receive: the wire copy of y (same bits).
        let y_wire = to_wire_vec(y.as_slice());
        let slot = if sent.delivered {
            SlotOutcome::Transmitted(&y_wire[..])
        } else {
            SlotOutcome::Silent
        };
        replica.close(scenario, slot_open, slot);
        let l = &mut open.ledger;
        l.slots += 1;
        l.triggers += u32::from(fired);
        l.transmissions += sent.attempts;
        l.delivered += u32::from(sent.delivered);
        l.lost += sent.lost();
        self.stats.slots += 1;
        self.stats.transmissions += u64::from(sent.attempts);
        self.stats.delivered += u64::from(sent.delivered);
        self.stats.lost += u64::from(sent.lost());
        if self.episode_count.0 != episode {
            self.episode_count = (episode, 0);
        }
        self.episode_count.1 += sent.attempts;
        let transmit = sent.delivered.then(|| {
            self.unacked
                .push_back((episode, step, self.episode_count.1));
            (y_wire, self.episode_count.1)
        });
        Ok(SlotDecision {
            episode,
            leg,
            step,
            transmit,
            attempts: sent.attempts,
            prior_digest: belief_digest(&prior),
        })
    }

    /// An ACK from the agent: it must acknowledge the oldest delivery not yet
    /// acknowledged (the agent ACKs in the order it received, which is the
    /// order this sensor delivered). Another run's ACK is ignored.
    pub fn on_ack(&mut self, a: &Ack) -> Result<(), SlotError> {
        if a.header.run != self.id.tag {
            return Ok(());
        }
        let got = (a.header.episode, a.header.step, a.sequence);
        match self.unacked.front() {
            Some(&d) if d == got => {
                self.unacked.pop_front();
                self.stats.acks += 1;
                Ok(())
            }
            other => Err(SlotError::UnexpectedAck {
                episode: got.0,
                step: got.1,
                sequence: got.2,
                expected: other.copied(),
            }),
        }
    }

    /// Deliveries not acknowledged (yet).
    pub fn unacknowledged(&self) -> usize {
        self.unacked.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::wire::{Header, belief_to_wire};
    use etp_shared::etkf::{Belief, Matrix};
    use etp_shared::rng::link_rng;
    use etp_shared::scenario::Scenario;

    const TAG: u64 = 7;
    const ID: SensorId = SensorId {
        index: 0,
        seed: 3,
        tag: TAG,
    };

    fn core() -> SensorCore<2, 2> {
        let s = Scenario::builtin("open-2d").expect("built-in");
        let f = EtKalmanFilter::<2, 2>::new(&s.plant, &s.sensors[0]);
        SensorCore::new(CompiledScenario::new(&s), f, 1.5, ID)
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

    /// A handover of a leg the scenario lacks is refused, not served.
    #[test]
    fn a_handover_beyond_the_scenarios_legs_is_refused() {
        let mut c = core();
        let legs = CompiledScenario::<2>::new(&Scenario::builtin("open-2d").expect("built-in"))
            .legs
            .len();
        let leg = legs as u32;
        c.on_threshold(&th(Threshold::OPEN, 1, leg, 1.0));
        let (mean, cov) = belief_to_wire(&belief());
        let h = Handover {
            header: header(1, leg, 0),
            dim: 2,
            mean,
            cov,
            ..Handover::default()
        };
        assert_eq!(
            c.on_handover(&h),
            Err(SlotError::NoSuchLeg {
                episode: 1,
                leg,
                legs
            })
        );
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

    /// The agent's step of leg 0 after slot decision `d`: its prior must be
    /// the one the sensor's replica triggered on (the digest); then the
    /// update with what reached the agent.
    fn agents_step(
        compiled: &CompiledScenario<2>,
        agent: &Belief<2>,
        d: &SlotDecision,
        beta: f64,
        k: u32,
    ) -> Belief<2> {
        let u = compiled.input(0, &agent.mean);
        let prior = compiled.prior(agent, &u);
        assert_eq!(d.prior_digest, belief_digest(&prior), "step {k}");
        let outcome = match &d.transmit {
            Some((y, _)) => SlotOutcome::Transmitted(&y[..]),
            None => SlotOutcome::Silent,
        };
        compiled.close_slot(0, &prior, outcome, beta)
    }

    /// The replica's priors are the agent's: the slot digests equal those of
    /// the priors `episode::step` computes from the same slot outcomes.
    #[test]
    fn the_slot_digest_is_the_agents_prior() {
        let s = Scenario::builtin("open-2d").expect("built-in");
        let compiled = CompiledScenario::<2>::new(&s);
        let mut c = core();
        c.on_threshold(&th(Threshold::OPEN, 0, 0, 1.0));
        let mut agent = belief();
        hand_over(&mut c, 0, 0, 0, &agent);
        let beta = compiled.silence_beta(0, 1.0);
        for k in 1..=10 {
            let d = slot(&mut c, 0, 0, k);
            agent = agents_step(&compiled, &agent, &d, beta, k);
        }
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

    /// open-2d with every link lossy (loss 0.5, one retry).
    fn lossy_core() -> (SensorCore<2, 2>, CompiledScenario<2>) {
        let s = Scenario::builtin("open-2d")
            .expect("built-in")
            .with_radio_override(&etp_shared::radio::RadioOverride {
                loss: Some(0.5),
                retries: Some(1),
                ..Default::default()
            })
            .expect("valid radio");
        let f = EtKalmanFilter::<2, 2>::new(&s.plant, &s.sensors[0]);
        let c = CompiledScenario::new(&s);
        (SensorCore::new(c.clone(), f, 1.5, ID), c)
    }

    /// docs/MODEL.md §8 at the sensor: each trigger's attempts are drawn
    /// from the link's own stream (the in-process simulation's channel of
    /// this episode and link), only a delivered attempt is published, the
    /// ledger counts attempts = delivered + lost, and the replica applies
    /// what the agent applies (a lost trigger is a silence with β_q).
    #[test]
    fn a_lossy_link_draws_each_attempt_from_its_own_stream_and_the_replica_follows_the_agent() {
        let (mut c, compiled) = lossy_core();
        let (episode, delta) = (6, 0.0);
        c.on_threshold(&th(Threshold::OPEN, episode, 0, delta));
        let mut agent = belief();
        hand_over(&mut c, episode, 0, 0, &agent);
        let mut reference = LinkChannel::new(
            compiled.radio.link(0),
            link_rng(3, streams::AGENT, episode, 0),
        );
        let beta = compiled.silence_beta(0, delta);
        assert_eq!(beta, 0.0, "at δ = 0 a silence is always a loss");
        let (mut delivered, mut lost, mut attempts) = (0, 0, 0);
        for k in 1..=60 {
            let d = slot(&mut c, episode, 0, k);
            reference.advance_to(u64::from(k));
            let t = reference.transmit();
            assert_eq!(
                (d.attempts, d.transmit.is_some()),
                (t.attempts, t.delivered),
                "step {k}"
            );
            attempts += t.attempts;
            delivered += u32::from(t.delivered);
            lost += t.lost();
            agent = agents_step(&compiled, &agent, &d, beta, k);
        }
        // q = 0.25 per trigger: both fates occur in 60 triggers.
        assert!(
            lost > 0 && delivered > 0,
            "{lost} lost, {delivered} delivered"
        );
        let ControlAction::Ledger { ledger, energy } =
            c.on_threshold(&th(Threshold::CLOSE, episode, 0, delta))
        else {
            panic!("no ledger")
        };
        assert_eq!(ledger.triggers, 60);
        assert_eq!(ledger.transmissions, attempts);
        assert_eq!(ledger.transmissions, ledger.delivered + ledger.lost);
        assert_eq!((ledger.delivered, ledger.lost), (delivered, lost));
        assert_eq!(energy, f64::from(attempts) * 1.5, "every attempt costs");
        assert_eq!(c.unacknowledged(), delivered as usize);
    }

    /// Every ACK must acknowledge the oldest unacknowledged delivery.
    #[test]
    fn acks_are_checked_against_the_deliveries() {
        let mut c = core();
        c.on_threshold(&th(Threshold::OPEN, 2, 0, 0.0));
        hand_over(&mut c, 2, 0, 0, &belief());
        let seq: Vec<u32> = (1..=2)
            .map(|k| slot(&mut c, 2, 0, k).transmit.expect("δ = 0 delivers").1)
            .collect();
        let ack = |step: u32, sequence: u32| Ack {
            header: header(2, 0, step),
            sequence,
            _pad: 0,
        };
        let mut other_run = ack(1, seq[0]);
        other_run.header.run = TAG + 1;
        assert_eq!(c.on_ack(&other_run), Ok(()));
        assert!(matches!(
            c.on_ack(&ack(2, seq[1])),
            Err(SlotError::UnexpectedAck {
                expected: Some((2, 1, _)),
                ..
            })
        ));
        assert_eq!(c.on_ack(&ack(1, seq[0])), Ok(()));
        assert_eq!(c.on_ack(&ack(2, seq[1])), Ok(()));
        assert!(c.on_ack(&ack(2, seq[1])).is_err(), "acknowledged twice");
        assert_eq!((c.stats.acks, c.unacknowledged()), (2, 0));
    }
}
