//! `etp demo`: the whole pipeline on the built-in default scenario — synthesize,
//! pick the `--min-target 0.95` strategy, validate it in-process, run it as
//! processes over iceoryx2 — and one table: predicted vs in-process vs
//! multi-process, packets per sensor, and where the plots and files are.

use crate::input::load_scenario_with_radio;
use crate::scenario_flags::RadioArgs;
use anyhow::{Context, Result};
use etp_launcher as multiprocess;
use etp_pipeline::front::write_front;
use etp_pipeline::mdp_build::{MdpRequest, build_mdp};
use etp_pipeline::output::write_new;
use etp_pipeline::progress::Progress;
use etp_pipeline::selection::{RequestSettings, meet_goal};
use etp_pipeline::validation::{MapRequest, StrategySource, ValidationRequest, validate};
use etp_runtime::scenario_arg::scenario_text;
use etp_shared::rng::mix64;
use etp_shared::scenario::DEFAULT_SCENARIO;
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::MDP_FILE;
use etp_synthesis::predict::request::{Goal, Verdict};
use serde_json::{Value, json};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario (built-in name or TOML path).
    #[arg(long, default_value = DEFAULT_SCENARIO)]
    pub scenario: String,
    /// Required target probability of the demo's strategy (P in [0, 1]).
    #[arg(long, value_name = "P", default_value_t = 0.95, value_parser = crate::input::probability)]
    pub min_target: f64,
    /// Monte Carlo segments per state-action of the synthesis (at least 1).
    #[arg(long, default_value_t = etp_synthesis::abstraction::DEFAULT_SAMPLES,
          value_parser = crate::values::whole::<u32>(1, None))]
    pub samples: u32,
    /// In-process validation episodes (at least 1).
    #[arg(long, default_value_t = 3000, value_parser = crate::values::whole::<u64>(1, None))]
    pub validate_episodes: u64,
    /// Multi-process episodes (at least 1).
    #[arg(long, default_value_t = 200, value_parser = crate::values::whole::<u64>(1, None))]
    pub run_episodes: u64,
    /// Seed of everything.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Requests of the predicted front drawn in front.png (`etp strategy
    /// front --points`; 0: none, the MDP's front alone; else 2 to 64).
    #[arg(long, value_name = "K", default_value_t = DEMO_FRONT_POINTS, value_parser = front_points)]
    pub front_points: usize,
    /// Output folder of everything the demo writes, the run's recording
    /// (`run.mcap`) included (default `out/demo-<scenario>-<seed>-<time>`;
    /// never reused).
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// The multi-process run's recording, in the demo's folder.
const RECORDING: &str = "run.mcap";

/// Requests of the demo's predicted front by default (`etp strategy front`
/// has 6).
const DEMO_FRONT_POINTS: usize = 4;

/// `--front-points K`: 0 (no predicted front) or `etp strategy front
/// --points`' range, refused before the demo's synthesis starts.
fn front_points(s: &str) -> std::result::Result<usize, String> {
    match s.trim() {
        "0" => Ok(0),
        _ => crate::values::whole::<usize>(2, Some(64))(s)
            .map_err(|e| format!("{e} (or 0: no predicted front)")),
    }
}

