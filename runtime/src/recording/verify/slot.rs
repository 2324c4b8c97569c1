//! The checks of one slot of a recorded episode against its re-run: who
//! sent, the sensor replica's prior (by digest), delivered against the
//! recorded measurement, the radio's attempts drawn again, and the sensor's
//! decision and measurement drawn again from the recorded true state.

use super::{EpisodeRecord, Mismatch, VerifyReport};
use crate::wire::sensor_to_agent::Measurement;
use crate::wire::vec_from_wire;
use etp_shared::episode::{CompiledScenario, RunSlot, SlotKey, belief_digest};
use etp_shared::etkf::{Belief, Vector};
use etp_shared::radio::LinkChannel;
use etp_shared::radio::schedule::ChannelSchedule;
use etp_shared::rng::streams;
use std::collections::BTreeMap;

/// Where the slot is and what the re-run holds there.
pub(super) struct SlotAt<'a, const N: usize> {
    pub episode: u64,
    pub leg: u32,
    /// The step (the slot's number in the episode).
    pub k: u32,
    /// The leg's serving sensor and threshold.
    pub sensor: usize,
    pub delta: f64,
    /// The slot's number in its leg (the periodic family decides on it).
    pub slot_in_leg: u32,
    /// The re-run's prior at this slot.
    pub prior: &'a Belief<N>,
    /// The leg's reference (send-on-delta's last delivered y).
    pub reference: Option<[f64; 6]>,
}

/// Why the checks of a slot stop the episode's re-run: a mismatch, or a
/// message missing from the record (the episode cut, where the file may
/// be cut there, else a mismatch).
pub(super) enum Stop {
    Mismatch(Mismatch),
    Missing(&'static str),
}

/// What the record holds at a slot that passed its checks.
pub(super) struct Checked<'r> {
    pub measurement: Option<&'r Measurement>,
}

/// Each sensor link's channel in one episode, made at its first attempt:
/// the run's, or its scheduled change (the recording's
/// `etp.channel_schedule`).
pub(super) struct Channels<'s> {
    pub schedule: &'s ChannelSchedule,
    pub made: BTreeMap<usize, LinkChannel>,
}

impl<'s> Channels<'s> {
    pub fn new(schedule: &'s ChannelSchedule) -> Self {
        Self {
            schedule,
            made: BTreeMap::new(),
        }
    }
}

/// The checks of `at` against the record `r`, in the agent's order; each
/// check that holds is counted in `rep`, and the slot once all hold (its
/// attempts, losses, step and kind of update). `channels`: each sensor link's
/// channel in this episode, made at its first attempt.
pub(super) fn check<'r, const N: usize>(
    c: &CompiledScenario<N>,
    r: &'r EpisodeRecord,
    at: &SlotAt<'_, N>,
    channels: &mut Channels<'_>,
    rep: &mut VerifyReport,
) -> Result<Checked<'r>, Stop> {
    let (leg, k, sensor) = (at.leg, at.k, at.sensor);
    let miss = |what: String, d: f64| {
        Stop::Mismatch(Mismatch {
            episode: at.episode,
            leg,
            step: k,
            what,
            max_abs_diff: d,
        })
    };
    let y = r.measurements.get(&k);
    if let Some(m) = y
        && m.header.sender as usize != sensor
    {
        return Err(miss(
            format!(
                "measurement from sensor {}, the leg is served by {sensor}",
                m.header.sender
            ),
            0.0,
        ));
    }
    let Some(slot) = r.slots.get(&k) else {
        return Err(Stop::Missing("slot not closed in the record"));
    };
    if slot.prior_digest != belief_digest(at.prior) {
        return Err(miss(
            "the sensor's replica triggered on another prior (slot.prior_digest)".into(),
            0.0,
        ));
    }
    rep.priors_checked += 1;
    if slot.delivered == 1 && y.is_none() {
        return Err(Stop::Missing(
            "slot says delivered but no measurement is recorded",
        ));
    }
    if slot.delivered != 1 && y.is_some() {
        return Err(miss(
            format!(
                "slot says delivered = {} but a measurement is recorded",
                slot.delivered
            ),
            0.0,
        ));
    }
    // The radio's draw of this slot's attempts, again.
    let redrawn = if slot.attempts == 0 {
        (0, false)
    } else {
        let Some(ctrl) = &r.control else {
            return Err(Stop::Missing(
                "no control recorded (the run's seed, for the radio)",
            ));
        };
        let schedule = channels.schedule;
        let channel = channels.made.entry(sensor).or_insert_with(|| {
            LinkChannel::of_link(
                schedule.link(&c.radio, sensor, at.episode),
                ctrl.seed,
                streams::AGENT,
                at.episode,
                sensor,
            )
        });
        channel.advance_to(u64::from(k));
        let t = channel.transmit();
        (t.attempts, t.delivered)
    };
    if redrawn != (slot.attempts, slot.delivered == 1) {
        return Err(miss(
            format!(
                "the radio re-drawn gives {} attempt(s), delivered {}; the slot records {}, delivered {}",
                redrawn.0, redrawn.1, slot.attempts, slot.delivered
            ),
            0.0,
        ));
    }
    // The sensor's decision, again from the recorded true state.
    if let (Some(t), Some(ctrl)) = (r.truths.get(&k), &r.control) {
        let x: Vector<N> = vec_from_wire(&t.x);
        let key = SlotKey {
            seed: ctrl.seed,
            episode: at.episode,
            step: k,
            sensor: sensor as u32,
        };
        let run_slot = RunSlot {
            prior: at.prior,
            x: &x,
            delta: at.delta,
            slot_in_leg: at.slot_in_leg,
            reference: at.reference.as_ref().map(|r| &r[..]),
            key,
        };
        let (sent, y_again) = c.redecide_slot(leg as usize, run_slot);
        if sent != (slot.attempts > 0) {
            return Err(miss(
                format!(
                    "the sensor's decision re-drawn ({} trigger) {}; the slot records {} attempt(s)",
                    c.trigger,
                    if sent { "sends" } else { "stays silent" },
                    slot.attempts
                ),
                0.0,
            ));
        }
        if let Some(m) = y {
            let worst = y_again
                .iter()
                .zip(m.y.iter())
                .filter(|(a, b)| a.to_bits() != b.to_bits())
                .map(|(a, b)| (a - b).abs())
                .reduce(f64::max);
            if let Some(d) = worst {
                return Err(miss(
                    "the measurement re-drawn from the recorded true state".into(),
                    d,
                ));
            }
        }
        rep.decisions_checked += 1;
    }
    rep.attempts_redrawn += u64::from(slot.attempts);
    rep.lost_redrawn += u64::from(slot.attempts - u32::from(redrawn.1));
    // A step counts once its slot is re-run: the step a collision ends has
    // no slot (nor has one cut by the end of the file), so steps =
    // measurements + silent slots.
    rep.steps += 1;
    match y {
        Some(_) => rep.explicit_updates += 1,
        None => rep.implicit_updates += 1,
    }
    Ok(Checked { measurement: y })
}
