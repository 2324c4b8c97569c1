//! A study: a batch of cases — every scenario × trigger family × request
//! of a SPEC ([`spec`]) — each synthesized, its strategy selected and
//! predicted as `etp strategy` does, and validated as `etp validate` does
//! ([`case`]); one JSON and one CSV table out ([`table`]). [`run`] is the
//! whole study from a typed [`StudyRequest`] on an executor: what `etp
//! study` and the Python package's `etpareto.study` call.
//!
//! * **Resumable.** A case is finished when its row file is on disk
//!   (`DIR/cases/<job>/row-K.json`, written beside and renamed, after its
//!   strategy); a study started again on the same DIR and SPEC does only
//!   the rest (a DIR of another SPEC is refused by name: `DIR/spec.json`,
//!   [`claim`]). The tables are written at the end, beside and renamed: a
//!   killed study leaves its finished cases and no table.
//! * **Across ranks.** On an executor of several ranks (`mpirun -n R etp
//!   study …`, `etp`'s feature `mpi`) rank 0 reads what is finished and
//!   says what is left ([`Plan`]); with enough jobs left ([`hand_out`]),
//!   whole jobs are handed to ranks (largest first, each to the least
//!   loaded rank: a deterministic [`schedule`]), each rank doing its own on
//!   its threads (`Executor::alone`) and writing its cases' files (the
//!   study folder must be shared by the ranks, as on a cluster's file
//!   system); with fewer, every rank works on each job in turn, its Monte
//!   Carlo shared out as in `etp synthesize`. At the end the ranks' rows
//!   are gathered and rank 0 writes the tables.
//! * **Same bytes.** Every case is the same bits whoever computes it (the
//!   streams are keyed by seed, not by rank or thread), and the tables hold
//!   no timing (`timings.csv` does): the same SPEC gives the same
//!   `study.json` and `study.csv` for any number of ranks and threads, in
//!   one go or resumed.

pub mod case;
pub mod spec;
pub mod table;

use crate::error::StudyError;
use crate::output::write_new;
use crate::progress::Progress;
use etp_synthesis::exec::Executor;
use indicatif::ProgressBar;
use serde::{Deserialize, Serialize};
use spec::Spec;
use std::path::{Path, PathBuf};
use table::{Finished, Row};

type Result<T> = std::result::Result<T, StudyError>;

/// What is left of one job.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobPlan {
    /// Index into `Spec::jobs`.
    pub job: usize,
    /// Its synthesis is on disk (front.json written): loaded, not built.
    /// Rank 0 says so for every rank: a rank that looked for itself could
    /// see a file rank 0 has just written and skip the build's collectives.
    pub synthesized: bool,
    /// Its unfinished cases (request indices; `None`: the synthesis-only row).
    pub pending: Vec<Option<usize>>,
}

/// What is left of a study.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    pub work: Vec<JobPlan>,
}

impl Plan {
    pub fn cases(&self) -> usize {
        self.work.iter().map(|w| w.pending.len()).sum()
    }
}

/// The cases of job `j` (request indices, or the synthesis-only row).
fn cases_of(spec: &Spec) -> Vec<Option<usize>> {
    if spec.requests.is_empty() {
        vec![None]
    } else {
        (0..spec.requests.len()).map(Some).collect()
    }
}

/// The finished cases under `dir` and what is left.
pub fn survey(spec: &Spec, dir: &Path) -> Result<(Vec<Finished>, Plan)> {
    let mut finished = Vec::new();
    let mut plan = Plan::default();
    for (j, job) in spec.jobs.iter().enumerate() {
        let job_dir = dir.join("cases").join(&job.id);
        let mut pending = Vec::new();
        for k in cases_of(spec) {
            match case::finished(&case::row_path(&job_dir, k))? {
                Some(f) => finished.push(f),
                None => pending.push(k),
            }
        }
        if !pending.is_empty() {
            plan.work.push(JobPlan {
                job: j,
                synthesized: job_dir.join("front.json").exists(),
                pending,
            });
        }
    }
    Ok((finished, plan))
}

