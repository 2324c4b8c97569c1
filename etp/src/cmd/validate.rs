//! `etp validate STRATEGY`: simulate a strategy in-process and compare with its
//! prediction, like the paper's tables.

use crate::report::{radio_table, summary_table};
use anyhow::Result;
use etp_pipeline::predictions::{self, checks};
use etp_pipeline::progress::Progress;
use etp_pipeline::validation::{
    MapRequest, StrategySource, ValidationRequest, map_stem_beside, validate,
};
use etp_recording_tools::vocab::channels_text;
use etp_shared::strategy::Strategy;
use etp_synthesis::simulate::SimulationSummary;
use std::path::PathBuf;

/// Exit code: the report was printed and at least one of the strategy's
/// predictions lies outside the simulation's interval (a check FAILS; the
/// checks at 95 % family-wise).
pub const EXIT_CHECK_FAILS: u8 = 6;

/// Exit codes (`etp validate --help`).
const EXIT_CODES: &str = "Exit codes: 0 every check holds; 6 a check FAILS (a prediction of the \
strategy lies outside the simulation's interval; the report is printed first); 1 an \
error (unreadable or edited strategy file: its `content_sha256` must match, an option the \
strategy does not take); 2 a bad command line (a value out of its range: nothing runs). \
The checks are one family at 95 % family-wise: each of the m checks at 1 − 0.05/m (Bonferroni), \
so that an honest strategy passes them all 95 % of the time (docs/MODEL.md, Statistics).";

#[derive(Debug, clap::Args)]
#[command(after_help = EXIT_CODES)]
pub struct Args {
    /// A strategy.json written by `etp strategy`.
    pub strategy: PathBuf,
    #[command(flatten)]
    pub sim: crate::input::EpisodeArgs,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Also draw the map with sampled trajectories (PNG + SVG next to the
    /// strategy: `<STRATEGY without .json>-map`, or `-o STEM`).
    #[arg(long)]
    pub plot: bool,
    /// With --plot: the figure's file stem, writes STEM.png and STEM.svg
    /// (its folder must exist).
    #[arg(short = 'o', long = "out", value_name = "STEM", requires = "plot")]
    pub out: Option<PathBuf>,
    /// Trajectories on the map (with --plot).
    #[arg(long, default_value_t = 40, requires = "plot")]
    pub plot_episodes: u64,
    /// Overwrite map plots that exist.
    #[arg(long)]
    pub force: bool,
    /// Evaluate under this radio instead of the scenario's (a robustness study).
    #[command(flatten)]
    pub radio: crate::scenario_flags::RadioArgs,
    /// The strategy's trigger family, confirmed (another family is refused).
    #[command(flatten)]
    pub trigger: crate::scenario_flags::TriggerArgs,
}

use etp_synthesis::exec::Executor;

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    // `-o STEM`: its folder must exist, refused by name before any work.
    if let Some(stem) = &a.out {
        etp_files::write::existing_folder_of(stem, "-o")?;
    }
    let map = a.plot.then(|| MapRequest {
        stem: a
            .out
            .clone()
            .unwrap_or_else(|| map_stem_beside(&a.strategy)),
        episodes: a.plot_episodes,
        force: a.force,
    });
    let v = validate(
        ValidationRequest {
            trigger: a.trigger.trigger,
            // The strategy's own channel unless the options say otherwise
            // (a robustness study); the report names both.
            radio: a.radio.to_override(),
            map,
            progress: Progress::new(a.json),
            ..ValidationRequest::new(
                StrategySource::File(a.strategy.clone()),
                a.sim.episodes,
                a.sim.seed,
            )
        },
        exec,
    )?;
    let (strategy, scenario, sum) = (&v.strategy, &v.scenario, &v.summary);
    if a.json {
        println!("{}", serde_json::to_string_pretty(&v.json)?);
    } else {
        println!("{} — {}", scenario.name, strategy.provenance.label);
        print!("{}", comparison_table(strategy, sum));
        println!("\npredictions of the strategy file:");
        print!("{}", predictions::text_of(strategy));
        print!("{}", check_text(strategy, sum));
        // The error this simulation measures (the stored one, if any, was
        // printed with the predictions above).
        if let Some(c) = predictions::check_of(strategy, sum, a.sim.seed) {
            print!(
                "{}",
                predictions::aggregation_text(&c, predictions::reference_name(strategy), "here")
            );
        }
        let names: Vec<String> = scenario.sensors.iter().map(|x| x.name.clone()).collect();
        println!(
            "\nsimulation details ({} episodes, seed {}, {}):",
            sum.episodes,
            a.sim.seed,
            channels_text(&v.synthesized, &scenario.radio, &names)
        );
        print!("{}", summary_table(sum));
        print!("{}", radio_table(scenario, sum));
        for p in &v.maps {
            println!("wrote {}", p.display());
        }
    }
    if v.failed.is_empty() {
        Ok(())
    } else {
        Err(etp_runtime::shell::ExitWith {
            code: EXIT_CHECK_FAILS,
            message: format!(
                "etp validate: {} check(s) FAIL: {} (the strategy's prediction against the simulation's interval joined with its own ±; its certified bounds against the simulation's interval; {}; {} episodes, seed {})",
                v.failed.len(),
                v.failed.join(", "),
                checks(strategy, sum).0.describe(),
                sum.episodes,
                a.sim.seed
            ),
        }
        .into())
    }
}

