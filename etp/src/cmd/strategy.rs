//! `etp strategy DIR (--min-target P [--max-collision C] | --max-energy E |
//! --vertex K)`: select a strategy on DIR's MDP and predict it on its own
//! beliefs; by default the request loop of docs/MODEL.md §7.4 (select,
//! rebuild on the strategy's own pools R times, tighten the request to the
//! MDP by the measured gap while the prediction misses it) — the strategy
//! you asked for, with the prediction etp stands by. `--confidence L`
//! selects on certified bounds in the same loop; `--quick` is the fast,
//! biased exploration path (no prediction stored). `etp strategy evaluate
//! STRATEGY DIR` predicts a given strategy on DIR's settings.

use anyhow::{Result, bail};
use clap::ArgGroup;
use std::path::PathBuf;

mod certified;
mod evaluate;
mod front;
mod quick;
mod select;

use crate::prediction_args::{CheckArgs, RebuildArgs, RequestLoopArgs};
use etp_pipeline::output::write_new;
use etp_pipeline::predictions;
use etp_pipeline::selection::DEFAULT_LEVEL;
use etp_pipeline::synthesis_dir::Synthesis;
use etp_shared::strategy::Strategy;
use etp_synthesis::exec::Executor;
use serde_json::json;

/// `etp strategy` exits with this code when the request is out of reach:
/// the best strategy the loop could stand behind was written and reported
/// (with its prediction, which misses the request).
pub const EXIT_OUT_OF_REACH: u8 = 7;

const EXIT_CODES: &str = "Exit codes: 0 the strategy was written and its prediction meets the \
request (each bound holds for the prediction itself); 7 the request is out of reach: no round's prediction met it, the \
best strategy found was written with its prediction and the report says by how much it misses; \
1 an error (nothing written); 2 a bad command line.";

#[derive(Debug, clap::Args)]
#[command(
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = EXIT_CODES,
    group(ArgGroup::new("request").required(true).args(["min_target", "max_energy", "vertex"]))
)]
pub struct Args {
    #[command(subcommand)]
    pub verb: Option<Verb>,
    /// Output directory of `etp synthesize` (holds mdp.bin and front.json).
    #[arg(required = true)]
    pub dir: Option<PathBuf>,
    /// Least energy with P_tar ≥ P (P in [0, 1]).
    #[arg(long, value_name = "P", value_parser = crate::input::probability)]
    pub min_target: Option<f64>,
    /// With --min-target: also P_coll ≤ C (C in [0, 1]).
    #[arg(long, value_name = "C", requires = "min_target", value_parser = crate::input::probability)]
    pub max_collision: Option<f64>,
    /// Highest P_tar with expected energy per episode ≤ E (E ≥ 0, in the
    /// scenario's energy unit: the sum of the transmission costs `c_m` of an
    /// episode, docs/MODEL.md §6).
    #[arg(long, value_name = "E", value_parser = energy)]
    pub max_energy: Option<f64>,
    /// Vertex K of the front (0 = least energy; see front.json), predicted
    /// on its rebuilds (no loop: a vertex is not a request).
    #[arg(long, value_name = "K")]
    pub vertex: Option<usize>,
    /// With --min-target: select on certified bounds at this level (in
    /// (0, 1), e.g. 0.95), in the request loop: a round meets the request when the
    /// bounds certified on its first on-policy rebuild do. Without
    /// --min-target only the level of the reported bounds (default 0.95).
    #[arg(long, value_name = "LEVEL", value_parser = level)]
    pub confidence: Option<f64>,
    /// With --confidence and --min-target: first add samples to DIR's MDP on
    /// the certified strategy's support (doubling them, at most
    /// --refine-rounds times) until its certified P_tar gap is ≤ G (a
    /// probability, G > 0); writes DIR/mdp-refined.bin, on which the loop
    /// selects.
    #[arg(long, value_name = "G", requires_all = ["confidence", "min_target"],
          value_parser = crate::values::positive)]
    pub refine_gap: Option<f64>,
    /// Rounds of sample allocation at most (each re-runs the abstraction).
    #[arg(long, default_value_t = 3, requires = "refine_gap")]
    pub refine_rounds: u32,
    #[command(flatten)]
    pub request_loop: RequestLoopArgs,
    #[command(flatten)]
    pub check: CheckArgs,
    /// Fast exploration: select on DIR's MDP and stop. Its values there
    /// (selection-time, certified, and cross-fitted when DIR was synthesized
    /// with --holdout-samples) are biased — the optimiser's
    /// pick and other strategies' beliefs in the pools — and stored only as
    /// diagnostics: the file has no `predicted` (`etp strategy evaluate`
    /// predicts it later).
    #[arg(long, conflicts_with_all = ["rounds", "replicates", "refine_gap"])]
    pub quick: bool,
    #[command(flatten)]
    pub out: OutArgs,
}

/// Where the strategy goes and how the report is printed.
#[derive(Debug, Clone, clap::Args)]
pub struct OutArgs {
    /// Where to write the strategy (default DIR/strategy.json; its folder
    /// must exist).
    #[arg(short = 'o', long = "out", alias = "output")]
    pub output: Option<PathBuf>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

impl OutArgs {
    /// A strategy file the user named goes into a folder that exists: a
    /// mistyped `-o` is refused by name before any work, not created.
    pub fn check_folder(&self) -> Result<()> {
        if let Some(path) = &self.output {
            etp_files::write::existing_folder_of(path, "-o")?;
        }
        Ok(())
    }

