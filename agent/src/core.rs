//! The agent's decisions in an episode, as pure functions of its state: no
//! ports, no clock. The step itself is the shared `episode::AgentCore`;
//! what the agent adds around it lives here and is unit-tested without
//! processes: whether a leg's OPEN names the scenario's sensor, what a
//! closed or dead slot means for the update (the prior digest must match;
//! a dead link predicts only and degrades the episode), and the episode's
//! bookkeeping (the waypoint's counts of the previous leg, the outcome).
//! [`crate::runtime`] is the thin iceoryx2 adapter around it.

use crate::AgentError;
use crate::link::{Fault, SlotResult};
use etp_runtime::wire::agent_to_coordinator::{Outcome, Waypoint};
use etp_runtime::wire::{Header, OutcomeCode, WireVec, belief_to_wire};
use etp_shared::episode::{CompiledScenario, LegResult, SlotOutcome, belief_digest};
use etp_shared::etkf::{Belief, Vector};

/// Counts of one leg as the coordinator learns them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LegCounts {
    pub steps: u32,
    pub received: u32,
    pub degraded: bool,
}

/// The agent's bookkeeping of one episode.
#[derive(Debug, Clone, Copy)]
pub struct EpisodeBook {
    /// The totals so far (the `outcome` message in the making).
    totals: Outcome,
    /// The leg before the current one (reported with the next waypoint).
    prev: LegCounts,
    /// A dead link in the current leg.
    leg_degraded: bool,
}

impl Default for EpisodeBook {
    fn default() -> Self {
        Self::new()
    }
}

impl EpisodeBook {
    pub fn new() -> Self {
        Self {
            totals: Outcome {
                dead_sensor: u32::MAX,
                ..Outcome::default()
            },
            prev: LegCounts::default(),
            leg_degraded: false,
        }
    }

    /// The `waypoint` of the decision point with `header`: the belief there
    /// and the counts of the previous leg.
    pub fn waypoint<const N: usize>(&self, header: Header, belief: &Belief<N>) -> Waypoint {
        let (mean, cov) = belief_to_wire(belief);
        Waypoint {
            header,
            dim: N as u32,
            prev_steps: self.prev.steps,
            prev_received: self.prev.received,
            prev_degraded: u32::from(self.prev.degraded),
            mean,
            cov,
        }
    }

    /// The coordinator opened leg `leg` at `sensor`: it must be the leg's
    /// sensor in the scenario.
    pub fn check_open<const N: usize>(
        c: &CompiledScenario<N>,
        leg: usize,
        sensor: usize,
    ) -> Result<(), AgentError> {
        match c.legs.get(leg) {
            Some(l) if l.sensor == sensor => Ok(()),
            Some(l) => Err(AgentError::Protocol(format!(
                "coordinator opened leg {leg} at sensor {sensor}, the scenario says {}",
                l.sensor
            ))),
            None => Err(AgentError::Protocol(format!(
                "coordinator opened leg {leg}, the scenario has {}",
                c.legs.len()
            ))),
        }
    }

    /// What slot `step` of `episode` at `sensor` means for the update.
    /// A closed slot: the sensor triggered on its replica's prior, which
    /// must be the agent's `prior` bit for bit (docs/MODEL.md §3.2); a
    /// transmitted measurement is delivered, none is silence. A dead link
    /// (`fault` the first time) degrades the episode: prediction only, or the
    /// explicit update with a measurement that arrived before the verdict.
    pub fn on_slot<const N: usize>(
        &mut self,
        (episode, step, sensor): (u64, u32, usize),
        prior: &Belief<N>,
        result: SlotResult,
        fault: Option<Fault>,
    ) -> Result<SlotOutcome<WireVec>, AgentError> {
        if let Some(f) = fault
            && self.totals.dead_sensor == u32::MAX
        {
            let o = &mut self.totals;
            o.dead_sensor = f.sensor;
            o.detect_us = f.detect_us;
            o.wait_started_unix_ns = f.wait_started_unix_ns;
            o.detected_unix_ns = f.detected_unix_ns;
        }
        let y = match result {
            SlotResult::Closed(y, digest) => {
                let ours = belief_digest(prior);
                if digest != ours {
                    return Err(AgentError::Protocol(format!(
                        "sensor {sensor}'s replica diverged at episode {episode} step {step}: \
                         prior digest {digest:#018x}, the agent's {ours:#018x}"
                    )));
                }
                return Ok(y.map_or(SlotOutcome::Silent, SlotOutcome::Delivered));
            }
            SlotResult::Dead(y) => y,
        };
        self.leg_degraded = true;
        self.totals.degraded = 1;
        self.totals.dead_slots += 1;
        Ok(y.map_or(SlotOutcome::Dead, SlotOutcome::Delivered))
    }

    /// A leg that did not end the episode ended with `counts`.
    pub fn end_leg(&mut self, counts: &LegResult) {
        self.prev = self.add(counts);
        self.leg_degraded = false;
    }

    fn add(&mut self, counts: &LegResult) -> LegCounts {
        let o = &mut self.totals;
        o.steps += counts.steps;
        o.slots += counts.slots;
        o.received += counts.transmissions;
        LegCounts {
            steps: counts.steps,
            received: counts.transmissions,
            degraded: self.leg_degraded,
        }
    }