/// A job's expected cost in segment-steps of simulation: its synthesis and
/// about two rounds of rebuilds per request (the schedule's weights; only
/// their order matters).
fn cost(spec: &Spec, j: usize, cases: usize) -> u64 {
    let job = &spec.jobs[j];
    let params = etp_synthesis::abstraction::AbstractionParams {
        samples: spec.settings.samples,
        seed: spec.settings.seed,
        ..Default::default()
    };
    let synth = etp_synthesis::abstraction::progress_total(&job.scenario, &params);
    let rebuild = etp_synthesis::predict::rebuild::progress_units(&job.scenario, &params)
        * u64::from(spec.settings.replicates)
        * 2;
    synth + cases as u64 * rebuild
}

/// The share of a synthesis that does not speed up with ranks (the Pareto
/// front — its hull — and certification, the aggregation test, start-up and
/// writing): 0.17 of `etp synthesize winding-2d` at its default 6000
/// samples on one rank, fitted to 1 and 2 ranks at three sample sizes
/// (docs/performance.md, "MPI"; `benchmarks/mpi.sh`).
pub const SERIAL_SHARE: f64 = 0.17;

/// Whether to hand whole jobs to ranks (`true`) or put every rank on each
/// job in turn: handing out is worth it when the ranks it keeps busy,
/// min(jobs, ranks), are more than Amdahl's speed-up of one job on all the
/// ranks, 1 / (σ + (1 − σ) / R) with σ = [`SERIAL_SHARE`]. With 2 ranks: 2
/// jobs or more; with 4: 3; with 64: 6.
pub fn hand_out(jobs: usize, ranks: usize) -> bool {
    if ranks < 2 || jobs < 2 {
        return false;
    }
    let r = ranks as f64;
    let together = 1.0 / (SERIAL_SHARE + (1.0 - SERIAL_SHARE) / r);
    jobs.min(ranks) as f64 >= together
}

/// Which rank does which job when jobs are handed out: largest first, each
/// to the least loaded rank (ties: the lower index). `assign[k]` is the
/// rank of `plan.work[k]`.
pub fn schedule(spec: &Spec, plan: &Plan, ranks: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..plan.work.len()).collect();
    let costs: Vec<u64> = plan
        .work
        .iter()
        .map(|w| cost(spec, w.job, w.pending.len()))
        .collect();
    order.sort_by(|&a, &b| costs[b].cmp(&costs[a]).then(a.cmp(&b)));
    let mut load = vec![0u64; ranks.max(1)];
    let mut assign = vec![0; plan.work.len()];
    for k in order {
        let r = (0..load.len())
            .min_by_key(|&r| (load[r], r))
            .unwrap_or_default();
        load[r] += costs[k];
        assign[k] = r;
    }
    assign
}

/// The study's result: every row, in job then request order.
#[derive(Debug, Clone, Serialize)]
pub struct Tables {
    pub rows: Vec<Row>,
    pub timings: Vec<TimingRow>,
}

/// A line of `timings.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct TimingRow {
    pub case: String,
    pub request_index: Option<usize>,
    pub rank: usize,
    pub threads: usize,
    pub synthesis_seconds: f64,
    pub selection_seconds: f64,
    pub validation_seconds: f64,
}

/// Put the rows of every case in order, refusing a gap or a duplicate.
pub fn tables(spec: &Spec, mut all: Vec<Finished>) -> Result<Tables> {
    let index = |f: &Finished| {
        (
            spec.jobs.iter().position(|j| j.id == f.row.case),
            f.row.request_index,
        )
    };
    all.sort_by_key(index);
    let want = spec.jobs.len() * spec.rows_per_job();
    for w in all.windows(2) {
        if index(&w[0]) == index(&w[1]) {
            return Err(StudyError::Bug(format!(
                "case {} request {:?} finished twice (a bug)",
                w[0].row.case, w[0].row.request_index
            )));
        }
    }
    if all.len() != want || all.iter().any(|f| index(f).0.is_none()) {
        return Err(StudyError::Bug(format!(
            "{} of the SPEC's {want} cases have a row (a bug: every case was scheduled)",
            all.len()
        )));
    }
    let timings = all
        .iter()
        .map(|f| TimingRow {
            case: f.row.case.clone(),
            request_index: f.row.request_index,
            rank: f.timing.rank,
            threads: f.timing.threads,
            synthesis_seconds: f.timing.synthesis_seconds,
            selection_seconds: f.timing.selection_seconds,
            validation_seconds: f.timing.validation_seconds,
        })
        .collect();
    Ok(Tables {
        rows: all.into_iter().map(|f| f.row).collect(),
        timings,
    })
}

