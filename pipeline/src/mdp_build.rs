//! The MDP step of a synthesis (docs/MODEL.md §4), shared by `etp
//! synthesize` and `etp demo`: simulate the segments with a progress bar,
//! split and lump on request, check, write `DIR/mdp.bin` (beside, then
//! renamed) and measure. The request is typed ([`MdpRequest`]): the scenario
//! already loaded and the abstraction parameters already made, so a command
//! that is not `synthesize` builds one without `synthesize`'s arguments.

pub mod split;

use crate::error::{Context, Error, Result};
use crate::output::write_new;
use crate::progress::Progress;
use etp_shared::scenario::Scenario;
use etp_synthesis::abstraction::split::SplitSettings;
use etp_synthesis::abstraction::{self, AbstractionParams};
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::{MDP_FILE, Mdp};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to build, and where.
#[derive(Debug, Clone)]
pub struct MdpRequest {
    /// The scenario, under its channel and trigger family.
    pub scenario: Scenario,
    pub params: AbstractionParams,
    /// The output folder (default `out/<scenario name>`).
    pub out: Option<PathBuf>,
    /// Replace an existing `mdp.bin`.
    pub force: bool,
    /// Lump indistinguishable states at this level (docs/MODEL.md §7.3).
    pub merge: Option<f64>,
    /// Adaptive splitting of the regions the aggregation test flags.
    pub split: SplitSettings,
    /// Draw the pools on this strategy's policy (docs/MODEL.md §7.3).
    pub pool_policy: Option<PathBuf>,
    /// With `pool_policy`: simulate every threshold at every state.
    pub all_actions: bool,
    /// Where the bars go (none drawn with `--json`).
    pub progress: Progress,
    /// Where the Monte Carlo runs (threads and ranks); rank 0 writes.
    pub exec: Executor,
}

impl MdpRequest {
    /// The default synthesis of `scenario` (`etp synthesize`'s defaults, no
    /// held-out sample) with `samples` segments per state-action from `seed`.
    pub fn defaults(scenario: Scenario, samples: u32, seed: u64) -> Self {
        Self {
            scenario,
            params: AbstractionParams {
                samples,
                seed,
                ..AbstractionParams::default()
            },
            out: None,
            force: false,
            merge: None,
            split: SplitSettings::default(),
            pool_policy: None,
            all_actions: false,
            progress: Progress::default(),
            exec: Executor::LOCAL,
        }
    }
}

/// What [`build_mdp`] did, for the summary.
#[derive(Debug, Clone, Serialize)]
pub struct MdpReport {
    pub scenario: String,
    pub method: String,
    pub path: PathBuf,
    pub samples: u32,
    pub holdout_samples: u32,
    pub seed: u64,
    pub states: usize,
    pub states_per_decision_point: Vec<usize>,
    /// `--merge`: the level and the states per decision point before lumping.
    pub merge: Option<MergeSummary>,
    /// `--split-budget`: what adaptive splitting did (before any lumping).
    pub split: Option<split::SplitSummary>,
    /// Sampled segments per state over its actions (`samples` × actions
    /// unless sample allocation added some): smallest and largest.
    pub samples_per_state: [u64; 2],
    /// Sampled segments that arrived in each non-initial state: min, median, max.
    pub arrivals_per_state: [u64; 3],
    /// Non-initial states that fewer than 100 sampled segments arrived in.
    pub states_under_100_arrivals: usize,
    pub choices: usize,
    pub transitions: usize,
    pub segments: u64,
    pub segment_steps: u64,
    pub seconds: f64,
    pub segment_steps_per_second: f64,
    pub threads: usize,
}

/// What `--merge` did.
#[derive(Debug, Clone, Serialize)]
pub struct MergeSummary {
    pub alpha: f64,
    pub states_before: usize,
    pub states_per_decision_point_before: Vec<usize>,
}

/// The result of the MDP step of `synthesize`.
#[derive(Debug, Clone)]
pub struct BuiltMdp {
    pub scenario: Scenario,
    pub mdp: Mdp,
    /// The output directory (holds `mdp.bin`).
    pub dir: PathBuf,
    pub report: MdpReport,
}

