//! End-to-end tests of the `etp` binary (one integration-test binary per crate;
//! one module per area).

#[path = "../../../tests/src/pyenv.rs"]
mod pyenv;

mod aggregation_check;
mod certified;
mod docs;
mod docs_map;
mod exact;
mod families;
mod integrity;
mod logs;
mod memory;
mod outputs;
mod pipeline;
mod pool_policy;
mod radio;
mod readme;
mod replay;
mod replay_cat;
mod replay_subcommands;
mod replay_tools;
mod request_loop;
mod run_config;
mod scenario_random;
mod schemas;
mod storm;
mod study;
mod synthesize;
mod trigger;
mod usage;
mod workable;

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn etp(args: &[&str]) -> Output {
    etp_threads(args, "2")
}

/// Run etp with a given rayon thread count.
fn etp_threads(args: &[&str], threads: &str) -> Output {
    Command::new(env!("CARGO_BIN_EXE_etp"))
        .args(args)
        .env("RAYON_NUM_THREADS", threads)
        .output()
        .expect("spawn etp")
}

fn ok_json(args: &[&str]) -> Value {
    let out = etp(args);
    assert!(
        out.status.success(),
        "etp {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON value")
}

fn fails_with(args: &[&str], needles: &[&str]) {
    let out = etp(args);
    assert!(!out.status.success(), "etp {args:?} should fail");
    let err = String::from_utf8_lossy(&out.stderr);
    for n in needles {
        assert!(err.contains(n), "stderr of etp {args:?} lacks {n:?}: {err}");
    }
}

/// A fresh scratch directory under the target dir (removed on drop). Each
/// gets a number of its own: two tests that chose the same name (they did:
/// `replay-plot`, `aggregation-check`) must not remove each other's files.
struct Scratch(PathBuf);
impl Scratch {
    fn new(name: &str) -> Self {
        static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("{name}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        Self(dir)
    }
    fn path(&self, p: &str) -> PathBuf {
        self.0.join(p)
    }
}
impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The iceoryx2 run a test publishes on (`--run-id`): whatever its
/// processes left (the `global_mgmt` file in /dev/shm, the run's root
/// folder) is removed when the test ends, passed or failed.
struct RunLeftovers(String);
impl RunLeftovers {
    /// A run id of this test process's own, `<tag><pid>`.
    fn new(tag: &str) -> Self {
        Self(format!("{tag}{}", std::process::id()))
    }
}
impl Drop for RunLeftovers {
    fn drop(&mut self) {
        if let Ok(run) = etp_runtime::wire::RunId::new(&self.0) {
            etp_runtime::cleanup::remove_run(&run);
        }
    }
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn check_describes_every_builtin() {
    for name in ["winding-2d", "open-2d", "superg-3d"] {
        let out = etp(&["check", name]);
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        for needle in ["legs", "sensors", "obstacles", "thresholds", "γ̄"] {
            assert!(text.contains(needle), "{name}: {needle} missing in\n{text}");
        }
        let v = ok_json(&["check", name, "--json"]);
        assert_eq!(v["name"], name);
    }
    let v = ok_json(&["check", "winding-2d", "--json"]);
    assert_eq!(v["legs"].as_array().map(Vec::len), Some(11));
    // γ̄ of the built-in thresholds: 1, 0.5, 0.25, 0.1, 0.05.
    let rates: Vec<f64> = v["thresholds"]
        .as_array()
        .expect("thresholds")
        .iter()
        .map(|t| t["expected_rate"]["m2"].as_f64().expect("rate"))
        .collect();
    for (r, e) in rates.iter().zip([1.0, 0.5, 0.25, 0.1, 0.05]) {
        assert!((r - e).abs() < 1e-4, "{rates:?}");
    }
}

#[test]
fn simulate_json_has_every_key_with_an_interval_and_is_reproducible() {
    let args = [
        "simulate",
        "winding-2d",
        "--delta",
        "1.4986",
        "--episodes",
        "400",
        "--seed",
        "3",
        "--json",
    ];
    let v = ok_json(&args);
    assert_eq!(v["episodes"], 400);
    for k in [
        "p_target",
        "p_collision",
        "p_free",
        "energy_mean",
        "steps_mean",
        "trigger_rate",
        "trigger_rate_expected",
    ] {
        assert!(v[k].is_number(), "{k} missing");
        assert!(v[format!("{k}_ci95")].is_number(), "{k}_ci95 missing");
    }
    let total = v["p_target"].as_f64().unwrap_or(0.0)
        + v["p_collision"].as_f64().unwrap_or(0.0)
        + v["p_free"].as_f64().unwrap_or(0.0);
    assert!((total - 1.0).abs() < 1e-12);
    assert_eq!(ok_json(&args), v, "same seed, same numbers");
    let other = ok_json(&[
        "simulate",
        "winding-2d",
        "--delta",
        "1.4986",
        "--episodes",
        "400",
        "--seed",
        "4",
        "--json",
    ]);
    assert_ne!(other, v);
}

#[test]
fn full_kf_transmits_everything() {
    let v = ok_json(&[
        "simulate",
        "open-2d",
        "--delta",
        "0",
        "--episodes",
        "200",
        "--json",
    ]);
    assert_eq!(v["trigger_rate"], 1.0);
    assert_eq!(v["trigger_rate_expected"], 1.0);
}

#[test]
fn bad_input_is_refused_with_a_reason() {
    fails_with(
        &["simulate", "windy-2d", "--delta", "0"],
        &["windy-2d", "winding-2d"],
    );
    fails_with(&["simulate", "winding-2d", "--delta", "-1"], &["--delta"]);
    fails_with(
        &["simulate", "winding-2d", "--delta", "0", "--episodes", "0"],
        &["--episodes"],
    );
    let dir = Scratch::new("bad-scenario");
    let text = etp_shared_text().replace("sensor = \"s3\"", "sensor = \"nobody\"");
    let path = dir.path("bad.toml");
    std::fs::write(&path, text).expect("write");
    fails_with(&["check", s(&path)], &["leg[", "sensor", "unknown sensor"]);
    std::fs::write(&path, "dim = [").expect("write");
    fails_with(&["check", s(&path)], &["not valid TOML"]);
}

fn etp_shared_text() -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/winding-2d.toml"),
    )
    .expect("scenario")
}

