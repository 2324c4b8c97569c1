//! A strategy checked against a simulation of it: the one validation step
//! ([`validate`], from a typed [`ValidationRequest`]) of `etp validate`,
//! `etp demo`, a study's cases and the Python package's
//! `etpareto.validate`, with its JSON and the checks that decide `etp
//! validate`'s exit code.

use crate::error::{Context, Error, Result};
use crate::predictions::{self, checks};
use crate::progress::Progress;
use etp_runtime::strategy_arg::{StrategyArgError, load_strategy};
use etp_shared::radio::{Radio, RadioOverride};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Strategy;
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::exec::Executor;
use etp_synthesis::report::{first_non_finite, summary_json};
use etp_synthesis::simulate::SimulationSummary;
use etp_synthesis::validate::simulate_strategy;
use serde_json::json;
use std::path::{Path, PathBuf};

/// The strategy a validation simulates.
#[derive(Debug, Clone)]
pub enum StrategySource {
    /// A sealed `strategy.json`, read with its seal checked, simulated on
    /// the scenario it carries under the channel it was synthesized for.
    File(PathBuf),
    /// A strategy already in memory and the scenario to simulate it on.
    Loaded {
        strategy: Box<Strategy>,
        scenario: Box<Scenario>,
    },
}

/// The map of sampled trajectories coloured by γ̄(δ) (`etp validate --plot`).
#[derive(Debug, Clone)]
pub struct MapRequest {
    /// Written as `STEM.png` and `STEM.svg` ([`map_stem_beside`]: beside
    /// the strategy file).
    pub stem: PathBuf,
    /// Trajectories drawn.
    pub episodes: u64,
    /// Replace figures that exist (else they are refused before any work).
    pub force: bool,
}

/// One validation: `episodes` episodes of a strategy simulated in-process
/// (seed `seed`) and checked against the strategy's predictions.
#[derive(Debug, Clone)]
pub struct ValidationRequest {
    pub strategy: StrategySource,
    /// The trigger family the caller expects (`None`: the strategy's own);
    /// another than the strategy's is refused, its thresholds and
    /// predictions holding for its own family only.
    pub trigger: Option<TriggerFamily>,
    /// Radio settings that replace the scenario's on every link (a
    /// robustness study); the default replaces nothing.
    pub radio: RadioOverride,
    pub episodes: u64,
    pub seed: u64,
    /// Also draw the map.
    pub map: Option<MapRequest>,
    /// Where the simulation's bar goes.
    pub progress: Progress,
}

impl ValidationRequest {
    /// `strategy` simulated for `episodes` episodes with `seed`, under its
    /// own channel and family, no map, its bar drawn.
    pub fn new(strategy: StrategySource, episodes: u64, seed: u64) -> Self {
        ValidationRequest {
            strategy,
            trigger: None,
            radio: RadioOverride::default(),
            episodes,
            seed,
            map: None,
            progress: Progress::default(),
        }
    }
}

/// What a validation found.
#[derive(Debug, Clone)]
pub struct Validation {
    pub strategy: Strategy,
    /// The scenario simulated (under the request's radio settings).
    pub scenario: Scenario,
    /// The channel the strategy was made for (the scenario's before the
    /// request's radio settings).
    pub synthesized: Radio,
    pub summary: SimulationSummary,
    /// `etp validate --json`'s object ([`comparison_json`]).
    pub json: serde_json::Value,
    /// The checks that fail ([`failed_checks`]; empty: every one holds).
    pub failed: Vec<&'static str>,
    /// The map's figures (empty without a map; rank 0 writes them).
    pub maps: Vec<PathBuf>,
}

