//! `etpareto.synthesize`, `etpareto.select_strategy`, `etpareto.validate`:
//! the steps of `etp synthesize`, `etp strategy` and `etp validate`
//! through `etp-pipeline` (the library those commands call), with the same
//! defaults, the same files and the same JSON. The work runs with the GIL
//! released on a worker thread while this thread passes the step under way
//! (`etp_pipeline::progress::Progress::current` of the value the work was
//! handed, so each call sees its own step) to the caller's progress
//! callback.

use crate::errors::{EtpError, ScenarioError, SimulationError, pipeline_error};
use crate::scenario::PyScenario;
use etp_pipeline::mdp_build::MdpRequest;
use etp_pipeline::progress::Progress;
use etp_pipeline::selection::{RequestSettings, meet_goal};
use etp_pipeline::synthesis_dir::Synthesis;
use etp_pipeline::synthesize::{SynthesisRequest, synthesize as synthesize_dir};
use etp_pipeline::validation::{
    MapRequest, StrategySource, ValidationRequest, map_stem_beside, validate as validate_step,
};
use etp_shared::scenario::Scenario;
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::exec::Executor;
use etp_synthesis::predict::request::Goal;
use pyo3::prelude::*;
use std::path::PathBuf;
use std::time::Duration;

/// How often the progress callback is called at most.
const POLL: Duration = Duration::from_millis(200);

/// Run `work` without the GIL on a worker thread, handing it where its
/// steps' progress goes (never drawn; watched when a callback is given);
/// meanwhile call `progress(stage, done, total)` each time the step under
/// way moves. A callback that raises stops the callbacks; its exception is
/// raised when the work has finished (the work itself cannot be
/// interrupted half-way: its files are written beside and renamed, so
/// nothing half-done is left either way).
pub(crate) fn with_progress<T: Send>(
    py: Python<'_>,
    progress: Option<Py<PyAny>>,
    work: impl FnOnce(Progress) -> T + Send,
) -> PyResult<T> {
    let Some(cb) = progress else {
        return Ok(py.detach(|| work(Progress::new(true))));
    };
    let watched = Progress::watched();
    let mut raised: Option<PyErr> = None;
    let out = py.detach(|| {
        std::thread::scope(|scope| {
            let handle = scope.spawn({
                let p = watched.clone();
                move || work(p)
            });
            let mut last: Option<(String, u64, u64)> = None;
            let mut report = |now: Option<(String, u64, u64)>, raised: &mut Option<PyErr>| {
                if raised.is_some() || now.is_none() || now == last {
                    return;
                }
                last.clone_from(&now);
                if let Some((stage, done, total)) = now {
                    Python::attach(|py| {
                        if let Err(e) = cb.call1(py, (stage, done, total)) {
                            *raised = Some(e);
                        }
                    });
                }
            };
            while !handle.is_finished() {
                std::thread::sleep(POLL);
                report(watched.current(), &mut raised);
            }
            report(watched.current(), &mut raised);
            handle.join()
        })
    });
    let out = out.map_err(|_| EtpError::new_err("the work panicked (a bug: please report it)"))?;
    match raised {
        Some(e) => Err(e),
        None => Ok(out),
    }
}

/// The scenario argument (`Scenario` or name/path) and its TOML text.
fn source_of(obj: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(s) = obj.cast::<PyScenario>() {
        return Ok(s.get().arg.clone());
    }
    obj.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "scenario: an etpareto.Scenario, a built-in name or a TOML path",
        )
    })
}

/// The scenario of `arg` under `trigger`, and its text (what `etp
/// synthesize` writes into DIR/scenario.toml), by the CLI's own function.
fn scenario_under(arg: &str, trigger: Option<&str>) -> PyResult<(Scenario, String)> {
    let family = trigger
        .map(TriggerFamily::parse)
        .transpose()
        .map_err(|e| ScenarioError::new_err(e.to_string()))?;
    etp_pipeline::synthesize::scenario_under(arg, family).map_err(pipeline_error)
}

/// Synthesize like `etp synthesize SCENARIO -o OUT --json` with these
/// options (the CLI's defaults): the MDP, the Method 1 baseline, the front
/// and its files, the aggregation check. Returns that command's JSON text.
#[pyfunction]
#[pyo3(signature = (scenario, out, samples = etp_synthesis::abstraction::DEFAULT_SAMPLES,
    seed = 0, trigger = None, holdout_samples = 0, kf_baseline = true,
    aggregation_episodes = etp_pipeline::synthesize::DEFAULT_AGGREGATION_EPISODES,
    force = false, progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn synthesize(
    py: Python<'_>,
    scenario: &Bound<'_, PyAny>,
    out: PathBuf,
    samples: u32,
    seed: u64,
    trigger: Option<String>,
    holdout_samples: u32,
    kf_baseline: bool,
    aggregation_episodes: u64,
    force: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    if samples == 0 {
        return Err(SimulationError::new_err(
            "samples must be at least 1 (`etp synthesize --samples`), got 0",
        ));
    }
    let (s, text) = scenario_under(&source_of(scenario)?, trigger.as_deref())?;
    let mut mdp = MdpRequest::defaults(s, samples, seed);
    mdp.params.holdout_samples = holdout_samples;
    mdp.out = Some(out);
    mdp.force = force;
    let mut request = SynthesisRequest::new(mdp, text);
    request.kf_baseline = kf_baseline;
    request.aggregation_episodes = aggregation_episodes;
    let done = with_progress(py, progress, move |p| {
        request.mdp.progress = p;
        synthesize_dir(request)
    })?
    .map_err(pipeline_error)?;
    serde_json::to_string(&done.to_json()).map_err(|e| EtpError::new_err(e.to_string()))
}

