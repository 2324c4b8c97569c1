//! `etp synthesize SCENARIO`: build the belief-space MDP by Monte Carlo
//! (docs/MODEL.md §4) and write `DIR/mdp.bin`.
//!
//! The work is `etp_pipeline::synthesize` (the MDP, the Method 1 baseline,
//! the Pareto step and the aggregation check), given the typed request
//! [`Args::request`] makes of the command line; [`run`] prints the report.

use crate::scenario_flags::{RadioArgs, TriggerArgs};
use anyhow::{Result, bail};
use etp_pipeline::aggregation;
use etp_pipeline::mdp_build::split;
use etp_pipeline::mdp_build::{MdpReport, MdpRequest};
use etp_pipeline::progress::Progress;
use etp_pipeline::synthesize::{
    DEFAULT_AGGREGATION_ALPHA, DEFAULT_AGGREGATION_EPISODES, SynthesisRequest, scenario_under,
    synthesize,
};
use etp_shared::discretization::BinCounts;
use etp_shared::scenario::Scenario;
use etp_synthesis::abstraction::split::SplitSettings;
use etp_synthesis::abstraction::{
    self, AbstractionParams, DEFAULT_LOOKAHEAD, DEFAULT_POOL_PER_REGION, DEFAULT_REST_BINS,
    DEFAULT_SAMPLES, Descriptor, default_kf_params,
};
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::{KfConvergenceParams, Method};
use std::path::PathBuf;

/// Method 2's belief descriptor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DescriptorArg {
    /// `workspace` for scenarios with a workspace map `[model] C`, else `per-axis`.
    Auto,
    /// The paper's per-axis (magnitude, angle) bins of all n eigen-axes of P.
    PerAxis,
    /// Per-axis bins of the workspace marginal C P Cᵀ plus coarse bins of the
    /// uncertainty C does not see (MODEL.md §7).
    Workspace,
}

impl From<DescriptorArg> for Descriptor {
    fn from(d: DescriptorArg) -> Self {
        match d {
            DescriptorArg::Auto => Descriptor::Auto,
            DescriptorArg::PerAxis => Descriptor::PerAxis,
            DescriptorArg::Workspace => Descriptor::WorkspaceMarginal,
        }
    }
}