/// `study.json`: the SPEC as understood, every row, and the counts.
pub fn study_json(spec: &Spec, rows: &[Row]) -> Result<String> {
    let count = |f: &dyn Fn(&Row) -> bool| rows.iter().filter(|r| f(r)).count();
    let v = serde_json::json!({
        "study": spec.name,
        "spec": serde_json::from_str::<serde_json::Value>(&spec.canonical()?)?,
        "cases": rows.len(),
        "met": count(&|r| r.verdict.as_deref() == Some("met")),
        "not_met": count(&|r| r.verdict.as_deref().is_some_and(|v| v != "met")),
        "checks_hold": count(&|r| r.checks_hold == Some(true)),
        "checks_fail": count(&|r| r.checks_hold == Some(false)),
        "rows": rows,
    });
    Ok(serde_json::to_string_pretty(&v)? + "\n")
}

/// A study to run: its SPEC, its folder, whether to draw progress.
#[derive(Debug, Clone)]
pub struct StudyRequest {
    pub spec: Spec,
    /// The study's folder (default `out/study-<name>`: [`folder`]); the
    /// same folder resumes a study that did not finish.
    pub out: Option<PathBuf>,
    /// Where the study's bar goes (its cases' steps count theirs there
    /// too, never drawn).
    pub progress: Progress,
}

/// What a study says as it goes (`etp study` prints it); each method's
/// default says nothing.
pub trait Observer {
    /// Rank 0 found `finished` of the study's `total` cases done in `dir`,
    /// `left` still to do.
    fn resuming(
        &mut self,
        _spec: &Spec,
        _dir: &Path,
        _finished: usize,
        _total: usize,
        _left: usize,
    ) {
    }
    /// This rank finished a case (its row file is written) in a job of
    /// `ranks` ranks; `bar` is the study's progress bar, to print above.
    fn finished(&mut self, _case: &Finished, _ranks: usize, _bar: &ProgressBar) {}
}

/// An [`Observer`] that says nothing.
pub struct Silent;

impl Observer for Silent {}

/// A finished study, as rank 0 has it: its folder, its tables and the
/// text of `study.json` (what `etp study --json` prints).
#[derive(Debug, Clone)]
pub struct Outcome {
    pub dir: PathBuf,
    pub tables: Tables,
    pub json: String,
}

/// Run the study `request` asks on `exec`: claim its folder, do the cases
/// not yet finished (this rank's share of them on an executor of several
/// ranks), then on rank 0 write `study.json`, `study.csv` and
/// `timings.csv`. The outcome on rank 0; `None` on the other ranks.
pub fn run(
    request: &StudyRequest,
    exec: &Executor,
    observer: &mut dyn Observer,
) -> Result<Option<Outcome>> {
    let spec = &request.spec;
    let dir = folder(spec, request.out.as_deref());
    etp_files::write::output_folder(&dir)?;
    claim(spec, &dir, exec)?;
    let cases_dir = dir.join("cases");
    etp_files::write::output_folder(&cases_dir)?;
    let (finished, plan) = share_plan(spec, &dir, exec)?;
    if exec.rank() == 0 && !finished.is_empty() {
        let total = spec.jobs.len() * spec.rows_per_job();
        observer.resuming(spec, &dir, finished.len(), total, plan.cases());
    }
    let (apart, mine) = run_share(request, &plan, &cases_dir, exec, observer)?;
    let Some(all) = gather(finished, &mine, apart, exec)? else {
        return Ok(None);
    };
    let tables = tables(spec, all)?;
    let json = study_json(spec, &tables.rows)?;
    write_new(exec, &dir.join("study.json"), json.as_bytes(), true)?;
    let csv = table::csv(&tables.rows)?;
    write_new(exec, &dir.join("study.csv"), csv.as_bytes(), true)?;
    let csv = table::csv(&tables.timings)?;
    write_new(exec, &dir.join("timings.csv"), csv.as_bytes(), true)?;
    Ok(Some(Outcome { dir, tables, json }))
}