    /// Writes `strategy` to `syn`'s output (rank 0 of `exec`); an existing
    /// file is replaced only with `--force`.
    pub fn write(&self, exec: &Executor, syn: &Synthesis, strategy: &Strategy) -> Result<()> {
        write_new(exec, &syn.output, strategy.to_json().as_bytes(), self.force)?;
        Ok(())
    }
}

impl CheckArgs {
    /// The aggregation check asked for (none at 0 episodes), stored in
    /// `strategy`'s predictions.
    pub fn store_aggregation_check(
        &self,
        strategy: &mut Strategy,
        quiet: bool,
        exec: &Executor,
    ) -> Result<()> {
        if self.aggregation_check > 0 {
            strategy.predictions.aggregation = predictions::aggregation_check(
                strategy,
                self.aggregation_check,
                &etp_pipeline::progress::Progress::new(quiet),
                exec,
            )?;
        }
        Ok(())
    }
}

/// The fields a `--json` report of a written strategy opens with: the
/// file, its label, the verdict and its predictions.
fn report_fields(
    syn: &Synthesis,
    strategy: &Strategy,
    verdict: &str,
) -> serde_json::Map<String, serde_json::Value> {
    let mut m = serde_json::Map::new();
    m.insert("strategy".into(), json!(syn.output));
    m.insert("label".into(), json!(strategy.provenance.label));
    m.insert("verdict".into(), json!(verdict));
    m.extend(predictions::json_fields(strategy));
    m
}

#[derive(Debug, clap::Subcommand)]
pub enum Verb {
    /// Predict a given strategy (same ω, states, bins) on its own beliefs:
    /// DIR's abstraction rebuilt R times on its pools and thresholds, every
    /// prediction of `etp strategy` from the rebuilds.
    Evaluate(EvaluateArgs),
    /// The predicted front: for requests spread over the P_tar range DIR's
    /// MDP reaches, the strategy `etp strategy DIR --min-target P` returns
    /// and its prediction (± 95 %), stored in DIR/front.json (`predicted`)
    /// and drawn over the MDP's selection-time front in DIR/front.png.
    Front(FrontArgs),
}

#[derive(Debug, clap::Args)]
pub struct FrontArgs {
    /// Output directory of `etp synthesize` (its front.json gains the curves).
    pub dir: PathBuf,
    /// Requests per curve (2..=64), evenly spaced over the MDP's P_tar range
    /// (both ends included).
    #[arg(long, value_name = "K", default_value_t = etp_synthesis::predict::front::DEFAULT_POINTS,
          value_parser = crate::values::whole::<usize>(2, Some(64)))]
    pub points: usize,
    /// Bounds on P_coll, one curve each (repeat or separate by commas;
    /// default: one curve without a bound).
    #[arg(long, value_name = "C", value_delimiter = ',', value_parser = crate::input::probability)]
    pub max_collision: Vec<f64>,
    #[command(flatten)]
    pub request_loop: RequestLoopArgs,
    /// Print the curves as JSON (the files are still written).
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, clap::Args)]
pub struct EvaluateArgs {
    /// A strategy.json (of DIR's scenario and thresholds).
    pub strategy: PathBuf,
    /// The synthesis whose settings and seed the rebuilds take.
    pub dir: PathBuf,
    /// Level of the certified bounds, in (0, 1).
    #[arg(long, value_name = "LEVEL", default_value_t = DEFAULT_LEVEL, value_parser = level)]
    pub confidence: f64,
    #[command(flatten)]
    pub rebuilds: RebuildArgs,
    #[command(flatten)]
    pub check: CheckArgs,
    #[command(flatten)]
    pub out: OutArgs,
}

fn energy(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("must be a finite number ≥ 0, got {v}"))
    }
}

fn level(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if v > 0.0 && v < 1.0 {
        Ok(v)
    } else {
        Err(format!("must lie strictly between 0 and 1, got {v}"))
    }
}

/// The request of the command line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    Goal(etp_synthesis::predict::request::Goal),
    Vertex(usize),
}

impl Request {
    pub fn label(&self, certified: Option<f64>) -> String {
        match self {
            Self::Goal(goal) => etp_pipeline::selection::goal_label(*goal, certified),
            Self::Vertex(k) => format!("vertex {k} of the front"),
        }
    }
}

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    match &a.verb {
        Some(Verb::Evaluate(e)) => return evaluate::run(e, exec),
        Some(Verb::Front(f)) => return front::run(f, exec),
        None => {}
    }
    a.out.check_folder()?;
    use etp_synthesis::predict::request::Goal;
    let request = match (a.min_target, a.max_energy, a.vertex) {
        (Some(min_target), None, None) => Request::Goal(Goal::MinTarget {
            min_target,
            max_collision: a.max_collision,
        }),
        (None, Some(max_energy), None) => Request::Goal(Goal::MaxEnergy { max_energy }),
        (None, None, Some(k)) => Request::Vertex(k),
        // The parser's group admits exactly one.
        _ => bail!("give exactly one of --min-target, --max-energy, --vertex"),
    };
    if a.quick {
        quick::run(&a, request, exec)
    } else {
        select::run(&a, request, exec)
    }
}
