//! The summary of a recording as the table `etp replay summary` prints.

use etp_runtime::recording::Contents;
use serde_json::Value;
use std::path::Path;

/// The summary `s` of the recording `c` read from `file`, as a table.
pub fn render(file: &Path, c: &Contents, s: &Value) -> String {
    let mut t = String::new();
    // Writing into a String cannot fail.
    let _ = write_table(&mut t, file, c, s);
    t
}

fn write_table(out: &mut String, file: &Path, c: &Contents, s: &Value) -> std::fmt::Result {
    use std::fmt::Write;
    let g = |k: &str| match s.get(k) {
        Some(Value::String(t)) => t.clone(),
        Some(Value::Null) | None => "unknown".into(),
        Some(v) => v.to_string(),
    };
    writeln!(
        out,
        "recording {} · run {} · scenario {} · seed {} · {}",
        file.display(),
        g("run_id"),
        g("scenario"),
        g("seed"),
        g("software_version")
    )?;
    if let Some(t) = &c.truncated {
        writeln!(
            out,
            "  UNFINISHED file: read every complete record; stopped at: {t}"
        )?;
    }
    writeln!(
        out,
        "  {} episodes (requested {}): target {} · collision {} · free {} · {} steps",
        g("episodes"),
        g("requested_episodes"),
        g("target"),
        g("collision"),
        g("free"),
        g("steps")
    )?;
    if let Some(p) = s
        .get("partial")
        .filter(|p| p["episodes"].as_array().is_some_and(|a| !a.is_empty()))
    {
        writeln!(
            out,
            "  partial (not counted): episodes {} · {} messages · {} measurement messages",
            p["episodes"], p["messages"], p["measurements"]
        )?;
    }
    if let Some(flags) = s
        .get("drift")
        .and_then(|d| {
            serde_json::from_value::<Vec<etp_runtime::report::DriftRecord>>(d.clone()).ok()
        })
        .filter(|f| !f.is_empty())
    {
        writeln!(
            out,
            "  channel monitor: DRIFT flagged {} time(s)",
            flags.len()
        )?;
        for f in &flags {
            writeln!(out, "    {}", f.describe())?;
        }
    }
    writeln!(
        out,
        "  transmissions: {} attempts in ledgers = {} delivered + {} lost · {} measurement messages · {} received by the agent",
        g("transmissions"),
        g("delivered"),
        g("lost"),
        g("measurements"),
        g("received")
    )?;
    let h = |k: &str| {
        s.get(k)
            .and_then(Value::as_f64)
            .map_or("–".into(), crate::vocab::human)
    };
    writeln!(
        out,
        "  energy {} (predicted {})",
        h("energy"),
        h("predicted_energy")
    )?;
    if let Some(missing) = s
        .get("missing_channels")
        .and_then(Value::as_array)
        .filter(|m| !m.is_empty())
    {
        let names: Vec<&str> = missing.iter().filter_map(Value::as_str).collect();
        writeln!(
            out,
            "  MISSING channels: {} (a filtered or partial copy): what needs them is not counted (–) and not checked",
            names.join(", ")
        )?;
    }
    if let Some(v) = s.get("prediction_check")
        && s.get("episodes")
            .and_then(Value::as_u64)
            .is_none_or(|n| n > 0)
    {
        write!(out, "{}", crate::vocab::prediction_check_text(v))?;
    }
    writeln!(
        out,
        "  {:<10} {:>12} {:>12} {:>10} {:>8} {:>12} {:>12} {:>12}",
        "sensor",
        "measurements",
        "attempts",
        "delivered",
        "lost",
        "received",
        "energy",
        "predicted"
    )?;
    if let Some(arr) = s.get("sensors").and_then(Value::as_array) {
        for x in arr {
            // A count the recording does not hold (null) shows as –.
            let n = |k: &str| {
                x.get(k)
                    .and_then(Value::as_u64)
                    .map_or("–".into(), |v| v.to_string())
            };
            let e = |k: &str| {
                x.get(k)
                    .and_then(Value::as_f64)
                    .map_or("–".into(), |v| format!("{v:.1}"))
            };
            writeln!(
                out,
                "  {:<10} {:>12} {:>12} {:>10} {:>8} {:>12} {:>12} {:>12}",
                x.get("name").and_then(Value::as_str).unwrap_or("?"),
                n("measurements"),
                n("transmissions"),
                n("delivered"),
                n("lost"),
                n("received"),
                e("energy"),
                e("predicted_energy")
            )?;
        }
    }
    if let Some(f) = s.get("identity_failures").and_then(Value::as_array) {
        for x in f {
            writeln!(out, "  IDENTITY FAILS: {}", x.as_str().unwrap_or("?"))?;
        }
    }
    writeln!(out, "  messages per channel:")?;
    if let Some(counts) = s.get("counts").and_then(Value::as_object) {
        for (t, n) in counts {
            writeln!(out, "    {t:<20} {n}")?;
        }
    }
    Ok(())
}