/// The validation step: read the strategy, confirm its family, put its
/// scenario under the radio settings, refuse map figures that exist, then
/// simulate (on `exec`'s threads and ranks, progress on rank 0), refuse a
/// simulation that overflowed, draw the map and check the predictions.
/// A check that fails is not an error: it is in [`Validation::failed`].
pub fn validate(request: ValidationRequest, exec: &Executor) -> Result<Validation> {
    let (strategy, scenario) = match request.strategy {
        StrategySource::File(path) => load_strategy(&path).map_err(strategy_file_error)?,
        StrategySource::Loaded { strategy, scenario } => (*strategy, *scenario),
    };
    if let Some(family) = request.trigger {
        confirm_family(family, scenario.trigger)?;
    }
    let synthesized = scenario.radio.clone();
    let mut scenario = scenario;
    scenario.radio = scenario
        .radio
        .for_use(None, &request.radio)
        .in_scenario("radio options")?;
    if let Some(map) = &request.map {
        for p in map_paths(&map.stem) {
            crate::output::refuse_existing(exec, &p, map.force)?;
        }
    }
    let pb = request.progress.bar(exec, request.episodes, "validate");
    let summary = simulate_strategy(
        &scenario,
        &strategy.policy,
        request.episodes,
        request.seed,
        &exec.work(|k| pb.inc(k)),
    )?
    .summary();
    pb.finish_and_clear();
    ensure_finite(&summary)?;
    let maps = match &request.map {
        Some(map) => plot_map(&scenario, &strategy, map, request.seed, exec)?,
        None => Vec::new(),
    };
    let json = comparison_json(&scenario, &synthesized, &strategy, &summary, request.seed);
    let failed = failed_checks(&strategy, &summary);
    Ok(Validation {
        strategy,
        scenario,
        synthesized,
        summary,
        json,
        failed,
        maps,
    })
}

/// A strategy file that could not be loaded, its words over its cause
/// (the text `etp` prints is the same chain).
fn strategy_file_error(e: StrategyArgError) -> Error {
    let what = e.to_string();
    let source: crate::error::Cause = match e {
        StrategyArgError::Read { source, .. } => Box::new(source),
        StrategyArgError::Invalid { source, .. } | StrategyArgError::Scenario { source, .. } => {
            Box::new(source)
        }
    };
    Error::Strategy {
        what,
        source: Some(source),
    }
}

/// Refuse a trigger family other than the strategy's own.
fn confirm_family(asked: TriggerFamily, strategy_family: TriggerFamily) -> Result<()> {
    if asked == strategy_family {
        return Ok(());
    }
    Err(Error::request(format!(
        "--trigger {asked}: the strategy was made for trigger family `{strategy_family}` \
         (its thresholds and predictions hold for that family only); synthesize with \
         --trigger {asked} for a strategy of that family"
    )))
}

/// The last line of defence against a result that is not a number: a
/// summary holding one (a scenario whose numbers overflowed in a way
/// `Scenario::from_toml` did not foresee) is an error naming the quantity.
pub fn ensure_finite(sum: &SimulationSummary) -> Result<()> {
    match first_non_finite(sum) {
        None => Ok(()),
        Some((key, v)) => Err(Error::Compute {
            what: format!(
                "the simulation's {key} is {v}, not a number: the scenario's arithmetic overflowed \
                 over {} episodes ({} steps); nothing is reported (check the scenario's model.F, \
                 Q, R and P0: docs/MODEL.md §1.1)",
                sum.episodes, sum.total_steps
            ),
            source: None,
        }),
    }
}

/// The map's stem beside a strategy file: `<STRATEGY without .json>-map`
/// (`etp validate --plot` without `-o`).
pub fn map_stem_beside(strategy_path: &Path) -> PathBuf {
    strategy_path.with_extension("").with_file_name(format!(
        "{}-map",
        strategy_path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("strategy")
    ))
}

/// The files of a map of stem `stem`.
fn map_paths(stem: &Path) -> [PathBuf; 2] {
    [stem.with_extension("png"), stem.with_extension("svg")]
}