fn check_text(strategy: &Strategy, sum: &SimulationSummary) -> String {
    let (family, all) = checks(strategy, sum);
    if all.is_empty() {
        return "  no check: the strategy file stands by no prediction (a --quick strategy; `etp strategy evaluate` predicts it)\n".into();
    }
    let mut o = format!(
        "  against the simulation's interval (predicted: joined with its own ±); {}:\n",
        family.describe()
    );
    let end = |x: f64| {
        if x.is_finite() {
            format!("{x:.4}")
        } else {
            "∞".into()
        }
    };
    for c in all {
        o.push_str(&format!(
            "    {:<42} {}   ({:.4} in [{}, {}])\n",
            c.name,
            if c.holds { "holds" } else { "FAILS" },
            c.value,
            end(c.low).replace("∞", "−∞"),
            end(c.high)
        ));
    }
    o
}

/// Predicted vs simulated, one row per quantity.
pub fn comparison_table(strategy: &Strategy, sum: &SimulationSummary) -> String {
    let Some(p) = strategy.predictions.predicted.as_ref().or(strategy
        .predictions
        .diagnostics
        .as_ref()
        .and_then(|d| d.selection.selection_time.as_ref()))
    else {
        return String::new();
    };
    let heading = if strategy.predictions.predicted.is_some() {
        "predicted"
    } else {
        "sel.-time"
    };
    let mut o = format!(
        "  {:<8} {:>10} {:>24} {:>22}\n",
        "",
        heading,
        "simulated (95 %)",
        format!("{heading} − simulated")
    );
    let measured = etp_pipeline::predictions::outcomes_of(sum);
    for (name, pred, sim, m) in [
        ("P_tar", p.p_target, sum.p_target, measured.p_target),
        (
            "P_coll",
            p.p_collision,
            sum.p_collision,
            measured.p_collision,
        ),
        ("energy", p.energy_mean, sum.energy_mean, None),
    ] {
        if let Some(m) = m {
            // The Wilson interval, which stays in [0, 1].
            let (lo, hi) = m.interval(etp_shared::stats::Z95);
            o.push_str(&format!(
                "  {name:<8} {:>9.2}% {:>7.2}% [{:>5.2}, {:>6.2}]% {:>+19.2} pt\n",
                100.0 * pred,
                100.0 * sim.value,
                100.0 * lo,
                100.0 * hi,
                100.0 * (pred - sim.value)
            ));
        } else {
            // Relative to the simulation, as every energy error etp prints.
            let rel = if sim.value != 0.0 {
                100.0 * (pred - sim.value) / sim.value
            } else {
                0.0
            };
            o.push_str(&format!(
                "  {name:<8} {:>10.2} {:>16.2} ± {:>5.2} {:>+20.2} %\n",
                pred, sim.value, sim.ci95, rel
            ));
        }
    }
    o
}
