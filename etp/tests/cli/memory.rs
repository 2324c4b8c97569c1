//! Issue 24 item 7: `etp replay export` and the summary (`etp replay FILE`)
//! stream a finished recording chunk by chunk, so their peak memory does not
//! grow with the recording's length.

use super::{Scratch, s};
use std::process::Command;

/// Peak resident set (KiB) of one `etp` child: the pinned venv's Python runs
/// it as its only child and reports `RUSAGE_CHILDREN`'s `ru_maxrss`, the peak
/// of that very process (the workspace forbids `unsafe`, so no `wait4` here).
fn peak_rss_kib(args: &[&str]) -> i64 {
    let script = r#"
import resource, subprocess, sys
r = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
if r.returncode != 0:
    sys.exit(f"etp exited {r.returncode}")
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
"#;
    let out = Command::new(crate::pyenv::python())
        .args(["-c", script, env!("CARGO_BIN_EXE_etp")])
        .args(args)
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "etp {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .trim()
        .parse()
        .expect("ru_maxrss in KiB")
}

fn record(dir: &Scratch, name: &str, episodes: &str) -> std::path::PathBuf {
    let rec = dir.path(name);
    let id = format!("t{}-mem{episodes}", std::process::id());
    let out = Command::new(env!("CARGO_BIN_EXE_etp"))
        .args([
            "run",
            "--scenario",
            "winding-2d",
            "--delta",
            "1.4986",
            "--episodes",
            episodes,
            "--seed",
            "3",
            "--run-id",
            &id,
            "--record",
            s(&rec),
            "--json",
        ])
        .output()
        .expect("etp run");
    assert!(
        out.status.success(),
        "etp run: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    rec
}

#[test]
fn export_peak_memory_is_flat_in_the_recordings_length() {
    let dir = Scratch::new("memory");
    let short = record(&dir, "short.mcap", "40");
    let long = record(&dir, "long.mcap", "400");
    let size = |p: &std::path::Path| std::fs::metadata(p).expect("size").len();
    assert!(
        size(&long) > 8 * size(&short),
        "the long recording is not ~10× the short one: {} vs {} bytes",
        size(&long),
        size(&short)
    );
    let export = |rec: &std::path::Path, out: &str| {
        peak_rss_kib(&["replay", "export", s(rec), s(&dir.path(out))])
    };
    let summary = |rec: &std::path::Path| peak_rss_kib(&["replay", s(rec), "--json"]);
    for (what, a, b) in [
        ("export", export(&short, "short"), export(&long, "long")),
        ("summary", summary(&short), summary(&long)),
    ] {
        eprintln!(
            "{what} peak RSS: {a} KiB for {} bytes, {b} KiB for {} bytes",
            size(&short),
            size(&long)
        );
        // Loading the file whole costs several times its size in memory
        // (the bytes, then every message as an owned vector); 10× the data
        // at flat memory stays well under 1.5×.
        assert!(
            (b as f64) < 1.5 * a as f64,
            "{what}: peak RSS grew with the recording: {a} KiB → {b} KiB"
        );
    }
}
