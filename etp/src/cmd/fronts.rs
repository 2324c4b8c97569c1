//! `etp fronts DIR…`: what the radio costs. The fronts of several syntheses
//! of one scenario (e.g. `etp synthesize --loss 0`, `--loss 0.1`, `--loss 0.3`,
//! and `--loss 0.3 --estimator naive`) on one figure: for each, the least
//! expected energy per episode that reaches each P_tar with P_coll at most
//! the bound (docs/MODEL.md §5 and §8), mixtures of its vertices included.

use crate::output::read_front;
use crate::output::read_mdp;
use anyhow::{Context, Result, bail};
use etp_shared::radio::RadioOverride;
use etp_synthesis::pareto::ParetoFront;
use etp_synthesis::pareto::select::{Request, select};
use serde_json::json;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Synthesis directories (each written by `etp synthesize`) of one scenario.
    #[arg(required = true, num_args = 1..)]
    pub dirs: Vec<PathBuf>,
    /// The bound on P_coll every curve respects (default: none).
    #[arg(long, value_name = "P")]
    pub max_collision: Option<f64>,
    /// Points per curve (P_tar targets, evenly spaced).
    #[arg(long, default_value_t = 60)]
    pub points: usize,
    /// Figure file stem: writes STEM.png and STEM.svg.
    #[arg(short = 'o', long = "out", default_value = "fronts")]
    pub out: PathBuf,
    /// Overwrite existing figure files.
    #[arg(long)]
    pub force: bool,
    /// Print the curves as JSON on stdout (the figure is still written).
    #[arg(long)]
    pub json: bool,
}

pub use etp_figures::Curve;

pub fn run(a: Args) -> Result<()> {
    if let Some(c) = a.max_collision
        && !(0.0..=1.0).contains(&c)
    {
        bail!("--max-collision must lie in [0, 1], got {c}");
    }
    if a.points < 2 {
        bail!("--points must be at least 2, got {}", a.points);
    }
    let stem = a.out.clone();
    for p in [stem.with_extension("png"), stem.with_extension("svg")] {
        crate::output::refuse_existing(&p, a.force)?;
    }
    let mut fronts: Vec<(PathBuf, ParetoFront, String)> = Vec::new();
    for dir in &a.dirs {
        let (mdp, text) = read_mdp(dir)?;
        let front = read_front(dir, &mdp)?;
        let radio = channel_of(&front, text.as_deref())
            .with_context(|| format!("the radio of {}", dir.display()))?;
        if let Some((d0, f0, _)) = fronts.first()
            && f0.scenario_hash != front.scenario_hash
        {
            bail!(
                "{} is a front of scenario `{}`, {} of `{}`: compare fronts of one scenario",
                dir.display(),
                front.scenario_name,
                d0.display(),
                f0.scenario_name
            );
        }
        fronts.push((dir.clone(), front, radio));
    }
    let curves: Vec<Curve> = fronts
        .iter()
        .map(|(dir, f, radio)| Curve {
            dir: dir.clone(),
            radio: radio.clone(),
            points: least_energy_curve(f, a.max_collision, a.points),
        })
        .collect();
    let name = fronts[0].1.scenario_name.clone();
    etp_figures::fronts_plot(&name, &curves, a.max_collision, &stem)?;
    if a.json {
        let v = json!({
            "scenario": name,
            "max_collision": a.max_collision,
            "fronts": curves.iter().map(|c| json!({
                "dir": c.dir,
                "radio": c.radio,
                "points": c.points.iter().map(|(t, e)| json!({"p_target": t, "energy": e})).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "files": [stem.with_extension("png"), stem.with_extension("svg")],
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        for c in &curves {
            match (c.points.first(), c.points.last()) {
                (Some(lo), Some(hi)) => println!(
                    "{:<40} P_tar {:.4} at energy {:.1} … {:.4} at {:.1}  ({})",
                    c.radio,
                    lo.0,
                    lo.1,
                    hi.0,
                    hi.1,
                    c.dir.display()
                ),
                _ => println!(
                    "{:<40} no strategy within the P_coll bound  ({})",
                    c.radio,
                    c.dir.display()
                ),
            }
        }
        println!(
            "wrote {} and {}",
            stem.with_extension("png").display(),
            stem.with_extension("svg").display()
        );
    }
    Ok(())
}

/// The channel a front was synthesized under (the override rule of
/// docs/MODEL.md §8.6 without options): its recorded radio, else its
/// scenario text's own.
fn channel_of(front: &ParetoFront, scenario_text: Option<&str>) -> Result<String> {
    let own = match scenario_text {
        Some(t) => etp_shared::scenario::Scenario::from_toml(t)?,
        None => etp_shared::scenario::Scenario::builtin(&front.scenario_name)?,
    };
    let names: Vec<String> = own.sensors.iter().map(|s| s.name.clone()).collect();
    let radio = own
        .radio
        .for_use(front.radio.as_ref(), &RadioOverride::default())?;
    Ok(radio.describe(&names))
}

/// Least energy for `points` P_tar targets, from the lowest P_tar of a
/// vertex within the bound to the highest reachable within it (the LP of
/// `etp strategy --min-target`, over mixtures of the vertices).
pub fn least_energy_curve(
    front: &ParetoFront,
    max_collision: Option<f64>,
    points: usize,
) -> Vec<(f64, f64)> {
    let within = |p: f64| max_collision.is_none_or(|c| p <= c + 1e-12);
    let targets: Vec<f64> = front
        .vertices
        .iter()
        .map(|v| &v.objectives)
        .filter(|o| within(o.p_collision))
        .map(|o| o.p_target)
        .collect();
    let Some(lo) = targets.iter().copied().reduce(f64::min) else {
        return Vec::new();
    };
    // The highest P_tar within the bound may need a mixture: find it by the LP.
    let reachable = |t: f64| {
        select(
            front,
            Request::MinTarget {
                min_target: t,
                max_collision,
            },
        )
        .ok()
    };
    let (mut ok, mut bad) = (lo, 1.0 + 1e-9);
    if reachable(1.0).is_some() {
        ok = 1.0;
    } else {
        for _ in 0..40 {
            let mid = 0.5 * (ok + bad);
            if reachable(mid).is_some() {
                ok = mid;
            } else {
                bad = mid;
            }
        }
    }
    let hi = ok;
    (0..points)
        .filter_map(|i| {
            let t = lo + (hi - lo) * i as f64 / (points - 1) as f64;
            reachable(t).map(|s| (t, s.predicted.energy))
        })
        .collect()
}
