//! The aggregation check `etp synthesize` runs after building the MDP
//! (`--aggregation-episodes`, `--aggregation-alpha`; docs/MODEL.md §7.3 and
//! `etp_synthesis::abstraction::aggregation`): which regions lump beliefs
//! with different futures.

use crate::progress::Progress;
use etp_shared::scenario::Scenario;
use etp_synthesis::abstraction::aggregation::{self, AggregationReport};
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::Mdp;
use std::fmt::Write;

/// Flags listed in the text report (all of them are in `--json`).
const SHOWN: usize = 12;

/// Run the check on `exec` (`None` when `episodes` is 0 or the MDP has no regions).
pub fn measure(
    scenario: &Scenario,
    mdp: &Mdp,
    episodes: u64,
    alpha: f64,
    progress: &Progress,
    exec: &Executor,
) -> crate::error::Result<Option<(AggregationReport, f64)>> {
    if episodes == 0 {
        return Ok(None);
    }
    let pb = progress.bar(exec, episodes, "aggregation check");
    let started = std::time::Instant::now();
    let work = exec.work(|k| pb.inc(k));
    let r = aggregation::measure(scenario, mdp, episodes, mdp.seed, alpha, &work)?;
    pb.finish_and_clear();
    Ok(r.map(|r| (r, started.elapsed().as_secs_f64())))
}

/// The text report.
pub fn describe(r: &AggregationReport, mdp: &Mdp, seconds: f64) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "  aggregation check ({} episodes, random δ, seed {}, {:.2} s): {} of {} tested state-actions ({} tests; {} too thin) split significantly at FDR {} → {} flagged states",
        r.episodes,
        r.seed,
        seconds,
        {
            let mut g: Vec<(u32, u16)> = r.flags.iter().map(|f| (f.state, f.action)).collect();
            g.sort_unstable();
            g.dedup();
            g.len()
        },
        r.groups_tested,
        r.tests,
        r.groups_thin,
        r.alpha,
        r.flagged_states.len()
    );
    for f in r.flags.iter().take(SHOWN) {
        let region = mdp
            .states
            .get(f.state as usize)
            .map_or_else(String::new, |s| s.region.to_string());
        let _ = writeln!(
            o,
            "    dp {} state {} [{}] δ = {} split on {}: {} segments, p = {:.1e} (adjusted {:.1e}), halves differ by TV {:.3}, from pooled by ≤ {:.3}",
            f.decision_point,
            f.state,
            region,
            mdp.deltas
                .get(usize::from(f.action))
                .copied()
                .unwrap_or(f64::NAN),
            r.features.get(f.feature).map_or("?", String::as_str),
            f.segments,
            f.p,
            f.p_adjusted,
            f.tv_halves,
            f.tv_pooled
        );
    }
    if r.flags.len() > SHOWN {
        let _ = writeln!(o, "    … {} more (--json lists all)", r.flags.len() - SHOWN);
    }
    o
}
