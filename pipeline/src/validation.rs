//! A strategy checked against a simulation of it — `etp validate`'s JSON
//! and the checks that decide its exit code, shared with the Python
//! package's `etpareto.validate`.

use crate::predictions::{self, checks};
use etp_shared::strategy::Strategy;
use etp_synthesis::exec::Executor;
use etp_synthesis::report::summary_json;
use etp_synthesis::simulate::SimulationSummary;
use serde_json::json;
use std::path::{Path, PathBuf};

/// `etp validate --plot`: the map with `episodes` sampled trajectories of
/// the strategy coloured by γ̄(δ), written beside the strategy file as
/// `<stem>-map.png` and `.svg` (refused when they exist, unless `force`).
/// The paths written.
pub fn plot_map(
    scenario: &etp_shared::scenario::Scenario,
    strategy: &Strategy,
    strategy_path: &Path,
    episodes: u64,
    seed: u64,
    force: bool,
    exec: &Executor,
) -> crate::error::Result<Vec<PathBuf>> {
    let stem = strategy_path.with_extension("").with_file_name(format!(
        "{}-map",
        strategy_path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("strategy")
    ));
    plot_map_to(scenario, strategy, &stem, episodes, seed, force, exec)
}

/// [`plot_map`] to `STEM.png` and `STEM.svg` (`etp validate --plot -o STEM`).
pub fn plot_map_to(
    scenario: &etp_shared::scenario::Scenario,
    strategy: &Strategy,
    stem: &Path,
    episodes: u64,
    seed: u64,
    force: bool,
    exec: &Executor,
) -> crate::error::Result<Vec<PathBuf>> {
    let stem = stem.to_path_buf();
    let paths = vec![stem.with_extension("png"), stem.with_extension("svg")];
    for p in &paths {
        crate::output::refuse_existing(exec, p, force)?;
    }
    let tr =
        etp_synthesis::validate::sample_trajectories(scenario, &strategy.policy, episodes, seed);
    if exec.is_root() {
        etp_figures::map_plot(scenario, &tr, &stem)?;
    }
    Ok(paths)
}

/// The names of the checks of [`checks`] that fail (empty: every check
/// holds at 95 % family-wise, `etp validate` exits 0).
pub fn failed_checks(strategy: &Strategy, sum: &SimulationSummary) -> Vec<&'static str> {
    checks(strategy, sum)
        .1
        .into_iter()
        .filter(|c| !c.holds)
        .map(|c| c.name)
        .collect()
}

/// The simulation in the vocabulary of `etp_recording_tools::vocab` (the flat keys of
/// `etp simulate`), with the strategy's identity, its predictions and the
/// checks of each prediction against the simulation.
pub fn comparison_json(
    scenario: &etp_shared::scenario::Scenario,
    synthesized: &etp_shared::radio::Radio,
    strategy: &Strategy,
    sum: &SimulationSummary,
    seed: u64,
) -> serde_json::Value {
    let mut v = summary_json(scenario, sum);
    // The per-sensor prediction of the strategy file (the MDP's), if it has one.
    if let (Some(per_ep), Some(sensors)) = (
        strategy.predictions.sensor_energy(scenario),
        v.get_mut("sensors")
            .and_then(serde_json::Value::as_array_mut),
    ) {
        for (x, e) in sensors.iter_mut().zip(per_ep) {
            x["predicted_energy"] = json!(etp_recording_tools::vocab::round_energy(
                e * sum.episodes as f64
            ));
        }
    }
    if let Some(m) = v.as_object_mut() {
        m.insert("scenario".into(), json!(scenario.name));
        let names: Vec<String> = scenario.sensors.iter().map(|x| x.name.clone()).collect();
        m.insert(
            "radio_synthesized".into(),
            json!(synthesized.describe(&names)),
        );
        m.insert("seed".into(), json!(seed));
        m.insert("strategy".into(), json!(strategy.provenance.label));
        m.insert(
            "delta".into(),
            json!(etp_recording_tools::vocab::constant_delta(&strategy.policy)),
        );
        m.extend(predictions::json_fields(strategy));
        m.insert(
            "predicted".into(),
            etp_recording_tools::vocab::prediction(strategy.predictions.predicted.as_ref()),
        );
        m.insert(
            "error".into(),
            predictions::check_of(strategy, sum, seed).map_or(serde_json::Value::Null, |c| {
                predictions::aggregation_json(&c, predictions::reference_name(strategy))
            }),
        );
        let (family, all) = checks(strategy, sum);
        let num = |x: f64| {
            if x.is_finite() {
                json!(x)
            } else {
                serde_json::Value::Null
            }
        };
        m.insert(
            "checks".into(),
            all.iter()
                .map(|c| {
                    json!({"check": c.name, "holds": c.holds, "value": c.value,
                        "low": num(c.low), "high": num(c.high)})
                })
                .collect(),
        );
        m.insert(
            "checks_level".into(),
            json!({"family_wise_level": family.level, "per_check_level": family.per_check_level(),
                "family_size": family.checks, "method": "Bonferroni"}),
        );
    }
    v
}
