//! `etp fronts DIR…`: what the radio or the trigger family costs. The
//! fronts of several syntheses of one scenario (e.g. `etp synthesize --loss
//! 0`, `--loss 0.3`, or `--trigger box`, `--trigger stochastic`) on one
//! figure: for each, the least expected energy per episode that reaches each
//! P_tar with P_coll at most the bound (docs/MODEL.md §5, §8 and §9),
//! mixtures of its vertices included, and dashed its certified curve (the
//! certified front of front.json); one panel per `--max-collision` bound.
//! "One scenario" is the scenario without its trigger family: the family
//! changes the content hash, nothing else does here.

use anyhow::Result;
use etp_pipeline::output::{read_front, read_mdp};
use etp_pipeline::synthesis_dir::{Identity, check_one_scenario, identity, labels};
use etp_synthesis::pareto::ParetoFront;
use etp_synthesis::pareto::select::{Request, select};
use serde_json::{Value, json};
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Synthesis directories (each written by `etp synthesize`) of one
    /// scenario, under any radio options and trigger families.
    #[arg(required = true, num_args = 1..)]
    pub dirs: Vec<PathBuf>,
    /// Bounds on P_coll, one panel each (repeat the option or separate by
    /// commas; default: one panel without a bound).
    #[arg(long, value_name = "P", value_delimiter = ',', value_parser = crate::input::probability)]
    pub max_collision: Vec<f64>,
    /// Points per curve (P_tar targets, evenly spaced; at least 2).
    #[arg(long, value_name = "K", default_value_t = 60, value_parser = crate::values::whole::<usize>(2, None))]
    pub points: usize,
    /// Figure file stem: writes STEM.png and STEM.svg (its folder must exist).
    #[arg(
        short = 'o',
        long = "out",
        value_name = "STEM",
        default_value = "fronts"
    )]
    pub out: PathBuf,
    /// Overwrite existing figure files.
    #[arg(long)]
    pub force: bool,
    /// Print the curves as JSON on stdout (the figure is still written).
    #[arg(long)]
    pub json: bool,
}

use etp_figures::{Curve, Panel};

/// One synthesis directory as the figure needs it.
struct Source {
    dir: PathBuf,
    front: ParetoFront,
    id: Identity,
}

pub fn run(a: Args) -> Result<()> {
    let stem = a.out.clone();
    etp_files::write::existing_folder_of(&stem, "-o")?;
    for p in [stem.with_extension("png"), stem.with_extension("svg")] {
        etp_files::write::refuse_existing(&p, a.force)?;
    }
    let mut sources: Vec<Source> = Vec::new();
    for dir in &a.dirs {
        let (mdp, text) = read_mdp(dir)?;
        let front = read_front(dir, &mdp)?;
        let id = identity(dir, &front, text.as_deref())?;
        sources.push(Source {
            dir: dir.clone(),
            front,
            id,
        });
    }
    check_one_scenario(
        &sources
            .iter()
            .map(|s| (s.dir.as_path(), s.front.scenario_name.as_str(), &s.id))
            .collect::<Vec<_>>(),
    )?;
    let labels = labels(
        &sources
            .iter()
            .map(|s| (s.dir.as_path(), &s.id))
            .collect::<Vec<_>>(),
    );
    let bounds: Vec<Option<f64>> = if a.max_collision.is_empty() {
        vec![None]
    } else {
        a.max_collision.iter().copied().map(Some).collect()
    };
    let panels: Vec<Panel> = bounds
        .iter()
        .map(|&bound| Panel {
            max_collision: bound,
            curves: sources
                .iter()
                .zip(&labels)
                .map(|(s, label)| Curve {
                    dir: s.dir.clone(),
                    label: label.clone(),
                    points: least_energy_curve(&s.front, bound, a.points),
                    certified: s
                        .front
                        .certified
                        .as_ref()
                        .map(|c| c.least_energy(bound))
                        .unwrap_or_default(),
                    predicted: predicted_marks(&s.front, bound),
                })
                .collect(),
        })
        .collect();
    let name = sources[0].front.scenario_name.clone();
    let families_differ = sources
        .iter()
        .any(|s| s.id.trigger != sources[0].id.trigger);
    let what = if families_differ {
        "trigger families"
    } else {
        "the radio"
    };
    etp_figures::fronts_plot(&name, what, &panels, &stem)?;
    let files = [stem.with_extension("png"), stem.with_extension("svg")];
    if a.json {
        let pairs = |p: &[(f64, f64)]| -> Vec<Value> {
            p.iter()
                .map(|(t, e)| json!({"p_target": t, "energy": e}))
                .collect()
        };
        let v = json!({
            "scenario": name,
            "panels": panels.iter().map(|p| json!({
                "max_collision": p.max_collision,
                "fronts": p.curves.iter().zip(&sources).map(|(c, s)| json!({
                    "dir": c.dir,
                    "label": c.label,
                    "radio": s.id.radio,
                    "trigger": s.id.trigger.name(),
                    "epsilon_energy": s.front.epsilon_energy,
                    "certified_confidence": s.front.certified.as_ref().map(|c| c.confidence),
                    "points": pairs(&c.points),
                    "certified": pairs(&c.certified),
                    "predicted": c.predicted.iter().map(|m| json!({
                        "p_target": m.p_target, "p_target_ci95": m.p_target_ci95,
                        "energy": m.energy, "energy_ci95": m.energy_ci95, "met": m.met,
                    })).collect::<Vec<_>>(),
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "files": files,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        for p in &panels {
            if bounds.len() > 1 || p.max_collision.is_some() {
                match p.max_collision {
                    Some(c) => println!("P_coll ≤ {c}:"),
                    None => println!("any P_coll:"),
                }
            }
            for c in &p.curves {
                match (c.points.first(), c.points.last()) {
                    (Some(lo), Some(hi)) => println!(
                        "{:<40} P_tar {:.4} at energy {:.1} … {:.4} at {:.1}; certified up to P_tar {}  ({})",
                        c.label,
                        lo.0,
                        lo.1,
                        hi.0,
                        hi.1,
                        c.certified
                            .last()
                            .map_or("n/a".into(), |x| format!("{:.4} at {:.1}", x.0, x.1)),
                        c.dir.display()
                    ),
                    _ => println!(
                        "{:<40} no strategy within the P_coll bound  ({})",
                        c.label,
                        c.dir.display()
                    ),
                }
            }
        }
        println!("wrote {} and {}", files[0].display(), files[1].display());
    }
    Ok(())
}

/// The predicted front of `front` under `bound` (front.json `predicted`,
/// written by `etp strategy front`), as the figure draws it.
fn predicted_marks(front: &ParetoFront, bound: Option<f64>) -> Vec<etp_figures::PredictedMark> {
    front
        .predicted
        .iter()
        .filter(|c| c.max_collision == bound)
        .flat_map(|c| &c.points)
        .map(|p| etp_figures::PredictedMark {
            p_target: p.predicted.p_target,
            energy: p.predicted.energy,
            p_target_ci95: p.predicted_ci95.p_target,
            energy_ci95: p.predicted_ci95.energy,
            met: p.met(),
        })
        .collect()
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
