//! One job of a study — a scenario under one trigger family — done as the
//! commands do it: `etp synthesize` (MDP and front, no Method 1 baseline),
//! then per request `etp strategy DIR --min-target P [--max-collision C]`
//! (the request loop and the strategy it stands by, [`crate::selection`])
//! and `etp validate STRATEGY --episodes N --seed S`. Every file goes into
//! the job's folder (`DIR/cases/<job>/`: mdp.bin, front.json, scenario.toml,
//! strategy-K.json, row-K.json), each written beside and renamed, the row
//! last: a row file on disk is a finished case.

use super::JobPlan;
use super::spec::{Job, Request, Settings, Target};
use super::table::{Finished, Row, Timing};
use crate::error::{Context, Error, StudyError};
use crate::front::write_front;
use crate::mdp_build::{MdpRequest, build_mdp};
use crate::output::write_new;
use crate::progress::Progress;
use crate::selection::{RequestSettings, meet_goal};
use crate::synthesis_dir::Synthesis;
use crate::validation::{StrategySource, ValidationRequest, validate};
use etp_shared::strategy::Strategy;
use etp_synthesis::exec::Executor;
use etp_synthesis::predict::request::Goal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The file of request `k`'s row (`None`: the synthesis-only row).
pub fn row_path(job_dir: &Path, k: Option<usize>) -> PathBuf {
    match k {
        Some(k) => job_dir.join(format!("row-{k}.json")),
        None => job_dir.join("row.json"),
    }
}

