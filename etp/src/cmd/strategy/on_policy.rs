//! `etp strategy DIR … --on-policy`: the strategy just selected, predicted
//! again on a rebuild of the abstraction whose pools are its own (true
//! state, belief) pairs and whose states simulate only its own thresholds
//! (docs/MODEL.md §7.3) — in one command what `etp synthesize --pool-policy`
//! and `etp strategy --evaluate` do in two, with DIR's own settings and
//! seed, so both give the same numbers. The rebuilt MDP is not kept.

use crate::progress;
use anyhow::{Context, Result};
use etp_shared::strategy::Strategy;
use etp_synthesis::abstraction;
use etp_synthesis::mdp::Mdp;
use serde_json::json;
use std::time::Instant;

/// The rebuild and what it cost.
pub struct Rebuilt {
    pub mdp: Mdp,
    pub seconds: f64,
}

impl Rebuilt {
    /// What `--json` reports of the rebuild.
    pub fn json(&self) -> serde_json::Value {
        json!({
            "states": self.mdp.states.len(),
            "choices": self.mdp.states.iter().map(|s| s.choices.len()).sum::<usize>(),
            "segments": self.mdp.total_segments,
            "seconds": self.seconds,
        })
    }

    /// One line for the text report.
    pub fn describe(&self) -> String {
        format!(
            "  on its own pools: rebuilt with {} states, {} segments in {:.1} s (docs/MODEL.md §7.3); the predictions below are the rebuild's\n",
            self.mdp.states.len(),
            self.mdp.total_segments,
            self.seconds
        )
    }
}

/// Rebuild `mdp`'s abstraction (same settings, same seed) with the pools
/// drawn on `strategy`, carrying the true state, on its thresholds only.
pub fn rebuild(strategy: &Strategy, mdp: &Mdp, quiet: bool) -> Result<Rebuilt> {
    let scenario = strategy
        .scenario()
        .context("--on-policy needs the strategy's scenario")?;
    let params = abstraction::params_of(mdp);
    let pb = progress::bar(
        abstraction::progress_total(&scenario, &params),
        "on-policy rebuild",
        quiet,
    );
    let started = Instant::now();
    let rebuilt =
        abstraction::build_on_policy(&scenario, &params, strategy, true, true, &|k| pb.inc(k))
            .context("--on-policy: rebuilding on the strategy's own pools")?;
    pb.finish_and_clear();
    rebuilt
        .check()
        .context("the rebuilt MDP failed its own consistency check (a bug)")?;
    Ok(Rebuilt {
        mdp: rebuilt,
        seconds: started.elapsed().as_secs_f64(),
    })
}
