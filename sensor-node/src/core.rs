//! What a sensor does with each message, as pure functions of its state: no
//! ports, no clock. [`crate::node`] is the thin iceoryx2 adapter around it
//! (receive, call, publish), so every decision here is unit-tested without
//! processes.

use etp_runtime::wire::agent_to_sensor::{Prior, Truth};
use etp_runtime::wire::coordinator_to_all::Threshold;
use etp_runtime::wire::{ThresholdKind, WireVec, belief_from_wire, to_wire_vec, vec_from_wire};
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
}

/// Why a slot cannot be served.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SlotError {
    /// The prior's leg is not (yet) open here. The adapter drains `threshold`
    /// once more before calling it a protocol error: the OPEN is published
    /// before the agent can send the leg's first prior, but both may arrive
    /// in one wake-up.
    #[error("prior for episode {episode} leg {leg} but the open leg is {open:?}")]
    LegNotOpen {
        episode: u64,
        leg: u32,
        open: Option<(u64, u32)>,
    },
    #[error("prior of episode {episode} step {step} without its truth")]
    NoTruth { episode: u64, step: u32 },
}

/// The open leg: its threshold and its ledger so far.
#[derive(Debug, Clone, Copy)]
struct OpenLeg {
    delta: f64,
    ledger: LegLedger,
}

/// One sensor's state between messages.
pub struct SensorCore<const N: usize, const M: usize> {
    filter: EtKalmanFilter<N, M>,
    cost: f64,
    index: u32,
    seed: u64,
    tag: u64,
    open: Option<OpenLeg>,
    /// (episode, transmissions in it) for the `sequence` field.
    episode_count: (u64, u32),
    pub stats: SensorStats,
}

