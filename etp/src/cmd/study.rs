//! `etp study SPEC.toml [-o DIR] [--json]`: run a study (every scenario ×
//! trigger family × request of the SPEC: synthesis, the strategy `etp
//! strategy` stands by, its validation) and write `DIR/study.json`,
//! `DIR/study.csv` and `DIR/timings.csv`; resumes a killed study on the
//! same DIR; on MPI ranks, shares out the jobs. The study is
//! `etp_pipeline::study::run`; this module parses, prints and sums up.

use anyhow::Result;
use etp_pipeline::progress::Progress;
use etp_pipeline::study::spec::Spec;
use etp_pipeline::study::table::Finished;
use etp_pipeline::study::{Observer, StudyRequest};
use etp_synthesis::exec::Executor;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::time::Instant;

const SPEC_HELP: &str = "SPEC (TOML): scenarios = [\"winding-2d\", \"my.toml\", { random = 4, \
seed = 9105 }] (names, paths relative to the SPEC, random draws); families = [\"box\", \
\"stochastic\"] (default: each scenario's own); requests = [{ min_target = 0.9 }, { min_target = \
\"kf-0.02\", max_collision = 0.05 }] (P_tar ≥ P, or the full Kalman filter's simulated P_tar minus \
D; none: synthesis only); samples, seed, replicates, rounds, episodes (validation, 0: none), \
aggregation_check, kf_episodes (defaults: those of etp synthesize, strategy and validate); name \
(default: the file's stem; the folder's default out/study-<name>). A folder holding another \
SPEC's study is refused naming each key that differs. Exit codes: 0 every case is done and the tables are written (requests out of reach and failed \
checks are results, in the table); 1 an error (finished cases are kept: run the same command \
again to resume); 2 a bad command line.";

#[derive(Debug, clap::Args)]
#[command(after_help = SPEC_HELP)]
pub struct Args {
    /// The study's SPEC file (TOML; see below).
    pub spec: PathBuf,
    /// The study's folder (default `out/study-<name>`); the same folder
    /// resumes a study that did not finish.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
    /// Print the study's JSON table on stdout.
    #[arg(long)]
    pub json: bool,
}

/// One finished case in a line (stderr).
fn line(f: &Finished, ranks: usize) -> String {
    let r = &f.row;
    let t = &f.timing;
    let mut s = format!("{} {}", r.case, r.request.as_deref().unwrap_or("synthesis"));
    if let Some(v) = &r.verdict {
        s.push_str(&format!(": {v}"));
    }
    if let (Some(p), Some(h)) = (r.predicted_p_target, r.predicted_p_target_ci95) {
        s.push_str(&format!(" · predicted P_tar {p:.4} ± {h:.4}"));
    }
    if let (Some(e), Some(h)) = (r.predicted_energy, r.predicted_energy_ci95) {
        s.push_str(&format!(", energy {e:.3} ± {h:.3}"));
    }
    if let (Some(p), Some(h)) = (r.simulated_p_target, r.simulated_p_target_ci95) {
        s.push_str(&format!(" · simulated P_tar {p:.4} ± {h:.4}"));
    }
    match r.checks_hold {
        Some(true) => s.push_str(" · checks hold"),
        Some(false) => s.push_str(&format!(
            " · FAILS: {}",
            r.failed_checks.as_deref().unwrap_or("?")
        )),
        None => {}
    }
    let secs = t.synthesis_seconds + t.selection_seconds + t.validation_seconds;
    s.push_str(&format!(" ({secs:.1} s"));
    if ranks > 1 {
        s.push_str(&format!(", rank {}", t.rank));
    }
    s.push(')');
    s
}

/// What `etp study` says as the study goes, on stderr.
struct Say;

impl Observer for Say {
    fn resuming(&mut self, spec: &Spec, dir: &Path, finished: usize, total: usize, left: usize) {
        eprintln!(
            "study {}: resuming in {}: {finished} of {total} cases finished, {left} left",
            spec.name,
            dir.display(),
        );
    }

    fn finished(&mut self, case: &Finished, ranks: usize, bar: &ProgressBar) {
        let text = line(case, ranks);
        if bar.is_hidden() {
            eprintln!("study: {text}");
        } else {
            bar.println(text);
        }
    }
}

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    let started = Instant::now();
    let request = StudyRequest {
        spec: Spec::load(&a.spec)?,
        out: a.out,
        progress: Progress::new(a.json),
    };
    let Some(done) = etp_pipeline::study::run(&request, exec, &mut Say)? else {
        return Ok(());
    };
    let (spec, dir, tables) = (&request.spec, &done.dir, &done.tables);
    let ranks = exec.ranks();
    if a.json {
        print!("{}", done.json);
        return Ok(());
    }
    let rows = &tables.rows;
    let met = rows
        .iter()
        .filter(|r| r.verdict.as_deref() == Some("met"))
        .count();
    let asked = rows.iter().filter(|r| r.verdict.is_some()).count();
    let validated: Vec<_> = rows.iter().filter_map(|r| r.checks_hold).collect();
    let plural = |n: usize, word: &str| format!("{n} {word}{}", if n == 1 { "" } else { "s" });
    println!(
        "study {} — {} ({} × {} per job) on {} in {:.1} s",
        spec.name,
        plural(rows.len(), "case"),
        plural(spec.jobs.len(), "job"),
        spec.rows_per_job(),
        plural(ranks, "rank"),
        started.elapsed().as_secs_f64()
    );
    if asked > 0 {
        println!("  requests met: {met} of {asked}");
    }
    if !validated.is_empty() {
        println!(
            "  validation: every check holds in {} of {}",
            validated.iter().filter(|h| **h).count(),
            validated.len()
        );
    }
    for name in ["study.json", "study.csv", "timings.csv"] {
        println!("  wrote {}", dir.join(name).display());
    }
    Ok(())
}