/// Which abstraction to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// Method 2: discretized covariance regions (the paper's contribution).
    Discretized,
    /// Method 1: enforced KF convergence near each waypoint (N + 3 states).
    KfConvergence,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Discretized => Method::Discretized,
            MethodArg::KfConvergence => Method::KfConvergence,
        }
    }
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Built-in name (winding-2d, open-2d, superg-3d, inertia-2d, inertia-3d) or path to a scenario TOML.
    pub scenario: String,
    /// Abstraction method.
    #[arg(long, value_enum, default_value_t = MethodArg::Discretized)]
    pub method: MethodArg,
    /// Simulated segments per (state, action) (at least 1).
    #[arg(long, default_value_t = DEFAULT_SAMPLES, value_parser = crate::values::whole::<u32>(1, None))]
    pub samples: u32,
    /// Held-out segments per (state, action) on the selection MDP (stream
    /// `HOLDOUT`, independent of the main samples; default 0). They only add
    /// cross-fitted diagnostics (`etp strategy --quick`, front.json): the
    /// prediction `etp strategy` stands by comes from rebuilds, which always
    /// draw their own (as many as --samples). Each one doubles the
    /// simulation time; the MDP's states and main transitions are the same
    /// bits with or without them.
    #[arg(long)]
    pub holdout_samples: Option<u32>,
    /// Seed of the random streams (same seed, same mdp.bin bytes, any thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Log-uniform magnitude bins per eigenvalue (Method 2; at least 1).
    #[arg(long, value_name = "K", default_value_t = BinCounts::default().magnitude, value_parser = crate::values::whole::<u16>(1, Some(u16::MAX as u64)))]
    pub magnitude_bins: u16,
    /// Angle bins per eigenvector on [0, π/2] (Method 2; unused for repeated
    /// eigenvalues; at least 1).
    #[arg(long, value_name = "K", default_value_t = BinCounts::default().angle, value_parser = crate::values::whole::<u16>(1, Some(u16::MAX as u64)))]
    pub angle_bins: u16,
    /// Method 2's belief descriptor.
    #[arg(long, value_enum, default_value_t = DescriptorArg::Auto)]
    pub descriptor: DescriptorArg,
    /// Coarse log-uniform bins of tr(Π P Π), the uncertainty the workspace map
    /// does not see (`--descriptor workspace`; at least 1).
    #[arg(long, value_name = "K", default_value_t = DEFAULT_REST_BINS, value_parser = crate::values::whole::<u16>(1, Some(u16::MAX as u64)))]
    pub rest_bins: u16,
    /// Workspace descriptor: bin the workspace marginal predicted this many
    /// silent steps ahead, C F^h P F^hᵀ Cᵀ, so velocity uncertainty counts
    /// for what it will do to the position (0: the marginal now).
    #[arg(long, default_value_t = DEFAULT_LOOKAHEAD)]
    pub lookahead: u32,
    /// Workspace descriptor: where its magnitude bins lie.
    #[arg(long, value_enum, default_value_t = RangeArg::Arrivals)]
    pub range: RangeArg,
    /// Pool particles kept per region and decision point (at least 1).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_POOL_PER_REGION,
          value_parser = crate::values::whole::<u32>(1, None))]
    pub pool: u32,
    /// Method 1: distance to the waypoint at which the full KF switches on
    /// in the workspace's length unit, > 0 (default max(5·u_max, 2·eps_x)).
    #[arg(long, value_name = "D", value_parser = crate::values::positive)]
    pub eps_kf: Option<f64>,
    /// Method 1: covariance convergence tolerance ‖P − P_KF‖max
    /// in the state covariance's units, > 0 (default 1 % of the smallest
    /// ‖P_KF‖max over the sensors).
    #[arg(long, value_name = "TOL", value_parser = crate::values::positive)]
    pub eps_p: Option<f64>,
    /// Output directory (default `out/<scenario name>`).
    #[arg(short = 'o', long = "out", alias = "output")]
    pub out: Option<PathBuf>,
    /// Overwrite an existing mdp.bin.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Skip the Method 1 (KF convergence) baseline front next to Method 2's.
    #[arg(long)]
    pub no_kf_baseline: bool,
    /// Lump the states of each decision point that the samples cannot tell
    /// apart at level ALPHA: for every action a χ² test of their outcomes
    /// (successors by lump) and a z-test of their mean energies (docs/MODEL.md
    /// §7.3). ALPHA in (0, 1); a smaller ALPHA lumps more. Off by default.
    #[arg(long, value_name = "ALPHA", value_parser = crate::values::open_unit)]
    pub merge: Option<f64>,
    /// The radio the segments are sampled with (docs/MODEL.md §8).
    #[command(flatten)]
    pub radio: RadioArgs,
    /// The trigger family the segments are sampled with (docs/MODEL.md §9),
    /// written into DIR/scenario.toml (`box` said aloud: the scenario itself).
    #[command(flatten)]
    pub trigger: TriggerArgs,
    /// Aggregation check: episodes with random thresholds whose legs test, per
    /// region and action, whether the outcomes differ between the halves of
    /// the region split at the median of a finer belief feature (0: off).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_AGGREGATION_EPISODES)]
    pub aggregation_episodes: u64,
    /// Aggregation check: false discovery rate of the flagged splits, in (0, 1).
    #[arg(long, value_name = "ALPHA", default_value_t = DEFAULT_AGGREGATION_ALPHA,
          value_parser = crate::values::open_unit)]
    pub aggregation_alpha: f64,
    /// Adaptive splitting of the regions the aggregation test flags.
    #[command(flatten)]
    pub split: SplitArgs,
    /// Draw the pools on-policy (docs/MODEL.md §7.3): on this strategy's
    /// bins, each region's pool sampled from the arrivals weighted by the
    /// probability that the strategy brings a belief there. A strategy of a
    /// Method 2 synthesis of the same scenario (`etp strategy … -o FILE`).
    #[arg(long, value_name = "STRATEGY.json")]
    pub pool_policy: Option<PathBuf>,
    /// With --pool-policy: simulate every threshold at every state (by
    /// default only those the strategy uses there: all that `etp strategy
    /// evaluate` needs, the same segments for them, at a fraction of the
    /// cost). Needed to select other strategies on these pools.
    #[arg(long, requires = "pool_policy")]
    pub all_actions: bool,
}