impl<const N: usize, const M: usize> SensorCore<N, M> {
    /// Sensor `index` with `filter`, cost per transmission `cost`, run seed
    /// and run tag (messages of other runs are ignored).
    pub fn new(filter: EtKalmanFilter<N, M>, cost: f64, index: u32, seed: u64, tag: u64) -> Self {
        Self {
            filter,
            cost,
            index,
            seed,
            tag,
            open: None,
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
                });
                ControlAction::None
            }
            Ok(ThresholdKind::Close) if t.sensor == self.index => {
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

    /// One slot: the agent's prior and the truth of the same step. Measures
    /// y = H x + v (noise keyed by episode and step, so independent of
    /// timing), whitens the innovation against the prior and triggers on
    /// ‖ε‖∞ > δ (docs/MODEL.md §2).
    pub fn on_slot(&mut self, p: &Prior, truth: Option<&Truth>) -> Result<SlotDecision, SlotError> {
        let (episode, leg, step) = (p.header.episode, p.header.leg, p.header.step);
        let Some(t) = truth.filter(|t| t.header.episode == episode && t.header.step == step) else {
            return Err(SlotError::NoTruth { episode, step });
        };
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
        let mut rng = stream_rng(
            self.seed,
            streams::SENSOR,
            (episode << 32) | u64::from(step),
        );
        let x: Vector<N> = vec_from_wire(&t.x);
        let y = self.filter.sensor.measure(&x, &mut rng);
        let prior = belief_from_wire::<N>(&p.mean, &p.cov);
        let transmit = self.filter.innovation(&prior).triggers(&y, open.delta);
        open.ledger.slots += 1;
        self.stats.slots += 1;
        if self.episode_count.0 != episode {
            self.episode_count = (episode, 0);
        }
        let transmit = transmit.then(|| {
            open.ledger.transmissions += 1;
            self.stats.transmissions += 1;
            self.episode_count.1 += 1;
            (to_wire_vec(y.as_slice()), self.episode_count.1)
        });
        Ok(SlotDecision {
            episode,
            leg,
            step,
            transmit,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::wire::{Header, belief_to_wire};
    use etp_shared::scenario::Scenario;

    const TAG: u64 = 7;

    fn core() -> SensorCore<2, 2> {
        let s = Scenario::builtin("open-2d").expect("built-in");
        let f = EtKalmanFilter::<2, 2>::new(&s.plant, &s.sensors[0]);
        SensorCore::new(f, 1.5, 0, 3, TAG)
    }

    fn th(kind: u32, episode: u64, leg: u32, delta: f64) -> Threshold {
        Threshold {
            header: Header {
                run: TAG,
                episode,
                leg,
                ..Header::default()
            },
            kind,
            sensor: 0,
            delta,
            ..Threshold::default()
        }
    }

    fn slot(c: &mut SensorCore<2, 2>, episode: u64, leg: u32, step: u32) -> SlotDecision {
        let h = Header {
            run: TAG,
            episode,
            leg,
            step,
            ..Header::default()
        };
        let b = etp_shared::etkf::Belief::<2> {
            mean: Vector::<2>::new(0.0, 0.0),
            cov: etp_shared::etkf::Matrix::<2, 2>::identity() * 0.01,
        };
        let (mean, cov) = belief_to_wire(&b);
        let p = Prior {
            header: h,
            dim: 2,
            mean,
            cov,
            ..Prior::default()
        };
        let t = Truth {
            header: h,
            dim: 2,
            x: to_wire_vec(&[0.5, 0.0]),
            ..Truth::default()
        };
        c.on_slot(&p, Some(&t)).expect("slot")
    }

    #[test]
    fn a_closed_leg_yields_its_ledger_priced_at_the_cost() {
        let mut c = core();
        assert_eq!(
            c.on_threshold(&th(Threshold::OPEN, 4, 1, 0.0)),
            ControlAction::None
        );
        // δ = 0 transmits every slot; the truth is far from the prior.
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
        assert_eq!(slot(&mut c, 4, 3, 9).transmit.map(|t| t.1), Some(4));
    }

    #[test]
    fn a_huge_threshold_is_silent_and_costs_nothing() {
        let mut c = core();
        c.on_threshold(&th(Threshold::OPEN, 0, 0, 1e9));
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
        let a = c.on_threshold(&th(Threshold::CLOSE, 1, 0, 0.0));
        assert!(
            matches!(a, ControlAction::Ledger { ledger, .. } if ledger.leg == 0 && ledger.slots == 0)
        );
        // Leg 2 is still open.
        assert_eq!(slot(&mut c, 1, 2, 5).leg, 2);
    }

    #[test]
    fn a_prior_of_an_unopened_leg_is_reported_not_served() {
        let mut c = core();
        let h = Header {
            run: TAG,
            episode: 2,
            leg: 1,
            step: 1,
            ..Header::default()
        };
        let p = Prior {
            header: h,
            ..Prior::default()
        };
        let t = Truth {
            header: h,
            ..Truth::default()
        };
        assert_eq!(
            c.on_slot(&p, Some(&t)),
            Err(SlotError::LegNotOpen {
                episode: 2,
                leg: 1,
                open: None
            })
        );
        assert_eq!(
            c.on_slot(&p, None),
            Err(SlotError::NoTruth {
                episode: 2,
                step: 1
            })
        );
        assert_eq!(c.stats.slots, 0);
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

    #[test]
    fn the_decision_is_keyed_by_episode_and_step_not_by_call_order() {
        let mut a = core();
        let mut b = core();
        a.on_threshold(&th(Threshold::OPEN, 5, 0, 1.0));
        b.on_threshold(&th(Threshold::OPEN, 5, 0, 1.0));
        let da: Vec<_> = (1..=20).map(|k| slot(&mut a, 5, 0, k)).collect();
        let db: Vec<_> = (1..=20).rev().map(|k| slot(&mut b, 5, 0, k)).collect();
        for (x, y) in da.iter().zip(db.iter().rev()) {
            assert_eq!(x.transmit.map(|t| t.0), y.transmit.map(|t| t.0));
        }
    }
}
