//! `strategy.json` keeps every byte: files written by an earlier etp load,
//! and are written back exactly as the earlier code wrote them back, so the
//! file format (keys, their order, formatting, seal) is unchanged.
//!
//! The fixtures `*.json` were written by `etp` built from the code before
//! `Strategy` was split into its policy, predictions and provenance:
//! `etp synthesize open-2d --samples 40 -o d && etp strategy d --vertex 0 --quick`
//! (no `predicted`), and
//! `etp synthesize open-2d --samples 40 --loss 0.1 --split-budget 3 -o e &&
//! etp strategy e --vertex 1 --replicates 2 --aggregation-check 200 --confidence 0.9`
//! (`predicted`, `predicted_ci95`, `certified`, `radio`, `aggregation`).
//! `*.rewritten.json` is what that same code wrote back after reading each
//! (`Strategy::from_sealed_json` then `Strategy::to_json`). It is not the
//! fixture itself: serde_json (without its `float_roundtrip` feature) reads
//! some floats one unit in the last place off, so a few digits and the seal
//! differ — the comparison is therefore against the earlier code's own
//! rewrite, which differs from the new code's only if the format does.

use etp_shared::strategy::Strategy;

fn fixture(name: &str) -> String {
    let path = format!("{}/tests/fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn round_trip(stem: &str) {
    let text = fixture(&format!("{stem}.json"));
    let strategy = Strategy::from_sealed_json(&text).expect("an earlier etp's file loads");
    let expected = fixture(&format!("{stem}.rewritten.json"));
    let written = strategy.to_json();
    if written != expected {
        let line = written
            .lines()
            .zip(expected.lines())
            .position(|(a, b)| a != b)
            .map_or(0, |i| i + 1);
        panic!("{stem}: written back, the file differs from the earlier code's at line {line}");
    }
    // What the earlier code wrote back is itself a valid strategy file.
    Strategy::from_sealed_json(&expected).expect("sealed");
    strategy
        .policy
        .scenario()
        .expect("its embedded scenario, hash checked");
}

#[test]
fn a_quick_strategy_file_is_written_back_byte_identical() {
    round_trip("strategy-open-2d-quick");
}

#[test]
fn a_predicted_strategy_file_is_written_back_byte_identical() {
    round_trip("strategy-open-2d-predicted");
}
