//! `etpareto.simulate`: the constant-threshold simulation of `etp simulate`
//! (`etp_synthesis::constant`), its summary the CLI's `--json` object
//! (`etp_synthesis::report::simulate_json`), its episodes and legs as tables
//! (`etp_synthesis::records`, the same episodes).

use crate::columns::{Column, Values, table_into_py};
use crate::errors::{EtpError, SimulationError, chain};
use etp_shared::episode::Outcome;
use etp_shared::scenario::Scenario;
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::constant::{check_delta, constant_records, simulate_constant};
use etp_synthesis::records::Records;
use etp_synthesis::report::simulate_json;
use pyo3::prelude::*;
use pyo3::types::PyList;

fn outcome_name(o: Outcome) -> &'static str {
    match o {
        Outcome::Target => "target",
        Outcome::Collision => "collision",
        Outcome::Free => "free",
    }
}

fn episode_table(r: &Records) -> Vec<Column> {
    let e = &r.episodes;
    let u32s = |f: fn(&etp_synthesis::records::EpisodeRecord) -> u32| {
        Values::U64(e.iter().map(|x| u64::from(f(x))).collect())
    };
    vec![
        Column::new(
            "episode",
            Values::U64(e.iter().map(|x| x.episode).collect()),
        ),
        Column::new(
            "outcome",
            Values::Text(
                e.iter()
                    .map(|x| Some(outcome_name(x.outcome).to_string()))
                    .collect(),
            ),
        ),
        Column::new("steps", u32s(|x| x.steps)),
        Column::new("slots", u32s(|x| x.slots)),
        Column::new("transmissions", u32s(|x| x.transmissions)),
        Column::new("triggers", u32s(|x| x.triggers)),
        Column::new("delivered", u32s(|x| x.delivered)),
        Column::new("energy", Values::F64(e.iter().map(|x| x.energy).collect())),
        Column::new(
            "expected_transmissions",
            Values::F64(e.iter().map(|x| x.expected_transmissions).collect()),
        ),
        Column::new(
            "nees_sum",
            Values::F64(e.iter().map(|x| x.nees_sum).collect()),
        ),
        Column::new(
            "squared_error_sum",
            Values::F64(e.iter().map(|x| x.squared_error_sum).collect()),
        ),
    ]
}

fn leg_table(r: &Records, s: &Scenario) -> Vec<Column> {
    let l = &r.legs;
    let u32s = |f: fn(&etp_synthesis::records::LegRecord) -> u32| {
        Values::U64(l.iter().map(|x| u64::from(f(x))).collect())
    };
    let sensor = |i: u32| s.sensors.get(i as usize).map(|x| x.name.clone());
    let obstacle = |o: Option<u32>| {
        o.map(|i| {
            s.obstacles
                .get(i as usize)
                .map_or_else(|| format!("obstacle-{i}"), |x| x.name.clone())
        })
    };
    vec![
        Column::new(
            "episode",
            Values::U64(l.iter().map(|x| x.episode).collect()),
        ),
        Column::new("leg", u32s(|x| x.leg)),
        Column::new(
            "sensor",
            Values::Text(l.iter().map(|x| sensor(x.sensor)).collect()),
        ),
        Column::new(
            "collision",
            Values::Text(l.iter().map(|x| obstacle(x.collision)).collect()),
        ),
        Column::new("steps", u32s(|x| x.steps)),
        Column::new("slots", u32s(|x| x.slots)),
        Column::new("transmissions", u32s(|x| x.transmissions)),
        Column::new("triggers", u32s(|x| x.triggers)),
        Column::new("delivered", u32s(|x| x.delivered)),
        Column::new("kf_slots", u32s(|x| x.kf_slots)),
        Column::new(
            "expected_transmissions",
            Values::F64(l.iter().map(|x| x.expected_transmissions).collect()),
        ),
        Column::new(
            "energy",
            Values::F64(
                l.iter()
                    .map(|x| {
                        s.sensors
                            .get(x.sensor as usize)
                            .map_or(f64::NAN, |c| c.cost * f64::from(x.transmissions))
                    })
                    .collect(),
            ),
        ),
    ]
}

/// A table's columns for Python (`crate::columns`).
type Table<'py> = Bound<'py, PyList>;

/// Simulate like `etp simulate SCENARIO --delta D --episodes N --seed S
/// [--trigger F] --json`: `(summary_json_text, episodes, legs)`, the
/// summary as the CLI's text, the tables as columns (`records=False`:
/// no tables, `None`s).
#[pyfunction]
#[pyo3(signature = (scenario, delta, episodes = 3000, seed = 0, trigger = None, records = true))]
pub fn simulate<'py>(
    py: Python<'py>,
    scenario: &Bound<'py, PyAny>,
    delta: f64,
    episodes: u64,
    seed: u64,
    trigger: Option<String>,
    records: bool,
) -> PyResult<(String, Option<Table<'py>>, Option<Table<'py>>)> {
    let delta = check_delta(delta).map_err(|e| SimulationError::new_err(e.to_string()))?;
    if episodes == 0 {
        // clap's range check of `--episodes` (at least 1).
        return Err(SimulationError::new_err(
            "episodes must be at least 1 (`etp simulate --episodes`), got 0",
        ));
    }
    let family = trigger
        .as_deref()
        .map(TriggerFamily::parse)
        .transpose()
        .map_err(|e| SimulationError::new_err(e.to_string()))?;
    let mut s = crate::scenario::resolve(scenario)?;
    if let Some(family) = family {
        s.trigger = family;
    }
    let quiet = |_: u64| {};
    let (summary, recs) = py
        .detach(|| {
            let summary = simulate_constant(&s, delta, episodes, seed, &quiet)?;
            let recs = if records {
                Some(constant_records(&s, delta, episodes, seed, &quiet)?)
            } else {
                None
            };
            Ok::<_, etp_synthesis::exec::ExecError>((summary, recs))
        })
        .map_err(|e| EtpError::new_err(chain(&e)))?;
    let text = serde_json::to_string(&simulate_json(&s, &summary, delta, seed))
        .map_err(|e| EtpError::new_err(e.to_string()))?;
    let (eps, legs) = match recs {
        Some(r) => (
            Some(table_into_py(py, episode_table(&r))?),
            Some(table_into_py(py, leg_table(&r, &s))?),
        ),
        None => (None, None),
    };
    Ok((text, eps, legs))
}