/// What is finished and what is left: rank 0 looks, the others follow its
/// plan (they may look at the folder after rank 0 has written to it).
/// The finished cases are rank 0's alone.
fn share_plan(spec: &Spec, dir: &Path, exec: &Executor) -> Result<(Vec<Finished>, Plan)> {
    let rank = exec.rank();
    let (finished, plan) = if rank == 0 {
        survey(spec, dir)?
    } else {
        (Vec::new(), Plan::default())
    };
    let said = exec
        .all_gather(if rank == 0 {
            serde_json::to_vec(&plan)?
        } else {
            Vec::new()
        })
        .map_err(StudyError::ranks("sharing the study's plan"))?;
    let plan: Plan = serde_json::from_slice(said.first().map_or(&[][..], |p| &p[..]))
        .map_err(StudyError::ranks("the study's plan from rank 0"))?;
    Ok((finished, plan))
}

/// This rank's share of `plan`, done: whole jobs to ranks when there are
/// enough of them ([`hand_out`], then `true`), else every rank on each
/// job. The cases this rank finished.
fn run_share(
    request: &StudyRequest,
    plan: &Plan,
    cases_dir: &Path,
    exec: &Executor,
    observer: &mut dyn Observer,
) -> Result<(bool, Vec<Finished>)> {
    let spec = &request.spec;
    let (rank, ranks) = (exec.rank(), exec.ranks());
    let apart = hand_out(plan.work.len(), ranks);
    let assign = if apart {
        schedule(spec, plan, ranks)
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
    let pb = request.progress.bar(exec, mine_count as u64, "study");
    let inner = request.progress.silenced();
    let mut mine: Vec<Finished> = Vec::new();
    // Whole jobs apart: this rank alone on its threads, writing its cases.
    let alone = exec.alone();
    let on = case::Placement {
        exec: if apart { &alone } else { exec },
        rank,
        progress: &inner,
    };
    for (w, r) in plan.work.iter().zip(&assign) {
        if *r != rank {
            continue;
        }
        let job = spec.jobs.get(w.job).ok_or_else(|| {
            StudyError::Bug("rank 0's plan names a job the SPEC does not have".into())
        })?;
        pb.set_message(job.id.clone());
        let mut done = |f: &Finished| {
            observer.finished(f, ranks, &pb);
            pb.inc(1);
            mine.push(f.clone());
        };
        case::run_job(
            job,
            w,
            cases_dir,
            &spec.requests,
            &spec.settings,
            &on,
            &mut done,
        )?;
    }
    pb.finish_and_clear();
    Ok((apart, mine))
}

/// Every rank's new rows to rank 0 (working together, rank 0 has them
/// all): with the cases finished before, every row on rank 0; `None` on
/// the others.
fn gather(
    finished: Vec<Finished>,
    mine: &[Finished],
    apart: bool,
    exec: &Executor,
) -> Result<Option<Vec<Finished>>> {
    let send = if apart || exec.rank() == 0 { mine } else { &[] };
    let parts = exec
        .all_gather(serde_json::to_vec(send)?)
        .map_err(StudyError::ranks("gathering the study's rows"))?;
    if exec.rank() != 0 {
        return Ok(None);
    }
    let mut all = finished;
    for (k, p) in parts.iter().enumerate() {
        let rows: Vec<Finished> = serde_json::from_slice(p)
            .map_err(StudyError::ranks(format!("the rows rank {k} sent")))?;
        all.extend(rows);
    }
    Ok(Some(all))
}

/// The study's folder: `-o DIR`, else `out/study-<name>`.
pub fn folder(spec: &Spec, out: Option<&Path>) -> PathBuf {
    out.map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new("out").join(format!("study-{}", spec.name)))
}