fn stage(quiet: bool, text: &str) {
    if !quiet {
        eprintln!("{text}");
    }
}

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    let started = Instant::now();
    let text = scenario_text(&a.scenario)?;
    let stamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64);
    // The scenario as `etp synthesize` loads it without options.
    let scenario = load_scenario_with_radio(&a.scenario, &RadioArgs::default())?;
    let dir = a.out.clone().unwrap_or_else(|| {
        PathBuf::from("out").join(format!(
            "demo-{}-{}-{:x}",
            scenario.name,
            a.seed,
            mix64(stamp) & 0xffff_ffff
        ))
    });
    etp_files::write::output_folder(&dir)?;
    if dir.join(MDP_FILE).exists() {
        anyhow::bail!(
            "{} already holds a synthesis; choose another --out",
            dir.display()
        );
    }

    // 1. Synthesis (MDP + front).
    stage(
        a.json,
        &format!(
            "[1/4] synthesizing {} ({} segments per state-action)…",
            scenario.name, a.samples
        ),
    );
    // `etp synthesize`'s defaults, but no held-out sample (the demo keeps
    // its time; strategies then report cross-fitted values as n/a) and no
    // Method 1 baseline.
    let mut request = MdpRequest::defaults(scenario.clone(), a.samples, a.seed);
    request.out = Some(dir.clone());
    request.progress = Progress::new(a.json);
    request.exec = exec.clone();
    let built = build_mdp(request)?;
    let front = write_front(&built.dir, &built.mdp, None, &text, None, false, exec)?;

    // 2. Strategy.
    stage(
        a.json,
        &format!(
            "[2/4] strategy: least energy with P_tar ≥ {}…",
            a.min_target
        ),
    );
    // The selection step of `etp strategy DIR --min-target P
    // --aggregation-check 0`: the request loop, the prediction from the
    // strategy's own rebuilds (docs/MODEL.md §7.4), the file it stands by.
    let mut syn = etp_pipeline::synthesis_dir::Synthesis::from_parts(
        &built.dir,
        built.mdp.clone(),
        Some(text.clone()),
        front.front.clone(),
        None,
        exec,
    )?;
    let goal = Goal::MinTarget {
        min_target: a.min_target,
        max_collision: None,
    };
    let settings = RequestSettings {
        aggregation_check: 0,
        ..RequestSettings::default()
    };
    let (outcome, strategy, _) = meet_goal(&syn, &syn.mdp, goal, &settings, &Progress::new(a.json))
        .context("the demo's strategy")?;
    if outcome.verdict != Verdict::Met {
        anyhow::bail!(
            "the demo's request P_tar ≥ {} is out of reach on this synthesis ({})",
            a.min_target,
            outcome.verdict.name()
        );
    }
    let strategy_path = dir.join("strategy.json");
    write_new(exec, &strategy_path, strategy.to_json().as_bytes(), false)?;

    // The predicted front (docs/MODEL.md §7.5): what `etp strategy front
    // DIR --points DEMO_FRONT_POINTS` stores and draws over the MDP's front.
    let points = a.front_points;
    if points > 0 {
        stage(
            a.json,
            &format!("      the predicted front ({points} requests, each a request loop)…"),
        );
    }
    let curves = if points == 0 {
        Vec::new()
    } else {
        etp_pipeline::predicted_front::compute(
            &syn,
            &[None],
            points,
            &etp_pipeline::selection::RequestSettings {
                aggregation_check: 0,
                ..Default::default()
            },
            &Progress::new(a.json),
            &|_, _| {},
        )?
    };
    if !curves.is_empty() {
        etp_pipeline::predicted_front::store(&mut syn, curves.clone())?;
    }

    // 3. In-process validation (+ map plot).
    stage(
        a.json,
        &format!(
            "[3/4] validating in-process ({} episodes)…",
            a.validate_episodes
        ),
    );
    // `etp validate strategy.json --plot`'s step, on the synthesis's
    // scenario (the strategy's own) in the demo's fresh folder.
    let map_stem = dir.join("strategy-map");
    let validation = validate(
        ValidationRequest {
            map: Some(MapRequest {
                stem: map_stem.clone(),
                episodes: 40,
                force: true,
            }),
            progress: Progress::new(a.json),
            ..ValidationRequest::new(
                StrategySource::Loaded {
                    strategy: Box::new(strategy),
                    scenario: Box::new(built.scenario.clone()),
                },
                a.validate_episodes,
                a.seed,
            )
        },
        exec,
    )?;
    let (strategy, sim) = (validation.strategy, validation.summary);

    // 4. Multi-process run.
    stage(
        a.json,
        &format!(
            "[4/4] running {} episodes as processes over iceoryx2…",
            a.run_episodes
        ),
    );
    let rargs = multiprocess::RunRequest {
        episodes: a.run_episodes,
        seed: a.seed,
        json: true,
        deadline: 600.0,
        predict_episodes: a.validate_episodes,
        // Every output of the demo in its folder, the recording too.
        record: multiprocess::RecordTo::File(dir.join(RECORDING)),
        ..multiprocess::RunRequest::new(multiprocess::RunTarget::Strategy {
            path: strategy_path.clone(),
            scenario: None,
        })
    };
    let (mp, problems) = multiprocess::execute(&rargs)?;

    let p = strategy
        .predictions
        .predicted
        .context("the demo's strategy has no prediction (a bug)")?;
    let h = strategy.predictions.predicted_ci95.unwrap_or_default();
    let num = |v: &Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let result = json!({
        "scenario": scenario.name,
        "strategy": strategy_path,
        "vertices": front.front.vertices.len(),
        "predicted_front": curves,
        "predicted": etp_recording_tools::vocab::prediction(Some(&p)),
        "predicted_ci95": {"p_target": h.p_target, "p_collision": h.p_collision, "energy_mean": h.energy_mean},
        "prediction_basis": strategy.predictions.prediction_basis,
        "in_process": {"episodes": sim.episodes, "p_target": sim.p_target.value, "p_target_ci95": sim.p_target.ci95,
                        "p_collision": sim.p_collision.value, "p_collision_ci95": sim.p_collision.ci95,
                        "energy_mean": sim.energy_mean.value, "energy_mean_ci95": sim.energy_mean.ci95},
        "multi_process": mp,
        "files": {"front_plot": dir.join("front.png"), "map_plot": map_stem.with_extension("png"),
                  "recording": mp["recording"]["path"].clone(), "dir": dir},
        "seconds": started.elapsed().as_secs_f64(),
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&result)?);
        return Ok(multiprocess::exit_for(&problems)?);
    }
    println!(
        "\netp demo — {} — {}",
        scenario.name, strategy.provenance.label
    );
    println!(
        "Pareto front: {} vertices (front.json); energy of the full Kalman filter {:.1}\n",
        front.front.vertices.len(),
        front.front.energy_scale
    );
    for c in &curves {
        println!(
            "Predicted front (front.png; each point the strategy `etp strategy --min-target P` returns):"
        );
        for q in &c.points {
            println!(
                "  P_tar ≥ {:.4}: {:<12} predicted P_tar {:.4} ± {:.4}, energy {:.2} ± {:.2} (MDP's value {:.2})",
                q.min_target,
                q.verdict,
                q.predicted.p_target,
                q.predicted_ci95.p_target,
                q.predicted.energy,
                q.predicted_ci95.energy,
                q.selection_time.energy
            );
        }
        println!();
    }
    println!(
        "  {:<10} {:>12} {:>22} {:>22}",
        "", "predicted", "in-process (95 %)", "multi-process (95 %)"
    );
    let pct = |v: f64| format!("{:.2}%", 100.0 * v);
    for (name, pred, ip, ipc, key) in [
        (
            "P_tar",
            p.p_target,
            sim.p_target.value,
            sim.p_target.ci95,
            "p_target",
        ),
        (
            "P_coll",
            p.p_collision,
            sim.p_collision.value,
            sim.p_collision.ci95,
            "p_collision",
        ),
    ] {
        println!(
            "  {name:<10} {:>12} {:>13} ± {:>6} {:>13} ± {:>6}",
            pct(pred),
            pct(ip),
            pct(ipc),
            pct(num(&mp, key)),
            pct(num(&mp, &format!("{key}_ci95")))
        );
    }
    println!(
        "  {:<10} {:>12.2} {:>13.2} ± {:>6.2} {:>13.2} ± {:>6.2}",
        "energy",
        p.energy_mean,
        sim.energy_mean.value,
        sim.energy_mean.ci95,
        num(&mp, "energy_mean"),
        num(&mp, "energy_mean_ci95")
    );
    println!(
        "\n  packets per sensor ({} multi-process episodes): transmitted (sensor ledger) / received (agent) / predicted",
        mp["episodes"]
    );
    for s in mp["sensors"].as_array().into_iter().flatten() {
        println!(
            "  {:<8} {:>11} {:>11} {:>11.1}",
            s["name"].as_str().unwrap_or("?"),
            s["transmissions"].as_u64().unwrap_or(0),
            s["received"].as_u64().unwrap_or(0),
            s["predicted_energy"].as_f64().unwrap_or(f64::NAN)
        );
    }
    let ledgers: u64 = mp["sensors"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|s| s["transmissions"].as_u64().unwrap_or(0))
        .sum();
    if let Some(recorded) = mp["recording"]["counts"]["measurement"].as_u64() {
        println!(
            "  {:<8} {:>11} (Σ ledgers) = {recorded} measurement messages in the recording",
            "total", ledgers
        );
    }
    println!("\n  files: {}", dir.display());
    println!("    front plot     {}", dir.join("front.png").display());
    println!(
        "    map plot       {}",
        map_stem.with_extension("png").display()
    );
    println!("    strategy       {}", strategy_path.display());
    if let Some(r) = mp["recording"]["path"].as_str() {
        println!("    recording      {r}  (etp replay {r})");
    }
    println!("  finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(multiprocess::exit_for(&problems)?)
}
