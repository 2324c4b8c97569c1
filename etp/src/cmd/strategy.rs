//! `etp strategy DIR (--min-target P [--max-collision C] | --max-energy E | --vertex K)`:
//! the least-energy (or highest-target) point meeting the constraints, realised
//! as a memoryless randomised strategy, written as `strategy.json`.

use crate::output::{read_front, read_mdp, write_new};
use anyhow::{Context, Result, bail};
use clap::ArgGroup;
use etp_synthesis::pareto::select::{Request, occupation_lp_min_energy, realise, select};
use etp_synthesis::pareto::to_strategy;
use serde_json::json;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
#[command(group(ArgGroup::new("request").required(true).args(["min_target", "max_energy", "vertex"])))]
pub struct Args {
    /// Output directory of `etp synthesize` (holds mdp.bin and front.json).
    pub dir: PathBuf,
    /// Least energy with P_tar ≥ P.
    #[arg(long, value_name = "P")]
    pub min_target: Option<f64>,
    /// With --min-target: also P_coll ≤ C.
    #[arg(long, value_name = "C", requires = "min_target")]
    pub max_collision: Option<f64>,
    /// Highest P_tar with expected energy ≤ E.
    #[arg(long, value_name = "E")]
    pub max_energy: Option<f64>,
    /// Vertex K of the front (0 = least energy; see front.json).
    #[arg(long, value_name = "K")]
    pub vertex: Option<usize>,
    /// Where to write the strategy (default DIR/strategy.json).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Print the selection as JSON.
    #[arg(long)]
    pub json: bool,
}

fn probability(name: &str, v: f64) -> Result<f64> {
    if !(0.0..=1.0).contains(&v) {
        bail!("{name} must be a probability in [0, 1], got {v}");
    }
    Ok(v)
}

pub fn run(a: Args) -> Result<()> {
    let request = match (a.min_target, a.max_energy, a.vertex) {
        (Some(p), None, None) => Request::MinTarget {
            min_target: probability("--min-target", p)?,
            max_collision: a
                .max_collision
                .map(|c| probability("--max-collision", c))
                .transpose()?,
        },
        (None, Some(e), None) => {
            if !(e.is_finite() && e >= 0.0) {
                bail!("--max-energy must be a finite number ≥ 0, got {e}");
            }
            Request::MaxEnergy { max_energy: e }
        }
        (None, None, Some(k)) => Request::Vertex(k),
        _ => bail!("give exactly one of --min-target, --max-energy, --vertex"),
    };
    let (mdp, scenario_text) = read_mdp(&a.dir)?;
    let front = read_front(&a.dir, &mdp)?;
    let output = a
        .output
        .clone()
        .unwrap_or_else(|| a.dir.join("strategy.json"));
    let selection = select(&front, request).context("selecting a point on the front")?;
    let omega = realise(&mdp, &front, &selection);
    let label = match request {
        Request::MinTarget {
            min_target,
            max_collision,
        } => match max_collision {
            Some(c) => format!("least energy with P_tar ≥ {min_target} and P_coll ≤ {c}"),
            None => format!("least energy with P_tar ≥ {min_target}"),
        },
        Request::MaxEnergy { max_energy } => format!("highest P_tar with energy ≤ {max_energy}"),
        Request::Vertex(k) => format!("vertex {k} of the front"),
    };
    let mut strategy = to_strategy(&mdp, &omega, label.clone(), selection.predicted);
    strategy.scenario_toml = scenario_text;
    // Cross-check with the whole-MDP occupation LP (independent of the enumeration).
    let cross_check = match request {
        Request::MinTarget {
            min_target,
            max_collision,
        } => occupation_lp_min_energy(&mdp, front.cost_model, min_target, max_collision).ok(),
        _ => None,
    };
    write_new(&output, strategy.to_json().as_bytes(), a.force)?;
    let p = &selection.predicted;
    if a.json {
        let v = json!({
            "strategy": output, "label": label,
            "predicted": {"p_target": p.p_target, "p_collision": p.p_collision, "energy_mean": p.energy},
            "vertices": selection.weights.iter().map(|(k, w)| json!({"vertex": k, "weight": w})).collect::<Vec<_>>(),
            "occupation_lp_energy": cross_check,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("{label}");
        println!(
            "  predicted  P_tar {:.4}  P_coll {:.4}  energy {:.2}",
            p.p_target, p.p_collision, p.energy
        );
        for (k, w) in &selection.weights {
            let o = &front.vertices[*k].objectives;
            println!(
                "  vertex {k:>3} weight {w:.4}  (P_tar {:.4}, P_coll {:.4}, energy {:.2})",
                o.p_target, o.p_collision, o.energy
            );
        }
        if let Some(lp) = cross_check {
            println!(
                "  cross-check: occupation-measure LP over the whole MDP gives energy {lp:.4}"
            );
        }
        println!("wrote {}", output.display());
    }
    Ok(())
}