/// Select like `etp strategy DIR (--min-target P [--max-collision C] |
/// --max-energy E)`: the request loop and the strategy it stands by,
/// written to `output` (default DIR/strategy.json). Returns the file's
/// text, the loop's verdict (`met`, or why not) and its rounds.
#[pyfunction]
#[pyo3(signature = (dir, min_target = None, max_collision = None, max_energy = None,
    replicates = etp_synthesis::predict::rebuild::DEFAULT_REPLICATES,
    rounds = etp_synthesis::predict::request::DEFAULT_ROUNDS, confidence = None,
    aggregation_check = etp_pipeline::predictions::AGGREGATION_CHECK_EPISODES,
    output = None, force = false, progress = None))]
#[allow(clippy::too_many_arguments)]
pub fn select_strategy(
    py: Python<'_>,
    dir: PathBuf,
    min_target: Option<f64>,
    max_collision: Option<f64>,
    max_energy: Option<f64>,
    replicates: u32,
    rounds: u32,
    confidence: Option<f64>,
    aggregation_check: u64,
    output: Option<PathBuf>,
    force: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(String, String, usize)> {
    let bad = |t: String| pyo3::exceptions::PyValueError::new_err(t);
    let probability = |name: &str, v: f64| {
        if (0.0..=1.0).contains(&v) {
            Ok(v)
        } else {
            Err(bad(format!(
                "{name} must be a probability in [0, 1], got {v}"
            )))
        }
    };
    let goal = match (min_target, max_energy) {
        (Some(p), None) => Goal::MinTarget {
            min_target: probability("min_target", p)?,
            max_collision: max_collision
                .map(|c| probability("max_collision", c))
                .transpose()?,
        },
        (None, Some(e)) if max_collision.is_none() => {
            if !(e.is_finite() && e >= 0.0) {
                return Err(bad(format!(
                    "max_energy must be a finite number ≥ 0, got {e}"
                )));
            }
            Goal::MaxEnergy { max_energy: e }
        }
        (None, Some(_)) => return Err(bad("max_collision goes with min_target".into())),
        _ => return Err(bad("give exactly one of min_target, max_energy".into())),
    };
    if !(2..=64).contains(&replicates) {
        return Err(bad(format!(
            "replicates must lie in 2..=64, got {replicates}"
        )));
    }
    if !(1..=20).contains(&rounds) {
        return Err(bad(format!("rounds must lie in 1..=20, got {rounds}")));
    }
    if let Some(l) = confidence
        && !(l > 0.0 && l < 1.0)
    {
        return Err(bad(format!(
            "confidence must lie strictly between 0 and 1, got {l}"
        )));
    }
    let settings = RequestSettings {
        replicates,
        rounds,
        confidence,
        aggregation_check,
    };
    let work = move |p: Progress| -> etp_pipeline::error::Result<(String, String, usize)> {
        let exec = Executor::LOCAL;
        let syn = Synthesis::load(&dir, output.as_deref(), &exec)?;
        etp_pipeline::output::refuse_existing(&exec, &syn.output, force)?;
        let (outcome, strategy, _) = meet_goal(&syn, &syn.mdp, goal, &settings, &p)?;
        let text = strategy.to_json();
        etp_pipeline::output::write_new(&exec, &syn.output, text.as_bytes(), force)?;
        Ok((
            text,
            outcome.verdict.name().to_string(),
            outcome.rounds.len(),
        ))
    };
    with_progress(py, progress, work)?.map_err(pipeline_error)
}

/// Validate like `etp validate STRATEGY --episodes N --seed S --json
/// [--plot --plot-episodes P]`: that command's JSON text, the names of the
/// checks that fail (empty: it would exit 0), and the map figures written.
#[pyfunction]
#[pyo3(signature = (strategy, episodes = 3000, seed = 0, plot_episodes = None, force = false, progress = None))]
pub fn validate(
    py: Python<'_>,
    strategy: PathBuf,
    episodes: u64,
    seed: u64,
    plot_episodes: Option<u64>,
    force: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(String, Vec<String>, Vec<PathBuf>)> {
    if episodes == 0 {
        return Err(SimulationError::new_err(
            "episodes must be at least 1 (`etp validate --episodes`), got 0",
        ));
    }
    let path = if strategy.is_dir() {
        strategy.join("strategy.json")
    } else {
        strategy
    };
    let request = ValidationRequest {
        map: plot_episodes.map(|n| MapRequest {
            stem: map_stem_beside(&path),
            episodes: n,
            force,
        }),
        ..ValidationRequest::new(StrategySource::File(path), episodes, seed)
    };
    let v = with_progress(py, progress, move |p| {
        validate_step(
            ValidationRequest {
                progress: p,
                ..request
            },
            &Executor::LOCAL,
        )
    })?
    .map_err(pipeline_error)?;
    let text = serde_json::to_string(&v.json).map_err(|e| EtpError::new_err(e.to_string()))?;
    let failed = v.failed.into_iter().map(str::to_string).collect();
    Ok((text, failed, v.maps))
}
