//! The Pareto step of `etp synthesize`: front.json, the front plot, and the
//! scenario text beside the MDP (so strategies made from DIR are self-contained).

use crate::error::{Context, Result};
use crate::output::write_new;
use etp_shared::radio::Radio;
use etp_synthesis::certify::front::{FRONT_CONFIDENCE, certified_front};
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::{ParetoFront, compute_front};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the Pareto step wrote and measured.
#[derive(Debug, Clone)]
pub struct FrontReport {
    pub front: ParetoFront,
    pub seconds: f64,
    pub files: Vec<PathBuf>,
}

/// Compute the front of `mdp` (and of a Method 1 MDP, attached as a baseline)
/// and write `front.json`, `front.png`, `front.svg` and `scenario.toml` into `dir`.
/// `radio`: the channel the MDP was sampled under when it is not the
/// scenario text's own (recorded in the front, and so in its strategies).
pub fn write_front(
    dir: &Path,
    mdp: &Mdp,
    method1: Option<&Mdp>,
    scenario_text: &str,
    radio: Option<&Radio>,
    force: bool,
    exec: &Executor,
) -> Result<FrontReport> {
    let start = Instant::now();
    let mut front =
        compute_front(mdp, CostModel::Counted).computing("computing the Pareto front")?;
    front.radio = radio.cloned();
    let seconds = start.elapsed().as_secs_f64();
    front.certified = Some(
        certified_front(mdp, &front, CostModel::Counted, FRONT_CONFIDENCE)
            .computing("certifying the front")?,
    );
    if let Some(m1) = method1 {
        let f1 = compute_front(m1, CostModel::Counted).computing("computing the Method 1 front")?;
        front.kf_convergence = Some(Box::new(f1));
    }
    let json_path = dir.join("front.json");
    write_new(exec, &json_path, front.to_json().as_bytes(), force)?;
    let scenario_path = dir.join("scenario.toml");
    write_new(exec, &scenario_path, scenario_text.as_bytes(), true)?;
    let stem = dir.join("front");
    if exec.is_root() {
        etp_figures::front_plot(&front, &stem)?;
    }
    Ok(FrontReport {
        front,
        seconds,
        files: vec![
            json_path,
            stem.with_extension("png"),
            stem.with_extension("svg"),
            scenario_path,
        ],
    })
}

/// A short human summary of a front.
pub fn describe(front: &ParetoFront) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "Pareto front: {} vertices, {} facets ({} weighted optimisations, {} hull rounds) on {} states / {} transitions",
        front.vertices.len(),
        front.facets.len(),
        front.optimisations,
        front.rounds,
        front.mdp_states,
        front.mdp_transitions
    );
    let _ = writeln!(
        o,
        "  a sample of the vertices (all of them are in front.json):\n  {:>4} {:>10} {:>9} {:>9}",
        "#", "energy", "P_tar", "P_coll"
    );
    let n = front.vertices.len();
    let shown: std::collections::BTreeSet<usize> = (0..12.min(n))
        .map(|i| i * n.saturating_sub(1) / 11)
        .chain(front.max_target_vertex())
        .collect();
    for (k, v) in front
        .vertices
        .iter()
        .enumerate()
        .filter(|(k, _)| shown.contains(k))
    {
        let x = &v.objectives;
        let _ = writeln!(
            o,
            "  {k:>4} {:>10.2} {:>8.2}% {:>8.2}%",
            x.energy,
            100.0 * x.p_target,
            100.0 * x.p_collision
        );
    }
    let _ = writeln!(o, "  baselines:");
    for b in &front.baselines {
        let x = &b.objectives;
        let _ = writeln!(
            o,
            "  {:>20} {:>10.2} {:>8.2}% {:>8.2}%",
            b.label,
            x.energy,
            100.0 * x.p_target,
            100.0 * x.p_collision
        );
    }
    o
}
