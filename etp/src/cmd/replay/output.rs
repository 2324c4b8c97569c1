//! What `etp replay` writes to stdout: through [`emit`] (a closed pipe ends
//! the output quietly), and the text of `verify`.

use anyhow::{Context, Result};
use etp_runtime::recording;

/// Write `text` to stdout. A closed pipe (`etp replay F | head -1`) ends the
/// output quietly; another write error is reported, never a panic.
pub(super) fn emit(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e).context("writing to stdout"),
        _ => Ok(()),
    }
}

pub(super) fn render_verify(v: &recording::VerifyReport) -> String {
    let mut t = String::new();
    // Writing into a String cannot fail.
    let _ = write_verify(&mut t, v);
    t
}

fn write_verify(out: &mut String, v: &recording::VerifyReport) -> std::fmt::Result {
    use std::fmt::Write;
    writeln!(
        out,
        "verify: {} · {} decision-point beliefs and {} handovers reproduced bit for bit; \
         the sensors' replicas triggered on the agent's prior in all {} slots checked",
        if v.passed() { "PASSED" } else { "FAILED" },
        v.waypoints_checked,
        v.handovers_checked,
        v.priors_checked
    )?;
    writeln!(
        out,
        "  {} episodes re-run ({} steps: {} with a measurement, {} silent, {} ended by a \
         collision before its slot); {} incomplete (end of file), {} degraded skipped",
        v.episodes_checked,
        v.steps + v.collision_steps,
        v.explicit_updates,
        v.implicit_updates,
        v.collision_steps,
        v.episodes_incomplete,
        v.episodes_degraded_skipped
    )?;
    writeln!(
        out,
        "  radio: {} transmission attempts re-drawn from the links' streams as recorded ({} lost)",
        v.attempts_redrawn, v.lost_redrawn
    )?;
    writeln!(
        out,
        "  sensor decisions: {} re-drawn from the recorded true states as recorded",
        v.decisions_checked
    )?;
    if let Some(n) = v.drift_flags_reproduced {
        writeln!(
            out,
            "  channel monitor: {n} drift flag(s) raised again from the recorded slots, bit for bit"
        )?;
    }
    for m in &v.mismatches {
        writeln!(
            out,
            "  MISMATCH episode {} leg {} step {}: {} (max |diff| {:e})",
            m.episode, m.leg, m.step, m.what, m.max_abs_diff
        )?;
    }
    if v.mismatch_count > v.mismatches.len() as u64 {
        writeln!(out, "  … {} mismatches in all", v.mismatch_count)?;
    }
    Ok(())
}
