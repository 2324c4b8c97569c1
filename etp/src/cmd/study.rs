//! `etp study SPEC.toml [-o DIR] [--json]`: run a study (every scenario ×
//! trigger family × request of the SPEC: synthesis, the strategy `etp
//! strategy` stands by, its validation) and write `DIR/study.json`,
//! `DIR/study.csv` and `DIR/timings.csv`; resumes a killed study on the
//! same DIR; on MPI ranks, shares out the jobs (`crate::study`).

use crate::study::{self, Plan, case, spec::Spec, table::Finished};
use anyhow::{Context, Result};
use etp_pipeline::output::write_new;
use etp_pipeline::progress;
use etp_synthesis::exec::Executor;
use std::path::PathBuf;
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

pub fn run(a: Args, exec: &Executor) -> Result<()> {
    let started = Instant::now();
    let spec = Spec::load(&a.spec)?;
    let dir = study::folder(&spec, a.out.as_deref());
    etp_files::write::output_folder(&dir)?;
    study::claim(&spec, &dir, exec)?;
    let cases_dir = dir.join("cases");
    etp_files::write::output_folder(&cases_dir)?;
    let (rank, ranks) = (exec.rank(), exec.ranks());
    // Rank 0 says what is finished and what is left: the others follow its
    // plan (they may look at the folder after rank 0 has written to it).
    let (finished, plan) = if rank == 0 {
        study::survey(&spec, &dir)?
    } else {
        (Vec::new(), Plan::default())
    };
    let said = exec
        .all_gather(if rank == 0 {
            serde_json::to_vec(&plan)?
        } else {
            Vec::new()
        })
        .context("sharing the study's plan")?;
    let plan: Plan = serde_json::from_slice(said.first().map_or(&[][..], |p| &p[..]))
        .context("the study's plan from rank 0")?;
    let total = spec.jobs.len() * spec.rows_per_job();
    if rank == 0 && !finished.is_empty() {
        eprintln!(
            "study {}: resuming in {}: {} of {total} cases finished, {} left",
            spec.name,
            dir.display(),
            finished.len(),
            plan.cases()
        );
    }
    // Whole jobs to ranks when there are enough of them (`hand_out`); else
    // every rank on each job.
    let apart = study::hand_out(plan.work.len(), ranks);
    let assign = if apart {
        study::schedule(&spec, &plan, ranks)
    } else {
        vec![rank; plan.work.len()]
    };
    let mine_count: usize = plan
        .work
        .iter()
        .zip(&assign)
        .filter(|(_, r)| **r == rank)
        .map(|(w, _)| w.pending.len())
        .sum();
    let pb = progress::bar(exec, mine_count as u64, "study", a.json);
    let mut mine: Vec<Finished> = Vec::new();
    // Whole jobs apart: this rank alone on its threads, writing its cases.
    let alone = exec.alone();
    let on = case::Placement {
        exec: if apart { &alone } else { exec },
        rank,
    };
    for (w, r) in plan.work.iter().zip(&assign) {
        if *r != rank {
            continue;
        }
        let job = spec
            .jobs
            .get(w.job)
            .context("rank 0's plan names a job the SPEC does not have")?;
        pb.set_message(job.id.clone());
        let mut done = |f: &Finished| {
            let text = line(f, ranks);
            if pb.is_hidden() {
                eprintln!("study: {text}");
            } else {
                pb.println(text);
            }
            pb.inc(1);
            mine.push(f.clone());
        };
        case::run_job(
            job,
            w,
            &cases_dir,
            &spec.requests,
            &spec.settings,
            &on,
            &mut done,
        )?;
    }
    pb.finish_and_clear();
    // Every rank's new rows to rank 0 (working together, rank 0 has them all).
    let send = if apart || rank == 0 { &mine[..] } else { &[] };
    let parts = exec
        .all_gather(serde_json::to_vec(send)?)
        .context("gathering the study's rows")?;
    if rank != 0 {
        return Ok(());
    }
    let mut all = finished;
    for (k, p) in parts.iter().enumerate() {
        let rows: Vec<Finished> =
            serde_json::from_slice(p).with_context(|| format!("the rows rank {k} sent"))?;
        all.extend(rows);
    }
    let tables = study::tables(&spec, all)?;
    let json = study::study_json(&spec, &tables.rows)?;
    write_new(exec, &dir.join("study.json"), json.as_bytes(), true)?;
    write_new(
        exec,
        &dir.join("study.csv"),
        study::table::csv(&tables.rows)?.as_bytes(),
        true,
    )?;
    write_new(
        exec,
        &dir.join("timings.csv"),
        study::table::csv(&tables.timings)?.as_bytes(),
        true,
    )?;
    if a.json {
        print!("{json}");
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
