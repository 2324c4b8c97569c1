//! The run's summary from a recording alone: episodes, outcomes, per-sensor
//! transmissions (`measurement` messages beside the sensors' ledgers and what
//! the agent received), energy vs prediction.

use anyhow::{Context, Result};
use etp_runtime::recording::{self, Contents, Recorded};
use etp_shared::strategy::Strategy;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::Path;

/// One sensor, in the vocabulary of `crate::vocab`.
#[derive(Debug, Default, Clone, serde::Serialize)]
struct SensorSummary {
    name: String,
    /// `measurement` messages sent by this sensor.
    measurements: u64,
    /// Sum of the sensor's ledgers (transmissions).
    transmissions: u64,
    /// Sum of the sensor's ledgers (energy).
    energy: f64,
    predicted_energy: Option<f64>,
}

/// The summary object of a recording.
pub fn summarize(c: &Contents) -> Result<Value> {
    let prediction: Option<Value> = c
        .meta(recording::META_PREDICTION, "json")
        .and_then(|t| serde_json::from_str(t).ok());
    let names: Vec<String> = prediction
        .as_ref()
        .and_then(|p| p.get("sensors"))
        .and_then(|s| serde_json::from_value(s.clone()).ok())
        .unwrap_or_default();
    let per_ep: Vec<f64> = prediction
        .as_ref()
        .and_then(|p| p.get("sensor_energy_per_episode"))
        .and_then(|s| serde_json::from_value(s.clone()).ok())
        .unwrap_or_default();
    let mut sensors: BTreeMap<u32, SensorSummary> = BTreeMap::new();
    let sensor = |sensors: &mut BTreeMap<u32, SensorSummary>, i: u32| {
        let name = names
            .get(i as usize)
            .cloned()
            .unwrap_or_else(|| format!("sensor {i}"));
        sensors.entry(i).or_insert_with(|| SensorSummary {
            name,
            ..SensorSummary::default()
        });
    };
    let mut counts = crate::OutcomeCounts::default();
    let (mut steps, mut received) = (0u64, 0u64);
    let mut episodes = 0u64;
    for m in &c.messages {
        let rec = recording::decode(&m.topic, &m.data)
            .with_context(|| format!("message at log time {}", m.log_time))?;
        match rec {
            Recorded::Measurement(x) => {
                sensor(&mut sensors, x.header.sender);
                if let Some(s) = sensors.get_mut(&x.header.sender) {
                    s.measurements += 1;
                }
            }
            Recorded::Ledger(l) => {
                sensor(&mut sensors, l.header.sender);
                if let Some(s) = sensors.get_mut(&l.header.sender) {
                    s.transmissions += u64::from(l.transmissions);
                    s.energy += l.energy;
                }
            }
            Recorded::Outcome(o) => {
                episodes += 1;
                steps += u64::from(o.steps);
                received += u64::from(o.received);
                counts.add(&o);
            }
            _ => {}
        }
    }
    // Every sensor of the scenario, those that never sent anything included.
    for i in 0..names.len().max(per_ep.len()) {
        sensor(&mut sensors, i as u32);
    }
    for (i, s) in &mut sensors {
        s.predicted_energy = per_ep
            .get(*i as usize)
            .map(|e| crate::vocab::round_energy(e * episodes as f64));
        s.energy = crate::vocab::round_energy(s.energy);
    }
    let measurements: u64 = sensors.values().map(|s| s.measurements).sum();
    let ledgers: u64 = sensors.values().map(|s| s.transmissions).sum();
    let frac = |n: u64| {
        if episodes > 0 {
            n as f64 / episodes as f64
        } else {
            0.0
        }
    };
    let energy: f64 = sensors.values().map(|s| s.energy).sum();
    let predicted_energy: Option<f64> = if per_ep.is_empty() {
        None
    } else {
        Some(crate::vocab::round_energy(
            per_ep.iter().sum::<f64>() * episodes as f64,
        ))
    };
    let num = |k: &str| {
        c.meta(recording::META_RUN, k)
            .and_then(|v| v.parse::<u64>().ok())
    };
    let strategy: Option<Strategy> = c
        .meta(recording::META_STRATEGY, "json")
        .and_then(|t| Strategy::from_json(t).ok());
    let scenario = c
        .meta(recording::META_RUN, "scenario_name")
        .map(str::to_string)
        .or_else(|| strategy.as_ref().map(|s| s.scenario_name.clone()));
    Ok(json!({
        "run_id": c.meta(recording::META_RUN, "run_id"),
        "scenario": scenario,
        "seed": num("seed"),
        "strategy": strategy.as_ref().map(|s| s.label.clone()),
        "delta": strategy.as_ref().and_then(crate::vocab::constant_delta),
        "predicted": strategy.as_ref().map(|s| crate::vocab::prediction(&s.predicted)),
        "software_version": c.meta(recording::META_RUN, "software_version"),
        "format_version": num("format_version"),
        "requested_episodes": num("episodes"),
        "finished": c.finished,
        "truncated": c.truncated,
        "messages": c.messages.len(),
        "counts": c.counts(),
        "episodes": episodes,
        "target": counts.target, "collision": counts.collision, "free": counts.free,
        "p_target": frac(counts.target), "p_collision": frac(counts.collision),
        "p_free": frac(counts.free),
        "steps": steps,
        "energy_mean": if episodes > 0 { json!(energy / episodes as f64) } else { Value::Null },
        "measurements": measurements,
        "transmissions": ledgers,
        "received": received,
        "energy": crate::vocab::round_energy(energy),
        "predicted_energy": predicted_energy,
        "sensors": sensors.values().collect::<Vec<_>>(),
    }))
}

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
    writeln!(
        out,
        "  transmissions: {} measurement messages · {} in ledgers · {} received by the agent",
        g("measurements"),
        g("transmissions"),
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
    writeln!(
        out,
        "  {:<10} {:>12} {:>12} {:>12} {:>12}",
        "sensor", "measurements", "ledgers", "energy", "predicted"
    )?;
    if let Some(arr) = s.get("sensors").and_then(Value::as_array) {
        for x in arr {
            let f = |k: &str| x.get(k).cloned().unwrap_or(Value::Null);
            writeln!(
                out,
                "  {:<10} {:>12} {:>12} {:>12.1} {:>12.1}",
                f("name").as_str().unwrap_or("?"),
                f("measurements").as_u64().unwrap_or(0),
                f("transmissions").as_u64().unwrap_or(0),
                f("energy").as_f64().unwrap_or(f64::NAN),
                f("predicted_energy").as_f64().unwrap_or(f64::NAN)
            )?;
        }
    }
    writeln!(out, "  messages per channel:")?;
    for (t, n) in c.counts() {
        writeln!(out, "    {t:<20} {n}")?;
    }
    Ok(())
}
