//! Issue 42 items 2 and 4 on MPI: `etp study` gives the same tables and
//! case files for any number of ranks and threads — with whole jobs handed
//! to ranks (2 ranks, 4 jobs) and with every rank on each job (4 ranks, 2
//! jobs) — and a study whose rank is killed fails, leaves no table, keeps
//! its finished cases and resumes to the same bytes.

use super::{ETP, etp, expect, mpirun, require_mpirun, scratch};
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

fn spec(scenarios: &str) -> String {
    format!(
        "scenarios = [{scenarios}]\nfamilies = [\"box\", \"stochastic\"]\n\
         requests = [{{ min_target = 0.8 }}]\nsamples = 200\nepisodes = 400\n\
         aggregation_check = 200\nreplicates = 2\nrounds = 2\n"
    )
}

/// The bytes a study is compared on: its tables and every case's files
/// but the figures and the row files (they hold timings).
fn outputs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for f in ["study.json", "study.csv", "spec.json"] {
        v.push((f.to_string(), std::fs::read(dir.join(f)).expect(f)));
    }
    let mut jobs: Vec<_> = std::fs::read_dir(dir.join("cases"))
        .expect("cases")
        .flatten()
        .map(|e| e.path())
        .collect();
    jobs.sort();
    for j in jobs {
        for f in ["mdp.bin", "front.json", "scenario.toml", "strategy-0.json"] {
            let name = format!(
                "{}/{f}",
                j.file_name().unwrap_or_default().to_string_lossy()
            );
            v.push((name, std::fs::read(j.join(f)).expect(f)));
        }
    }
    v
}

fn same(a: &[(String, Vec<u8>)], b: &[(String, Vec<u8>)], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: not the same files");
    for ((n, x), (m, y)) in a.iter().zip(b) {
        assert_eq!(n, m, "{what}");
        assert!(x == y, "{what}: {n} differs");
    }
}

#[test]
fn a_study_is_the_same_bytes_on_any_number_of_ranks() {
    require_mpirun();
    let root = scratch("study-bytes");
    let file = root.join("spec.toml");
    std::fs::write(&file, spec("\"open-2d\"")).expect("spec");
    let f = file.to_str().expect("utf-8");
    let run = |ranks: Option<u32>, threads: u32| {
        let tag = format!(
            "{}x{threads}",
            ranks.map_or("plain".into(), |n| n.to_string())
        );
        let out = root.join(&tag);
        let o = out.to_str().expect("utf-8");
        let stdout = expect(
            etp(ranks, threads, &["study", f, "-o", o]),
            &[0],
            &format!("{tag} study"),
        );
        let text = String::from_utf8_lossy(&stdout);
        assert!(text.contains("2 cases"), "{tag}: {text}");
        (
            outputs(&out),
            std::fs::read_to_string(out.join("timings.csv")).expect("timings"),
        )
    };
    let (plain, _) = run(None, 2);
    // 2 ranks, 2 jobs: one job per rank (timings name both ranks).
    let (two, timings) = run(Some(2), 1);
    same(&plain, &two, "2 ranks × 1 thread");
    let ranks: Vec<&str> = timings
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(2))
        .collect();
    assert_eq!(ranks, ["0", "1"], "the jobs' ranks: {timings}");
    // 4 ranks, 2 jobs: every rank on each job.
    let (four, _) = run(Some(4), 2);
    same(&plain, &four, "4 ranks × 2 threads");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_study_whose_rank_is_killed_resumes_to_the_same_bytes() {
    require_mpirun();
    let root = scratch("study-killed");
    let file = root.join("spec.toml");
    std::fs::write(&file, spec("\"open-2d\", \"winding-2d\"")).expect("spec");
    let f = file.to_str().expect("utf-8");
    let whole = root.join("whole");
    expect(
        etp(None, 2, &["study", f, "-o", whole.to_str().expect("utf-8")]),
        &[0],
        "the uninterrupted study",
    );
    let dir = root.join("cut");
    let d = dir.to_str().expect("utf-8");
    let child = mpirun(2)
        .arg(ETP)
        .args(["study", f, "-o", d])
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpirun starts");
    // Once a case is finished, kill rank 1.
    let started = Instant::now();
    let finished = |dir: &Path| {
        std::fs::read_dir(dir.join("cases"))
            .map(|js| {
                js.flatten()
                    .filter(|j| j.path().join("row-0.json").exists())
                    .count()
            })
            .unwrap_or(0)
    };
    while finished(&dir) == 0 {
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "no case finished in 600 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    super::killed::kill_rank_1(child);
    assert!(
        !dir.join("study.json").exists() && !dir.join("study.csv").exists(),
        "a failed study left a table"
    );
    let kept = finished(&dir);
    assert!((1..4).contains(&kept), "{kept} of 4 cases finished");
    // Resumed on 2 ranks: the rest only, and the same bytes as the whole run.
    let stdout = expect(
        etp(Some(2), 1, &["study", f, "-o", d]),
        &[0],
        "the resumed study",
    );
    assert!(String::from_utf8_lossy(&stdout).contains("4 cases"));
    same(
        &outputs(&whole),
        &outputs(&dir),
        "resumed after a killed rank",
    );
    let _ = std::fs::remove_dir_all(&root);
}