/// `--range`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RangeArg {
    /// Per decision point, from the arrivals' smallest workspace eigenvalue to the 99.5 % quantile of their largest
    Arrivals,
    /// From P_KF to silent propagation at the largest δ (the paper's rule)
    Propagation,
}

/// The abstraction parameters of the command line.
pub fn params(a: &Args, s: &Scenario) -> Result<AbstractionParams> {
    let kf = match a.method {
        MethodArg::Discretized => {
            if a.eps_kf.is_some() || a.eps_p.is_some() {
                bail!("--eps-kf and --eps-p apply to --method kf-convergence only");
            }
            None
        }
        MethodArg::KfConvergence => {
            let d = default_kf_params(s);
            Some(KfConvergenceParams {
                eps_kf: a.eps_kf.unwrap_or(d.eps_kf),
                eps_p: a.eps_p.unwrap_or(d.eps_p),
            })
        }
    };
    Ok(AbstractionParams {
        method: a.method.into(),
        samples: a.samples,
        holdout_samples: a.holdout_samples.unwrap_or(0),
        seed: a.seed,
        bins: BinCounts {
            magnitude: a.magnitude_bins,
            angle: a.angle_bins,
        },
        pool_per_region: a.pool,
        kf,
        descriptor: a.descriptor.into(),
        rest_bins: a.rest_bins,
        lookahead: a.lookahead,
        range: match a.range {
            RangeArg::Arrivals => abstraction::RangeRule::Arrivals,
            RangeArg::Propagation => abstraction::RangeRule::Propagation,
        },
    })
}

/// The splitting options (docs/MODEL.md §7.3): the command line of
/// [`SplitSettings`].
#[derive(Debug, Clone, clap::Args)]
pub struct SplitArgs {
    /// Adaptive splitting: split at most N regions that the aggregation test
    /// flags (at the flagged covariance feature's median) and re-estimate the
    /// MDP, round by round (0: off; each split adds at most one state).
    #[arg(long, value_name = "N", default_value_t = SplitSettings::default().budget)]
    pub split_budget: u32,
    /// Adaptive splitting: at most R rounds (each one re-runs the Monte
    /// Carlo; at least 1).
    #[arg(long, value_name = "R", default_value_t = SplitSettings::default().rounds,
          value_parser = crate::values::whole::<u32>(1, None))]
    pub split_rounds: u32,
    /// Adaptive splitting: random-δ episodes per round for the test (at
    /// least 1).
    #[arg(long, value_name = "N", default_value_t = SplitSettings::default().episodes,
          value_parser = crate::values::whole::<u64>(1, None))]
    pub split_episodes: u64,
    /// Adaptive splitting: false discovery rate of a round's tests, in (0, 1).
    #[arg(long, value_name = "ALPHA", default_value_t = SplitSettings::default().alpha,
          value_parser = crate::values::open_unit)]
    pub split_alpha: f64,
}

impl SplitArgs {
    fn settings(&self) -> SplitSettings {
        SplitSettings {
            budget: self.split_budget,
            rounds: self.split_rounds,
            episodes: self.split_episodes,
            alpha: self.split_alpha,
        }
    }
}