/// Build the MDP of `r.scenario` and write `DIR/mdp.bin`; refuses (before any
/// work, touching nothing) when the file exists and `force` is not set.
pub fn build_mdp(r: MdpRequest) -> Result<BuiltMdp> {
    let MdpRequest {
        scenario: s,
        params: p,
        out,
        force,
        merge,
        split,
        pool_policy,
        all_actions,
        progress,
        exec,
    } = r;
    let dir = out.unwrap_or_else(|| Path::new("out").join(&s.name));
    let path = dir.join(MDP_FILE);
    etp_files::write::output_folder(&dir)?;
    crate::output::refuse_existing(&exec, &path, force)?;
    if let Some(alpha) = merge
        && !(alpha > 0.0 && alpha < 1.0)
    {
        return Err(Error::request(format!(
            "--merge: the level α must lie in (0, 1) (got {alpha})"
        )));
    }
    split::check(&split, p.method)?;
    let pool_policy = match &pool_policy {
        None => None,
        Some(path) => {
            if split.budget > 0 {
                return Err(Error::request(
                    "--pool-policy and --split-budget: choose one (the policy's strategy carries its own splits)",
                ));
            }
            let (st, _) = etp_runtime::strategy_arg::load_strategy(path)
                .in_strategy(format!("--pool-policy {}", path.display()))?;
            st.policy.check_scenario(&s).in_strategy(format!(
                "--pool-policy {}: not a strategy of {}",
                path.display(),
                s.name
            ))?;
            Some(st)
        }
    };
    let pb = progress.bar(&exec, abstraction::progress_total(&s, &p), "synthesize");
    let started = Instant::now();
    let mdp = match &pool_policy {
        None => abstraction::build(&s, &p, &exec.work(|k| pb.inc(k))),
        Some(st) => abstraction::build_on_policy(
            &s,
            &p,
            &st.policy,
            true,
            !all_actions,
            &exec.work(|k| pb.inc(k)),
        ),
    }
    .computing("building the abstraction")?;
    pb.finish_and_clear();
    mdp.check()
        .computing("the built MDP failed its own consistency check (a bug)")?;
    let first_seconds = started.elapsed().as_secs_f64();
    let (mdp, split) = split::apply(&s, &p, mdp, first_seconds, &split, &progress, &exec)?;
    let (mdp, merge) = match merge {
        None => (mdp, None),
        Some(alpha) => {
            let (merged, r) = abstraction::merge_equivalent(&mdp, alpha).computing("--merge")?;
            merged
                .check()
                .computing("the merged MDP failed its own consistency check (a bug)")?;
            let summary = MergeSummary {
                alpha,
                states_before: mdp.states.len(),
                states_per_decision_point_before: r.before,
            };
            (merged, Some(summary))
        }
    };
    let seconds = started.elapsed().as_secs_f64();
    // Checked above; `force` here only covers a file that appeared meanwhile.
    write_new(&exec, &path, &mdp.encode(), force)?;
    let arrivals = arrivals_summary(&mdp);
    let report = MdpReport {
        scenario: s.name.clone(),
        method: format!("{:?}", mdp.method),
        path: path.clone(),
        samples: mdp.samples_per_choice,
        holdout_samples: mdp.holdout_samples,
        seed: mdp.seed,
        states: mdp.states.len(),
        states_per_decision_point: mdp.states_per_decision_point(),
        merge,
        split,
        samples_per_state: samples_per_state(&mdp),
        arrivals_per_state: arrivals.0,
        states_under_100_arrivals: arrivals.1,
        choices: mdp.states.iter().map(|s| s.choices.len()).sum(),
        transitions: mdp.num_transitions(),
        segments: mdp.total_segments,
        segment_steps: mdp.total_steps,
        seconds,
        segment_steps_per_second: mdp.total_steps as f64 / seconds.max(1e-9),
        threads: exec.threads(),
    };
    Ok(BuiltMdp {
        scenario: s,
        mdp,
        dir,
        report,
    })
}

fn samples_per_state(mdp: &Mdp) -> [u64; 2] {
    let per: Vec<u64> = mdp
        .states
        .iter()
        .map(|s| s.choices.iter().map(|c| u64::from(c.samples)).sum())
        .collect();
    [
        per.iter().copied().min().unwrap_or(0),
        per.iter().copied().max().unwrap_or(0),
    ]
}

/// `([min, median, max], states under 100)` of the arrivals into non-initial states.
fn arrivals_summary(mdp: &Mdp) -> ([u64; 3], usize) {
    let mut a: Vec<u64> = mdp
        .arrivals_per_state()
        .into_iter()
        .zip(&mdp.states)
        .filter(|(_, s)| s.decision_point > 0)
        .map(|(n, _)| n)
        .collect();
    a.sort_unstable();
    let under = a.iter().filter(|&&n| n < 100).count();
    match (a.first(), a.last()) {
        (Some(&lo), Some(&hi)) => ([lo, a[a.len() / 2], hi], under),
        _ => ([0; 3], 0),
    }
}