/// Piped stderr (not a terminal): a plain progress line every
/// `ETP_PROGRESS_SECONDS` instead of a bar; `--json` keeps stderr quiet.
#[test]
fn piped_progress_prints_lines() {
    let run = |json: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_etp"));
        c.args([
            "simulate",
            "winding-2d",
            "--delta",
            "1.4986",
            "--episodes",
            "3000",
        ])
        .env("ETP_PROGRESS_SECONDS", "0.05")
        .env("RAYON_NUM_THREADS", "1");
        if json {
            c.arg("--json");
        }
        c.output().expect("spawn etp")
    };
    let out = run(false);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let line = err
        .lines()
        .find(|l| l.starts_with("simulate: ") && l.contains("/3000 (") && l.contains(" s"))
        .unwrap_or_else(|| panic!("no progress line in {err:?}"));
    assert!(
        line.contains("% ) after") || line.contains("%) after"),
        "{line}"
    );
    let quiet = run(true);
    assert!(quiet.status.success());
    assert!(
        quiet.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&quiet.stderr)
    );
}

/// A lossy radio (docs/MODEL.md §8): attempts add up, the counts are per
/// sensor, and the options are checked with their names.
#[test]
fn simulate_with_a_lossy_radio_counts_attempts_and_names_bad_options() {
    let base = [
        "simulate",
        "winding-2d",
        "--delta",
        "1.4986",
        "--episodes",
        "300",
        "--seed",
        "2",
        "--json",
    ];
    let ideal = ok_json(&base);
    assert_eq!(ideal["radio"], "ideal");
    assert_eq!(ideal["lost"], 0);
    assert_eq!(ideal["transmissions"], ideal["delivered"]);
    assert_eq!(ideal["transmissions"], ideal["triggers"]);
    let mut args = base.to_vec();
    args.extend(["--loss", "0.3", "--retries", "1"]);
    let v = ok_json(&args);
    let n = |v: &serde_json::Value, k: &str| v[k].as_u64().unwrap_or(u64::MAX);
    assert_eq!(n(&v, "transmissions"), n(&v, "delivered") + n(&v, "lost"));
    assert!(n(&v, "lost") > 0 && n(&v, "delivered") <= n(&v, "triggers"));
    assert!(
        v["radio"]
            .as_str()
            .unwrap_or("")
            .contains("loss 0.3, retries 1")
    );
    assert!(v["nees"].as_f64().is_some_and(|x| x > 0.0));
    let mut sum = 0;
    for s in v["sensors"].as_array().expect("sensors") {
        assert_eq!(n(s, "transmissions"), n(s, "delivered") + n(s, "lost"));
        sum += n(s, "lost");
    }
    assert_eq!(sum, n(&v, "lost"));
    for (opt, val) in [("--loss", "1.0"), ("--retries", "-1"), ("--burst", "0.5")] {
        let mut args = base.to_vec();
        args.extend(["--loss", "0.2", opt, val]);
        if opt == "--loss" {
            args.truncate(base.len());
            args.extend([opt, val]);
        }
        fails_with(&args, &[opt]);
    }
    let mut args = base.to_vec();
    args.extend(["--estimator", "smart"]);
    fails_with(&args, &["--estimator"]);
}