/// Refuse a DIR that holds another SPEC's study; otherwise (rank 0 of
/// `exec`) record this one.
pub fn claim(spec: &Spec, dir: &Path, exec: &Executor) -> Result<()> {
    let path = dir.join("spec.json");
    let mine = spec.canonical()?;
    match std::fs::read_to_string(&path) {
        Ok(theirs) if theirs == mine => Ok(()),
        Ok(theirs) => Err(StudyError::AnotherSpec(format!(
            "{} holds the study of another SPEC (its spec.json differs: {}): give another -o, \
             or move it away to start over{}",
            dir.display(),
            differences(&theirs, &mine),
            renamed_hint(&theirs, &spec.name)
        ))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Ok(write_new(exec, &path, mine.as_bytes(), false)?)
        }
        Err(e) => Err(StudyError::Folder {
            what: format!("reading {}", path.display()),
            source: Box::new(e),
        }),
    }
}

/// A SPEC file renamed changes the study's name (its file's stem by
/// default): say how to keep the stored one and resume.
fn renamed_hint(stored: &str, name: &str) -> String {
    let stored_name = serde_json::from_str::<serde_json::Value>(stored)
        .ok()
        .and_then(|v| v.get("name").and_then(|n| n.as_str()).map(str::to_string));
    match stored_name {
        Some(old) if old != name => format!(
            "; to resume it with this file, set name = \"{old}\" in it (a SPEC's name is its \
             file's stem unless it sets one)"
        ),
        _ => String::new(),
    }
}

/// Where two SPECs as stored (`spec.json`) differ, each place with the
/// stored value and this SPEC's (the first few; a SPEC's `name` defaults
/// to its file name, so a renamed file shows as `name`).
fn differences(stored: &str, mine: &str) -> String {
    const SHOWN: usize = 6;
    let (Ok(a), Ok(b)) = (
        serde_json::from_str::<serde_json::Value>(stored),
        serde_json::from_str::<serde_json::Value>(mine),
    ) else {
        return "the stored spec.json is not JSON".into();
    };
    let mut found = Vec::new();
    diff_values("", &a, &b, &mut found);
    let n = found.len();
    let mut text = found.into_iter().take(SHOWN).collect::<Vec<_>>().join("; ");
    if n > SHOWN {
        text.push_str(&format!("; … {n} differences in all"));
    }
    text
}

/// Push `path: stored → this SPEC` for every leaf where `a` and `b` differ.
fn diff_values(path: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
    use serde_json::Value;
    let at = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
            for k in keys {
                let none = Value::Null;
                diff_values(
                    &at(k),
                    x.get(k).unwrap_or(&none),
                    y.get(k).unwrap_or(&none),
                    out,
                );
            }
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => {
            for (i, (p, q)) in x.iter().zip(y).enumerate() {
                diff_values(&format!("{path}[{i}]"), p, q, out);
            }
        }
        _ if a != b => out.push(format!(
            "{} {a} in the folder, {b} in this SPEC",
            if path.is_empty() { "the SPEC" } else { path }
        )),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::hand_out;

    #[test]
    fn the_differences_of_two_specs_are_named_with_both_values() {
        let d = super::differences(
            r#"{"name": "a", "settings": {"samples": 100, "seed": 1}, "jobs": [1, 2]}"#,
            r#"{"name": "b", "settings": {"samples": 200, "seed": 1}, "jobs": [1, 2, 3]}"#,
        );
        assert_eq!(
            d,
            "jobs [1,2] in the folder, [1,2,3] in this SPEC; name \"a\" in the folder, \
             \"b\" in this SPEC; settings.samples 100 in the folder, 200 in this SPEC"
        );
    }

    #[test]
    fn jobs_are_handed_out_when_that_keeps_more_ranks_busy_than_sharing() {
        assert!(!hand_out(5, 1));
        assert!(!hand_out(1, 64));
        assert!(hand_out(2, 2));
        assert!(!hand_out(2, 4));
        assert!(hand_out(3, 4));
        assert!(!hand_out(5, 64));
        assert!(hand_out(6, 64));
        assert!(hand_out(15, 64));
    }
}