    /// The episode ended in `outcome` during a leg with `counts`: the
    /// `outcome` message (its header is the adapter's).
    pub fn finish(mut self, header: Header, counts: &LegResult, outcome: OutcomeCode) -> Outcome {
        let last = self.add(counts);
        Outcome {
            header,
            outcome: outcome.code(),
            last_steps: last.steps,
            last_received: last.received,
            ..self.totals
        }
    }
}

/// The episode's end code after its last leg: target if `x` is in the target box.
pub fn end_code<const N: usize>(c: &CompiledScenario<N>, x: &Vector<N>) -> OutcomeCode {
    match c.classify_end(x) {
        etp_shared::episode::Outcome::Target => OutcomeCode::Target,
        _ => OutcomeCode::Free,
    }
}

/// A wire measurement as the filter's y (its first M entries, same bits).
pub fn measurement<const M: usize>(y: &WireVec) -> Vector<M> {
    Vector::<M>::from_fn(|i, _| y[i])
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_shared::episode::LegEnd;
    use etp_shared::scenario::Scenario;

    fn compiled() -> CompiledScenario<2> {
        CompiledScenario::new(&Scenario::builtin("winding-2d").expect("built-in"))
    }

    fn counts(steps: u32, slots: u32, transmissions: u32) -> LegResult {
        LegResult {
            end: LegEnd::Terminated,
            steps,
            slots,
            transmissions,
            kf_slots: 0,
            expected_transmissions: 0.0,
        }
    }

    const AT: (u64, u32, usize) = (4, 9, 1);

    #[test]
    fn a_closed_slot_must_carry_the_agents_prior_digest() {
        let c = compiled();
        let prior = c.initial;
        let mut book = EpisodeBook::new();
        let d = belief_digest(&prior);
        let y = [1.0, 2.0, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(
            book.on_slot(AT, &prior, SlotResult::Closed(Some(y), d), None)
                .expect("same digest"),
            SlotOutcome::Delivered(y)
        );
        assert_eq!(
            book.on_slot(AT, &prior, SlotResult::Closed(None, d), None)
                .expect("same digest"),
            SlotOutcome::Silent
        );
        let err = book
            .on_slot(AT, &prior, SlotResult::Closed(None, d ^ 1), None)
            .expect_err("another digest");
        assert!(
            err.to_string().contains("diverged at episode 4 step 9"),
            "{err}"
        );
        let o = book.finish(Header::default(), &counts(2, 2, 1), OutcomeCode::Free);
        assert_eq!((o.degraded, o.dead_slots, o.dead_sensor), (0, 0, u32::MAX));
    }

    #[test]
    fn a_dead_link_predicts_only_and_degrades_the_episode() {
        let c = compiled();
        let prior = c.initial;
        let mut book = EpisodeBook::new();
        let fault = Fault {
            sensor: 1,
            detect_us: 1500,
            wait_started_unix_ns: 10,
            detected_unix_ns: 20,
        };
        // Never the implicit update on a dead link, whatever the digest.
        assert_eq!(
            book.on_slot(AT, &prior, SlotResult::Dead(None), Some(fault))
                .expect("dead"),
            SlotOutcome::Dead
        );
        // A measurement that arrived before the verdict is still used.
        let y = [3.0; 6];
        assert_eq!(
            book.on_slot(AT, &prior, SlotResult::Dead(Some(y)), None)
                .expect("dead"),
            SlotOutcome::Delivered(y)
        );
        book.end_leg(&counts(5, 5, 2));
        let wp = book.waypoint(Header::default(), &prior);
        assert_eq!(
            (wp.prev_steps, wp.prev_received, wp.prev_degraded),
            (5, 2, 1)
        );
        let o = book.finish(Header::default(), &counts(3, 2, 1), OutcomeCode::Collision);
        assert_eq!(o.outcome, OutcomeCode::Collision.code());
        assert_eq!((o.degraded, o.dead_slots, o.dead_sensor), (1, 2, 1));
        assert_eq!((o.detect_us, o.detected_unix_ns), (1500, 20));
        assert_eq!((o.steps, o.slots, o.received), (8, 7, 3));
        assert_eq!((o.last_steps, o.last_received), (3, 1));
    }

    #[test]
    fn the_open_must_name_the_legs_sensor() {
        let c = compiled();
        let s = c.legs[1].sensor;
        EpisodeBook::check_open(&c, 1, s).expect("the scenario's sensor");
        assert!(EpisodeBook::check_open(&c, 1, s + 1).is_err());
        assert!(EpisodeBook::check_open(&c, c.legs.len(), s).is_err());
    }

    #[test]
    fn the_first_waypoint_reports_no_previous_leg() {
        let c = compiled();
        let wp = EpisodeBook::new().waypoint(Header::default(), &c.initial);
        assert_eq!((wp.dim, wp.prev_steps, wp.prev_degraded), (2, 0, 0));
        assert_eq!(wp.mean[..2], c.initial.mean.as_slice()[..]);
    }
}
