//! `etp trigger-curves SCENARIO -o STEM`: the literature's plot of trigger
//! families (docs/MODEL.md §9). For each family and each threshold δ of the
//! scenario's `deltas`, `etp simulate`'s in-process episodes with the family
//! set (`--trigger`): the measured communication rate, the estimation error
//! (RMSE of ‖x − x̂‖ and NEES/n over the slots) and the family's closed-form
//! rate where it has one (`TriggerFamily::expected_rate`).

use crate::input::load_scenario_with_radio;
use crate::scenario_flags::{RadioArgs, parse_family};
use anyhow::{Result, bail};
use etp_figures::{FamilySeries, RatePoint};
use etp_pipeline::progress;
use etp_shared::stats::Estimate;
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::constant::simulate_constant;
use etp_synthesis::exec::Executor;
use serde_json::{Value, json};
use std::path::PathBuf;

/// Samples of a closed-form rate curve over [0, max δ].
const CLOSED_FORM_SAMPLES: usize = 120;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Built-in name (winding-2d, open-2d, superg-3d, inertia-2d, inertia-3d) or path to a scenario TOML.
    pub scenario: String,
    /// Trigger families to compare (comma-separated; default all five: box,
    /// stochastic, send-on-delta, variance, periodic).
    #[arg(long, value_name = "FAMILY", value_delimiter = ',', value_parser = parse_family)]
    pub families: Vec<TriggerFamily>,
    #[command(flatten)]
    pub sim: crate::input::EpisodeArgs,
    #[command(flatten)]
    pub radio: RadioArgs,
    /// Figure file stem: writes STEM.png and STEM.svg (its folder must exist).
    #[arg(
        short = 'o',
        long = "out",
        value_name = "STEM",
        default_value = "trigger-curves"
    )]
    pub out: PathBuf,
    /// Overwrite existing figure files.
    #[arg(long)]
    pub force: bool,
    /// Print the points as JSON on stdout (the figure is still written).
    #[arg(long)]
    pub json: bool,
}