impl Args {
    /// The MDP step's request: the scenario of the command line (its text
    /// under `--trigger`, then the radio options) and its parameters, run
    /// on `exec`.
    pub fn request(&self, exec: &Executor) -> Result<MdpRequest> {
        let (scenario, _) = load(self)?;
        Ok(MdpRequest {
            params: params(self, &scenario)?,
            scenario,
            out: self.out.clone(),
            force: self.force,
            merge: self.merge,
            split: self.split.settings(),
            pool_policy: self.pool_policy.clone(),
            all_actions: self.all_actions,
            progress: Progress::new(self.json),
            exec: exec.clone(),
        })
    }
}

/// A readable summary of the MDP step.
pub fn report_text(r: &MdpReport) -> String {
    let merge = match &r.merge {
        Some(m) => format!(
            "  lumped at α = {}: {} states → {} ({:?} per decision point before)\n",
            m.alpha, m.states_before, r.states, m.states_per_decision_point_before
        ),
        None => String::new(),
    };
    let merge = match &r.split {
        Some(s) => format!("{}{merge}", split::describe(s)),
        None => merge,
    };
    format!(
        "{} · {} · {} samples per state-action (+{} held out) · seed {}\n\
         \x20 wrote {}\n\
         \x20 states {} (+3 terminal) per decision point {:?}\n{}\
         \x20 samples per state {}–{} · arrivals per state min {} · median {} · max {} · {} states under 100\n\
         \x20 choices {} · transitions {}\n\
         \x20 segments {} · segment-steps {} · {:.2} s · {:.2} M steps/s on {} threads\n",
        r.scenario,
        r.method,
        r.samples,
        r.holdout_samples,
        r.seed,
        r.path.display(),
        r.states,
        r.states_per_decision_point,
        merge,
        r.samples_per_state[0],
        r.samples_per_state[1],
        r.arrivals_per_state[0],
        r.arrivals_per_state[1],
        r.arrivals_per_state[2],
        r.states_under_100_arrivals,
        r.choices,
        r.transitions,
        r.segments,
        r.segment_steps,
        r.seconds,
        r.segment_steps_per_second / 1e6,
        r.threads,
    )
}

/// The scenario of the command line: its text under `--trigger` (so that
/// the content hash is the family's), then the radio options.
fn load(a: &Args) -> Result<(Scenario, String)> {
    let (s, text) = scenario_under(&a.scenario, a.trigger.trigger)?;
    Ok((a.radio.apply(s)?, text))
}

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    let (_, text) = load(&a)?;
    let request = SynthesisRequest {
        mdp: a.request(exec)?,
        text,
        kf_baseline: !a.no_kf_baseline,
        aggregation_episodes: a.aggregation_episodes,
        aggregation_alpha: a.aggregation_alpha,
    };
    let done = synthesize(request)?;
    let built = &done.built;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&done.to_json())?);
    } else {
        print!("{}", report_text(&built.report));
        if let Some((r, secs)) = &done.aggregation {
            print!("{}", aggregation::describe(r, &built.mdp, *secs));
        }
        print!("{}", etp_pipeline::front::describe(&done.front.front));
        println!("  computed in {:.3} s", done.front.seconds);
        if built.mdp.policy_only() {
            let policy = a
                .pool_policy
                .as_deref()
                .map_or_else(|| "STRATEGY.json".into(), |p| p.display().to_string());
            println!(
                "  only the thresholds {policy} uses were simulated: this front is not the scenario's; \
                 `etp strategy evaluate {policy} DIR` (DIR the synthesis it was selected on) \
                 predicts that strategy from {} such rebuilds (--all-actions to select others on these pools)",
                etp_synthesis::predict::rebuild::DEFAULT_REPLICATES
            );
        }
        for f in &done.front.files {
            println!("  wrote {}", f.display());
        }
    }
    if let Some((dir, names)) = &done.stale {
        eprintln!(
            "moved {} (made from the replaced MDP) to {}",
            names.join(", "),
            dir.display()
        );
    }
    Ok(())
}
