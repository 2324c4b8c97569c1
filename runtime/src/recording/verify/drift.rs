//! `replay verify`'s check of the channel monitor (docs/MODEL.md §11): the
//! agent's `etp_shared::drift::Monitor` fed again, from the recording, with
//! every recorded slot in the order the agent closed them (episode, step),
//! at its leg's opened δ, must raise exactly the recorded `drift` flags,
//! every field bit for bit. The slots themselves are checked against the
//! radio's and the trigger's re-draws by the re-run (`super::slot`), so
//! the flags follow from the run's seed.

use super::{EpisodeRecord, Mismatch, VerifyReport};
use crate::wire::agent_to_coordinator::Drift;
use etp_shared::drift::{Flag, Monitor, MonitorConfig};
use etp_shared::radio::Transmission;
use etp_shared::scenario::Scenario;
use std::collections::BTreeMap;

/// The flag as the agent published it (the header's episode and step
/// compared, the rest of it aside).
fn same(f: &Flag, d: &Drift) -> bool {
    let mut header = d.header;
    (header.episode, header.step) = (f.episode, f.step);
    Drift::of_flag(header, f).same_flag(d)
}

/// Feed the monitor every recorded slot of the episodes before `upto` (a
/// cut file's horizon: later episodes may miss slots) and compare its
/// flags with the recorded ones, episode by episode.
pub(super) fn check(
    scenario: &Scenario,
    config: MonitorConfig,
    episodes: &BTreeMap<u64, EpisodeRecord>,
    upto: Option<u64>,
    rep: &mut VerifyReport,
) {
    let mut monitor = Monitor::new(scenario, config);
    let mut reproduced = 0u64;
    for (&e, r) in episodes.range(..upto.unwrap_or(u64::MAX)) {
        monitor.start_episode(e);
        let mut flags = Vec::new();
        for (&step, slot) in &r.slots {
            let leg = slot.header.leg;
            let (Some(l), Some(&delta)) = (scenario.legs.get(leg as usize), r.opens.get(&leg))
            else {
                continue;
            };
            let t = Transmission {
                attempts: slot.attempts,
                delivered: slot.delivered == 1,
            };
            flags.extend(monitor.observe(l.sensor, step, delta, t));
        }
        let miss = |step: u32, what: String| Mismatch {
            episode: e,
            leg: 0,
            step,
            what,
            max_abs_diff: 0.0,
        };
        for i in 0..flags.len().max(r.drift.len()) {
            match (flags.get(i), r.drift.get(i)) {
                (Some(f), Some(d)) if same(f, d) => reproduced += 1,
                (Some(f), Some(d)) => rep.mismatch(miss(
                    d.header.step,
                    format!(
                        "drift flag {i}: recorded {} {} at step {} (statistic {}), re-run {} {} at step {} (statistic {})",
                        d.sensor, d.quantity, d.header.step, d.statistic,
                        f.sensor, f.quantity.code(), f.step, f.statistic
                    ),
                )),
                (Some(f), None) => rep.mismatch(miss(
                    f.step,
                    format!("the re-run flags sensor {} {} here; nothing recorded", f.sensor, f.quantity.name()),
                )),
                (None, Some(d)) => rep.mismatch(miss(
                    d.header.step,
                    format!("a drift flag (sensor {}, quantity {}) is recorded; the re-run raises none", d.sensor, d.quantity),
                )),
                (None, None) => {}
            }
        }
    }
    rep.drift_flags_reproduced = Some(reproduced);
}