/// The finished case at `path`, if any (a file that does not parse is an
/// error naming it: it was written whole, so it was edited).
pub fn finished(path: &Path) -> Result<Option<Finished>, StudyError> {
    let folder = |what: String, e: Box<dyn std::error::Error + Send + Sync>| StudyError::Folder {
        what,
        source: e,
    };
    match std::fs::read_to_string(path) {
        Ok(t) => Finished::from_json(&t)
            .map(Some)
            .map_err(|e| folder(path.display().to_string(), Box::new(e))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(folder(format!("reading {}", path.display()), Box::new(e))),
    }
}

/// The job's synthesis: loaded when rank 0 found its front on disk, else
/// built (a leftover mdp.bin of a killed run is rebuilt: same seed, same
/// bytes) and kept in memory — in an MPI job only rank 0 writes the files,
/// and the other ranks must not wait for them.
fn synthesis(
    job: &Job,
    synthesized: bool,
    dir: &Path,
    s: &Settings,
    timing: &mut Timing,
    (exec, progress): (&Executor, &Progress),
) -> Result<Synthesis, Error> {
    if synthesized {
        return Synthesis::load(dir, None, exec);
    }
    let started = Instant::now();
    let mut request = MdpRequest::defaults(job.scenario.clone(), s.samples, s.seed);
    request.out = Some(dir.to_path_buf());
    request.force = true;
    request.progress = progress.clone();
    request.exec = exec.clone();
    let built = build_mdp(request)?;
    let front = write_front(&built.dir, &built.mdp, None, &job.text, None, true, exec)?;
    timing.synthesis_seconds = started.elapsed().as_secs_f64();
    Synthesis::from_parts(
        dir,
        built.mdp,
        Some(job.text.clone()),
        front.front,
        None,
        exec,
    )
}

fn base_row(job: &Job, syn: &Synthesis, s: &Settings) -> Row {
    Row {
        case: job.id.clone(),
        request_index: None,
        scenario: job.scenario.name.clone(),
        source: job.source.clone(),
        family: job.family.name().to_string(),
        n: job.scenario.dim,
        samples: s.samples,
        seed: s.seed,
        states: syn.mdp.states.len(),
        vertices: syn.front.vertices.len(),
        front_epsilon: syn.front.epsilon,
        request: None,
        kf_p_target: None,
        min_target: None,
        max_collision: None,
        verdict: None,
        rounds: None,
        strategy: None,
        predicted_p_target: None,
        predicted_p_target_ci95: None,
        predicted_p_collision: None,
        predicted_p_collision_ci95: None,
        predicted_energy: None,
        predicted_energy_ci95: None,
        certified_p_target_low: None,
        certified_p_collision_high: None,
        certified_energy_high: None,
        episodes: None,
        simulated_p_target: None,
        simulated_p_target_ci95: None,
        simulated_p_collision: None,
        simulated_p_collision_ci95: None,
        simulated_energy: None,
        simulated_energy_ci95: None,
        miss_p_target: None,
        miss_p_collision: None,
        miss_energy_relative: None,
        checks_hold: None,
        failed_checks: None,
    }
}

/// Rounded to 4 decimals (a `kf-…` request as a person would write it).
fn round4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

/// The full Kalman filter's simulated P_tar on the job's scenario (`etp
/// simulate SCENARIO --delta 0 --episodes N --seed S`), once per job
/// however many `kf-…` requests ask it.
fn kf_p_target(syn: &Synthesis, s: &Settings, kf: &mut Option<f64>) -> Result<f64, Error> {
    if let Some(p) = *kf {
        return Ok(p);
    }
    let p = etp_synthesis::constant::simulate_constant(
        &syn.scenario,
        0.0,
        s.kf_episodes,
        s.seed,
        &syn.exec.work(|_| {}),
    )?
    .p_target
    .value;
    *kf = Some(p);
    Ok(p)
}

/// Request `k` of the job: selected, predicted, validated; its row.
fn request(
    job: &Job,
    syn: &Synthesis,
    s: &Settings,
    (k, r): (usize, &Request),
    kf: &mut Option<f64>,
    timing: &mut Timing,
    progress: &Progress,
) -> Result<Row, Error> {
    let mut row = base_row(job, syn, s);
    row.request_index = Some(k);
    row.request = Some(r.describe());
    let started = Instant::now();
    let min_target = match r.min_target {
        Target::Value(p) => p,
        Target::BelowKf(d) => {
            let kf = kf_p_target(syn, s, kf)?;
            row.kf_p_target = Some(kf);
            round4(kf - d).clamp(0.0, 1.0)
        }
    };
    row.min_target = Some(min_target);
    row.max_collision = r.max_collision;
    let goal = Goal::MinTarget {
        min_target,
        max_collision: r.max_collision,
    };
    let settings = RequestSettings {
        replicates: s.replicates,
        rounds: s.rounds,
        confidence: None,
        aggregation_check: s.aggregation_check,
    };
    let (outcome, strategy, _) = meet_goal(syn, &syn.mdp, goal, &settings, progress)?;
    let file = format!("strategy-{k}.json");
    let path = syn.dir.join(&file);
    write_new(&syn.exec, &path, strategy.to_json().as_bytes(), true)?;
    timing.selection_seconds = started.elapsed().as_secs_f64();
    row.verdict = Some(outcome.verdict.name().to_string());
    row.rounds = Some(outcome.rounds.len());
    row.strategy = Some(format!("cases/{}/{file}", job.id));
    let p = strategy.predictions.predicted;
    let h = strategy.predictions.predicted_ci95;
    row.predicted_p_target = p.map(|p| p.p_target);
    row.predicted_p_collision = p.map(|p| p.p_collision);
    row.predicted_energy = p.map(|p| p.energy_mean);
    row.predicted_p_target_ci95 = h.map(|h| h.p_target);
    row.predicted_p_collision_ci95 = h.map(|h| h.p_collision);
    row.predicted_energy_ci95 = h.map(|h| h.energy_mean);
    let c = strategy.predictions.certified;
    row.certified_p_target_low = c.map(|c| c.p_target_low);
    row.certified_p_collision_high = c.map(|c| c.p_collision_high);
    row.certified_energy_high = c.map(|c| c.energy_high);
    if s.episodes == 0 {
        return Ok(row);
    }
    // `etp validate STRATEGY --episodes N --seed S`: the strategy as read
    // back from its file's bytes (in memory: in an MPI job the other ranks
    // do not wait for rank 0's file).
    let started = Instant::now();
    let strategy = Strategy::from_sealed_json(&strategy.to_json())
        .in_strategy(format!("{} read back", path.display()))?;
    let scenario = strategy
        .policy
        .scenario()
        .in_strategy("the strategy's scenario")?;
    let v = validate(
        ValidationRequest {
            progress: progress.clone(),
            ..ValidationRequest::new(
                StrategySource::Loaded {
                    strategy: Box::new(strategy),
                    scenario: Box::new(scenario),
                },
                s.episodes,
                s.seed,
            )
        },
        &syn.exec,
    )?;
    let sum = v.summary;
    timing.validation_seconds = started.elapsed().as_secs_f64();
    row.episodes = Some(sum.episodes);
    row.simulated_p_target = Some(sum.p_target.value);
    row.simulated_p_target_ci95 = Some(sum.p_target.ci95);
    row.simulated_p_collision = Some(sum.p_collision.value);
    row.simulated_p_collision_ci95 = Some(sum.p_collision.ci95);
    row.simulated_energy = Some(sum.energy_mean.value);
    row.simulated_energy_ci95 = Some(sum.energy_mean.ci95);
    if let Some(p) = p {
        // Predicted − simulated, the sign of every error etp prints.
        row.miss_p_target = Some(p.p_target - sum.p_target.value);
        row.miss_p_collision = Some(p.p_collision - sum.p_collision.value);
        row.miss_energy_relative = (sum.energy_mean.value != 0.0)
            .then(|| (p.energy_mean - sum.energy_mean.value) / sum.energy_mean.value);
    }
    row.checks_hold = Some(v.failed.is_empty());
    row.failed_checks = Some(v.failed.join("; "));
    Ok(row)
}

/// Where a job's cases run: the executor of their Monte Carlo and files
/// (the job's ranks together, or this rank alone) and this process's rank
/// in the job, which the timings record.
pub struct Placement<'a> {
    pub exec: &'a Executor,
    pub rank: usize,
    /// Where the cases' steps count their progress (drawn by none of
    /// them: the study draws its own bar).
    pub progress: &'a Progress,
}

