//! Acceptance of issue 42: mdp.bin, front.json, strategy.json and the JSON
//! of `validate` and `simulate` byte-identical for 1, 2 and 4 ranks × 1 and
//! 2 threads, against the plain build's run, on winding-2d and on a random
//! scenario with n = 6. Small sample counts: the bytes are what is compared.

use super::{ETP, etp, expect, require_mpirun, scratch};
use std::path::Path;

/// What a configuration is compared on.
const NAMES: [&str; 5] = [
    "mdp.bin",
    "front.json",
    "strategy.json",
    "validate --json",
    "simulate --json",
];

/// Drop the wall-clock keys of a JSON report (the only bytes that may
/// differ between two runs): every object key ending in `seconds`.
fn without_timing(bytes: &[u8], what: &str) -> Vec<u8> {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.retain(|k, _| !k.ends_with("seconds"));
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_slice(bytes)
        .unwrap_or_else(|e| panic!("{what}: not JSON ({e}): {}", String::from_utf8_lossy(bytes)));
    strip(&mut v);
    serde_json::to_vec(&v).expect("JSON encodes")
}

/// The outputs of one configuration on `scenario`, in [`NAMES`] order.
fn outputs(
    scenario: &str,
    target: &str,
    extra: &[&str],
    ranks: Option<u32>,
    threads: u32,
    root: &Path,
) -> Vec<Vec<u8>> {
    let tag = format!(
        "{}x{threads}",
        ranks.map_or("plain".into(), |n| n.to_string())
    );
    let dir = root.join(&tag);
    let d = dir.to_str().expect("utf-8 path");
    let mut synth = vec![
        "synthesize",
        scenario,
        "--samples",
        "60",
        "--aggregation-episodes",
        "300",
        "--seed",
        "1",
        "-o",
        d,
    ];
    synth.extend_from_slice(extra);
    expect(
        etp(ranks, threads, &synth),
        &[0],
        &format!("{tag} synthesize"),
    );
    // The request loop with its rebuilds; out of reach (exit 7) still
    // writes the closest strategy, whose bytes are compared the same.
    let strategy = [
        "strategy",
        d,
        "--min-target",
        target,
        "--replicates",
        "2",
        "--rounds",
        "2",
        "--aggregation-check",
        "200",
    ];
    expect(
        etp(ranks, threads, &strategy),
        &[0, 7],
        &format!("{tag} strategy"),
    );
    let st = dir.join("strategy.json");
    let st = st.to_str().expect("utf-8");
    let validate = ["validate", st, "--episodes", "300", "--json"];
    // Exit 6 (a check fails at so few episodes) is an outcome, not an error.
    let v = expect(
        etp(ranks, threads, &validate),
        &[0, 6],
        &format!("{tag} validate"),
    );
    let simulate = [
        "simulate",
        scenario,
        "--delta",
        "1.5",
        "--episodes",
        "300",
        "--json",
    ];
    let s = expect(
        etp(ranks, threads, &simulate),
        &[0],
        &format!("{tag} simulate"),
    );
    let read = |n: &str| std::fs::read(dir.join(n)).unwrap_or_else(|e| panic!("{tag}: {n}: {e}"));
    vec![
        read("mdp.bin"),
        read("front.json"),
        read("strategy.json"),
        without_timing(&v, "validate"),
        without_timing(&s, "simulate"),
    ]
}

/// Every configuration against the plain build's outputs.
/// `target`: the `--min-target` request (one the request loop can handle
/// on that scenario at these sample counts); `extra`: more `synthesize`
/// options.
fn same_bytes(scenario: &str, target: &str, extra: &[&str], root: &Path) {
    let reference = outputs(scenario, target, extra, None, 2, &root.join("plain"));
    for ranks in [1, 2, 4] {
        for threads in [1, 2] {
            let got = outputs(scenario, target, extra, Some(ranks), threads, root);
            for (k, name) in NAMES.iter().enumerate() {
                assert!(
                    got[k] == reference[k],
                    "{scenario}: {name} differs on {ranks} ranks × {threads} threads from the plain run"
                );
            }
        }
    }
}

#[test]
fn winding_2d_same_bytes_for_any_number_of_ranks_and_threads() {
    require_mpirun();
    let root = scratch("bytes-winding");
    same_bytes("winding-2d", "0.9", &[], &root);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn random_n6_same_bytes_for_any_number_of_ranks_and_threads() {
    require_mpirun();
    let root = scratch("bytes-random6");
    let toml = root.join("random6.toml");
    let out = std::process::Command::new(ETP)
        .args([
            "scenario",
            "random",
            "--dim-agent",
            "6",
            "--seed",
            "3",
            "-o",
        ])
        .arg(&toml)
        .output()
        .expect("etp starts");
    expect(out, &[0], "scenario random");
    // 4 magnitude bins (default 12): 113 states instead of 371, whose
    // Pareto front (46 MB of front.json, computed on every rank) made each
    // configuration's synthesis ~20 s instead of ~3 s; the Monte Carlo
    // shared across ranks is the same kind.
    same_bytes(
        toml.to_str().expect("utf-8"),
        "0.6",
        &["--magnitude-bins", "4"],
        &root,
    );
    let _ = std::fs::remove_dir_all(&root);
}
