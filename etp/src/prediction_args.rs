//! The options that say how a strategy is predicted and how the request
//! loop runs, defined once for every command that predicts (`etp strategy`,
//! `strategy front`, `strategy evaluate`, `etp compare`).

use etp_pipeline::predictions::AGGREGATION_CHECK_EPISODES;

/// How a strategy is predicted: its on-policy rebuilds.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct RebuildArgs {
    /// On-policy rebuilds of a prediction (seeds DIR's + 0 … R − 1): their
    /// mean cross-fitted value with a Student-t ± over their spread, which
    /// covers the rebuilds' whole Monte Carlo (docs/MODEL.md §7.3); R in 2..=64.
    #[arg(long, value_name = "R", default_value_t = etp_synthesis::predict::rebuild::DEFAULT_REPLICATES,
          value_parser = crate::values::whole::<u32>(2, Some(64)))]
    pub replicates: u32,
}

/// The request loop (`etp strategy`, `strategy front`, `compare`): each
/// round's prediction, and how many rounds at most.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct RequestLoopArgs {
    #[command(flatten)]
    pub rebuilds: RebuildArgs,
    /// Rounds of the request loop at most (1..=20).
    #[arg(long, value_name = "N", default_value_t = etp_synthesis::predict::request::DEFAULT_ROUNDS,
          value_parser = crate::values::whole::<u32>(1, Some(20)))]
    pub rounds: u32,
}

/// The check stored beside a prediction.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct CheckArgs {
    /// Episodes of the selection-time aggregation check: the strategy
    /// simulated in-process against its prediction (stored, printed,
    /// re-measured by `etp validate`); 0 = no check.
    #[arg(long, value_name = "N", default_value_t = AGGREGATION_CHECK_EPISODES)]
    pub aggregation_check: u64,
}