/// One simulated (family, δ).
struct Measured {
    delta: f64,
    rate: Estimate,
    rate_model: Estimate,
    closed_form: Option<f64>,
    rmse: Estimate,
    nees: Estimate,
    p_target: Estimate,
    energy: Estimate,
}

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    let stem = a.out.clone();
    etp_files::write::existing_folder_of(&stem, "-o")?;
    for p in [stem.with_extension("png"), stem.with_extension("svg")] {
        etp_pipeline::output::refuse_existing(exec, &p, a.force)?;
    }
    let mut families: Vec<TriggerFamily> = Vec::new();
    let given = if a.families.is_empty() {
        TriggerFamily::ALL.to_vec()
    } else {
        a.families.clone()
    };
    for f in given {
        if !families.contains(&f) {
            families.push(f);
        }
    }
    let base = load_scenario_with_radio(&a.scenario, &a.radio)?;
    if base.deltas.is_empty() {
        bail!("scenario `{}`: triggering.deltas is empty", base.name);
    }
    // The closed form needs one measurement dimension for every sensor.
    let m = base.sensors.first().map(|s| s.dim());
    let m = m.filter(|&m| base.sensors.iter().all(|s| s.dim() == m));
    let max_delta = base.deltas.iter().copied().fold(0.0, f64::max);
    let total = a.sim.episodes * (families.len() * base.deltas.len()) as u64;
    let pb = progress::bar(exec, total, "trigger-curves", a.json);
    let mut results: Vec<(TriggerFamily, Vec<Measured>)> = Vec::new();
    for &family in &families {
        let mut s = base.clone();
        s.trigger = family;
        let mut deltas = base.deltas.clone();
        deltas.sort_by(f64::total_cmp);
        let points = deltas
            .into_iter()
            .map(|delta| {
                let sum = simulate_constant(
                    &s,
                    delta,
                    a.sim.episodes,
                    a.sim.seed,
                    &exec.work(|k| pb.inc(k)),
                )?;
                Ok(Measured {
                    delta,
                    rate: sum.trigger_rate,
                    rate_model: sum.trigger_rate_expected,
                    closed_form: m.and_then(|m| family.expected_rate(delta, m)),
                    rmse: sum.rmse,
                    nees: sum.nees,
                    p_target: sum.p_target,
                    energy: sum.energy_mean,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        results.push((family, points));
    }
    pb.finish_and_clear();
    let series: Vec<FamilySeries> = results
        .iter()
        .map(|(family, pts)| FamilySeries {
            name: family.name().to_string(),
            points: pts
                .iter()
                .map(|p| RatePoint {
                    delta: p.delta,
                    rate: (p.rate.value, p.rate.ci95),
                    rmse: (p.rmse.value, p.rmse.ci95),
                    nees: (p.nees.value, p.nees.ci95),
                })
                .collect(),
            closed_form: match m {
                Some(m) if family.expected_rate(0.0, m).is_some() => (0..=CLOSED_FORM_SAMPLES)
                    .filter_map(|i| {
                        let d = max_delta * i as f64 / CLOSED_FORM_SAMPLES as f64;
                        family.expected_rate(d, m).map(|r| (d, r))
                    })
                    .collect(),
                _ => Vec::new(),
            },
        })
        .collect();
    etp_figures::trigger_curves_plot(&base.name, &series, &stem)?;
    let files = [stem.with_extension("png"), stem.with_extension("svg")];
    if a.json {
        let est = |m: &mut serde_json::Map<String, Value>, k: &str, e: Estimate| {
            m.insert(k.into(), json!(e.value));
            m.insert(format!("{k}_ci95"), json!(e.ci95));
        };
        let v = json!({
            "scenario": base.name,
            "episodes": a.sim.episodes,
            "seed": a.sim.seed,
            "radio": base.radio.describe(&etp_synthesis::report::sensor_names(&base)),
            "families": results.iter().map(|(family, pts)| json!({
                "trigger": family.name(),
                "exact": family.exact(),
                "points": pts.iter().map(|p| {
                    let mut o = serde_json::Map::new();
                    o.insert("delta".into(), json!(p.delta));
                    est(&mut o, "trigger_rate", p.rate);
                    o.insert("trigger_rate_expected".into(), json!(p.rate_model.value));
                    o.insert("trigger_rate_closed_form".into(), json!(p.closed_form));
                    est(&mut o, "rmse", p.rmse);
                    est(&mut o, "nees", p.nees);
                    est(&mut o, "p_target", p.p_target);
                    est(&mut o, "energy_mean", p.energy);
                    Value::Object(o)
                }).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "files": files,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{} · {} episodes per point · seed {} · radio: {}",
            base.name,
            a.sim.episodes,
            a.sim.seed,
            base.radio
                .describe(&etp_synthesis::report::sensor_names(&base))
        );
        println!(
            "{:<14} {:>7} {:>17} {:>8} {:>17} {:>15} {:>8}",
            "family", "δ", "rate", "closed", "RMSE", "NEES/n", "P_tar"
        );
        for (family, pts) in &results {
            for p in pts {
                println!(
                    "{:<14} {:>7.4} {:>8.4} ± {:<6.4} {:>8} {:>8.4} ± {:<6.4} {:>6.3} ± {:<5.3} {:>8.4}",
                    family.name(),
                    p.delta,
                    p.rate.value,
                    p.rate.ci95,
                    p.closed_form.map_or("—".into(), |r| format!("{r:.4}")),
                    p.rmse.value,
                    p.rmse.ci95,
                    p.nees.value,
                    p.nees.ci95,
                    p.p_target.value
                );
            }
        }
        println!("wrote {} and {}", files[0].display(), files[1].display());
    }
    Ok(())
}