/// The map with `map.episodes` sampled trajectories of the strategy
/// (seed `seed`) coloured by γ̄(δ), drawn by rank 0 (refused when its
/// files exist, unless `map.force`). The paths written.
fn plot_map(
    scenario: &Scenario,
    strategy: &Strategy,
    map: &MapRequest,
    seed: u64,
    exec: &Executor,
) -> Result<Vec<PathBuf>> {
    let paths = map_paths(&map.stem);
    for p in &paths {
        crate::output::refuse_existing(exec, p, map.force)?;
    }
    let tr = etp_synthesis::validate::sample_trajectories(
        scenario,
        &strategy.policy,
        map.episodes,
        seed,
    );
    if exec.is_root() {
        etp_figures::map_plot(scenario, &tr, &map.stem)?;
    }
    Ok(paths.into())
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
    scenario: &Scenario,
    synthesized: &Radio,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/tests/fixtures/strategy-open-2d-predicted.json")
    }

    fn quiet(strategy: StrategySource) -> ValidationRequest {
        ValidationRequest {
            progress: Progress::new(true),
            ..ValidationRequest::new(strategy, 200, 3)
        }
    }

    /// A file and the same strategy in memory on its own scenario are one
    /// validation: the same summary, JSON and failed checks.
    #[test]
    fn a_file_and_its_strategy_in_memory_validate_alike() {
        let exec = Executor::LOCAL;
        let from_file = validate(quiet(StrategySource::File(fixture())), &exec).expect("file");
        let (strategy, scenario) = load_strategy(&fixture()).expect("fixture");
        let loaded = StrategySource::Loaded {
            strategy: Box::new(strategy),
            scenario: Box::new(scenario),
        };
        let in_memory = validate(quiet(loaded), &exec).expect("in memory");
        assert_eq!(from_file.summary.episodes, 200);
        assert_eq!(from_file.json, in_memory.json);
        assert_eq!(from_file.failed, in_memory.failed);
        assert!(from_file.maps.is_empty());
        assert_eq!(from_file.json["seed"], 3);
    }

    /// Requests refused before any work, each by its kind: another trigger
    /// family, radio settings the channel refuses, an unreadable file.
    #[test]
    fn refused_requests_name_their_kind() {
        let exec = Executor::LOCAL;
        let mut r = quiet(StrategySource::File(fixture()));
        r.trigger = Some(TriggerFamily::Periodic);
        let e = validate(r, &exec).expect_err("another family");
        assert!(matches!(e, Error::Request(_)), "{e}");
        assert!(e.to_string().starts_with("--trigger periodic:"), "{e}");
        let mut r = quiet(StrategySource::File(fixture()));
        r.radio.loss = Some(2.0);
        let e = validate(r, &exec).expect_err("a loss above 1");
        assert!(matches!(e, Error::Scenario { .. }), "{e}");
        assert_eq!(e.to_string(), "radio options");
        let e = validate(quiet(StrategySource::File("no/such.json".into())), &exec)
            .expect_err("no file");
        assert!(matches!(e, Error::Strategy { .. }), "{e}");
        assert_eq!(e.to_string(), "reading no/such.json");
    }

    /// A map whose figure exists is refused, without `force`, before the
    /// simulation; with `force` both figures are drawn.
    #[test]
    fn a_map_that_exists_is_refused_unless_forced() {
        let dir = std::env::temp_dir().join(format!("etp-validation-map-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("folder");
        let stem = dir.join("m");
        std::fs::write(stem.with_extension("png"), b"mine").expect("planted");
        let with_map = |force| ValidationRequest {
            map: Some(MapRequest {
                stem: stem.clone(),
                episodes: 2,
                force,
            }),
            ..quiet(StrategySource::File(fixture()))
        };
        let e = validate(with_map(false), &Executor::LOCAL).expect_err("exists");
        assert!(matches!(e, Error::Output(_)), "{e}");
        assert!(!stem.with_extension("svg").exists());
        let v = validate(with_map(true), &Executor::LOCAL).expect("forced");
        assert_eq!(
            v.maps,
            vec![stem.with_extension("png"), stem.with_extension("svg")]
        );
        assert!(v.maps.iter().all(|p| p.is_file()));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_map_stem_beside_a_strategy_drops_its_extension() {
        assert_eq!(
            map_stem_beside(Path::new("out/s.json")),
            PathBuf::from("out/s-map")
        );
    }
}