/// Do the cases of `job` that its `plan` names (request indices; `None`:
/// the synthesis-only row), in order, calling `done` as each is written.
pub fn run_job(
    job: &Job,
    plan: &JobPlan,
    cases_dir: &Path,
    requests: &[Request],
    s: &Settings,
    on: &Placement,
    done: &mut dyn FnMut(&Finished),
) -> Result<(), StudyError> {
    let dir = cases_dir.join(&job.id);
    etp_files::write::output_folder(&dir)?;
    let (exec, rank) = (on.exec, on.rank);
    let threads = exec.threads();
    let fresh = || Timing {
        rank,
        threads,
        ..Timing::default()
    };
    let mut timing = fresh();
    let mut kf = None;
    let syn = synthesis(
        job,
        plan.synthesized,
        &dir,
        s,
        &mut timing,
        (exec, on.progress),
    )
    .map_err(|source| StudyError::Case {
        what: format!("study case {}: the synthesis", job.id),
        source,
    })?;
    for &k in &plan.pending {
        let row = match k {
            None => base_row(job, &syn, s),
            Some(k) => {
                let r = requests.get(k).ok_or_else(|| {
                    StudyError::Bug(format!("study case {}: no request {k} (a bug)", job.id))
                })?;
                request(job, &syn, s, (k, r), &mut kf, &mut timing, on.progress).map_err(
                    |source| StudyError::Case {
                        what: format!("study case {} request {k}", job.id),
                        source,
                    },
                )?
            }
        };
        let f = Finished {
            row,
            timing: std::mem::replace(&mut timing, fresh()),
        };
        write_new(exec, &row_path(&dir, k), f.to_json()?.as_bytes(), true)?;
        done(&f);
    }
    Ok(())
}
