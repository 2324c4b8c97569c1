//! Issue 42 item 2: `etp study SPEC` — every case is what the commands
//! make (the synthesis `etp synthesize` writes, the strategy `etp
//! strategy` writes, the numbers `etp validate` prints), the table matches
//! its schema, and a study killed in the middle resumes: finished cases
//! kept as they were, the tables the same bytes as an uninterrupted run's.

use super::{Scratch, etp, fails_with, s};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Two jobs (open-2d under box and stochastic) × two requests, small.
const SPEC: &str = r#"
scenarios = ["open-2d"]
families = ["box", "stochastic"]
requests = [{ min_target = 0.8 }, { min_target = "kf-0.02" }]
samples = 300
episodes = 500
aggregation_check = 300
kf_episodes = 500
"#;

fn study(spec: &Path, out: &Path) -> std::process::Output {
    etp(&["study", s(spec), "-o", s(out)])
}

fn ok(o: &std::process::Output, what: &str) {
    assert!(
        o.status.success(),
        "{what}: {:?}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn a_study_case_is_what_the_commands_make() {
    let dir = Scratch::new("study-cases");
    let spec = dir.path("small.toml");
    std::fs::write(&spec, SPEC).expect("spec");
    let out = dir.path("out");
    let o = study(&spec, &out);
    ok(&o, "etp study");
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("4 cases (2 jobs × 2 per job)"), "{text}");
    let table: serde_json::Value =
        serde_json::from_slice(&read(&out.join("study.json"))).expect("study.json is JSON");
    super::schemas::validate(&dir.0, "study", &table)
        .unwrap_or_else(|e| panic!("study.json against schemas/study.json:\n{e}"));
    let rows = table["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 4);
    // The CSV: a header and the same rows.
    let csv = String::from_utf8(read(&out.join("study.csv"))).expect("utf-8");
    assert_eq!(csv.lines().count(), 5, "{csv}");
    assert!(csv.starts_with("case,request_index,scenario,"), "{csv}");

    // Job 01 (stochastic) by hand, as a user would: the same files.
    let case = out.join("cases/01-open-2d-stochastic");
    let cli = dir.path("cli");
    ok(
        &etp(&[
            "synthesize",
            "open-2d",
            "--trigger",
            "stochastic",
            "--samples",
            "300",
            "--no-kf-baseline",
            "-o",
            s(&cli),
        ]),
        "etp synthesize",
    );
    for f in ["mdp.bin", "front.json", "scenario.toml"] {
        assert_eq!(read(&cli.join(f)), read(&case.join(f)), "{f}");
    }
    // Request 1: P_tar ≥ KF − 0.02, the KF's P_tar simulated as `etp simulate --delta 0`.
    let row = &rows[3];
    assert_eq!(row["case"], "01-open-2d-stochastic");
    let kf = super::ok_json(&[
        "simulate",
        s(&cli.join("scenario.toml")),
        "--delta",
        "0",
        "--episodes",
        "500",
        "--json",
    ]);
    assert_eq!(row["kf_p_target"], kf["p_target"]);
    let min_target = row["min_target"].as_f64().expect("min_target");
    let want = ((kf["p_target"].as_f64().expect("kf") - 0.02) * 1e4).round() / 1e4;
    assert_eq!(min_target, want);
    let strategy = cli.join("s1.json");
    let o = etp(&[
        "strategy",
        s(&cli),
        "--min-target",
        &min_target.to_string(),
        "--aggregation-check",
        "300",
        "-o",
        s(&strategy),
    ]);
    assert!(
        matches!(o.status.code(), Some(0 | 7)),
        "etp strategy: {o:?}"
    );
    assert_eq!(
        read(&strategy),
        read(&case.join("strategy-1.json")),
        "strategy-1.json"
    );
    let o = etp(&["validate", s(&strategy), "--episodes", "500", "--json"]);
    assert!(
        matches!(o.status.code(), Some(0 | 6)),
        "etp validate: {o:?}"
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("validate JSON");
    for (mine, theirs) in [
        ("simulated_p_target", "p_target"),
        ("simulated_p_target_ci95", "p_target_ci95"),
        ("simulated_p_collision", "p_collision"),
        ("simulated_energy", "energy_mean"),
        ("simulated_energy_ci95", "energy_mean_ci95"),
    ] {
        assert_eq!(row[mine], v[theirs], "{mine} vs validate's {theirs}");
    }
    let holds = v["checks"]
        .as_array()
        .expect("checks")
        .iter()
        .all(|c| c["holds"] == true);
    assert_eq!(row["checks_hold"], holds);
    assert_eq!(row["checks_hold"], o.status.code() == Some(0));
}

#[test]
fn a_killed_study_resumes_from_its_finished_cases() {
    let dir = Scratch::new("study-resume");
    let spec = dir.path("small.toml");
    std::fs::write(&spec, SPEC).expect("spec");
    let whole = dir.path("whole");
    ok(&study(&spec, &whole), "uninterrupted study");

    // Killed (SIGKILL) once its first job's rows are written.
    let cut = dir.path("cut");
    let mut child = Command::new(env!("CARGO_BIN_EXE_etp"))
        .args(["study", s(&spec), "-o", s(&cut)])
        .env("RAYON_NUM_THREADS", "2")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("etp study starts");
    let first = cut.join("cases/00-open-2d-box/row-1.json");
    let started = Instant::now();
    while !first.exists() {
        if let Ok(Some(status)) = child.try_wait() {
            panic!("the study ended ({status}) before it could be killed");
        }
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "no row after 600 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().expect("kill -9");
    child.wait().expect("reaped");
    assert!(
        !cut.join("study.json").exists() && !cut.join("study.csv").exists(),
        "a killed study left a table"
    );
    let kept = read(&first);
    let o = study(&spec, &cut);
    ok(&o, "the resumed study");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("resuming in"), "{err}");
    assert_eq!(read(&first), kept, "a finished case was redone");
    for f in ["study.json", "study.csv", "spec.json"] {
        assert_eq!(read(&cut.join(f)), read(&whole.join(f)), "{f}");
    }
    // No temporary sibling left anywhere.
    let mut stack = vec![cut.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("folder").flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            assert!(!name.contains(".tmp-etp"), "left behind: {name}");
            if e.path().is_dir() {
                stack.push(e.path());
            }
        }
    }

    // Another SPEC in the same folder is refused by name, nothing touched.
    let other = dir.path("other.toml");
    std::fs::write(&other, SPEC.replace("samples = 300", "samples = 301")).expect("spec");
    fails_with(
        &["study", s(&other), "-o", s(&cut)],
        &[
            "holds the study of another SPEC",
            "settings.samples 300 in the folder, 301 in this SPEC",
        ],
    );
    assert_eq!(
        read(&cut.join("study.json")),
        read(&whole.join("study.json"))
    );
}

/// A SPEC file renamed (its `name` defaults to the file's) cannot resume
/// the study of the old name: the refusal says that the name is what differs.
#[test]
fn resuming_under_a_renamed_spec_names_what_differs() {
    let dir = Scratch::new("study-renamed");
    let spec = dir.path("first.toml");
    std::fs::write(&spec, SPEC).expect("spec");
    let out = dir.path("study");
    // The folder is claimed (spec.json written) before any case starts:
    // stop the study there.
    let mut child = Command::new(env!("CARGO_BIN_EXE_etp"))
        .args(["study", s(&spec), "-o", s(&out)])
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("etp study starts");
    let claimed = out.join("spec.json");
    let started = Instant::now();
    while !claimed.exists() {
        if let Ok(Some(status)) = child.try_wait() {
            panic!("the study ended ({status}) before it claimed its folder");
        }
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "no spec.json after 600 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().expect("kill -9");
    child.wait().expect("reaped");
    let stored = std::fs::read(&claimed).expect("spec.json");
    let renamed = dir.path("second.toml");
    std::fs::rename(&spec, &renamed).expect("rename");
    fails_with(
        &["study", s(&renamed), "-o", s(&out)],
        &[
            "holds the study of another SPEC",
            r#"name "first" in the folder, "second" in this SPEC"#,
            r#"set name = "first" in it"#,
        ],
    );
    assert_eq!(std::fs::read(&claimed).expect("spec.json"), stored);
}

#[test]
fn a_bad_spec_is_refused_naming_the_key() {
    let dir = Scratch::new("study-bad");
    for (text, needle) in [
        (
            "scenarios = [\"open-2d\"]\nrequests = [{ min_target = 1.2 }]\n",
            "requests[0].min_target",
        ),
        (
            "scenarios = [\"open-2d\"]\nfamilies = [\"boxy\"]\n",
            "families",
        ),
        ("scenarios = [\"nowhere-2d\"]\n", "scenarios[0]"),
        ("scenarios = [\"open-2d\"]\nsampels = 3\n", "sampels"),
    ] {
        let spec = dir.path("bad.toml");
        std::fs::write(&spec, text).expect("spec");
        fails_with(&["study", s(&spec), "-o", s(&dir.path("out"))], &[needle]);
        assert!(!dir.path("out").join("spec.json").exists());
    }
}
