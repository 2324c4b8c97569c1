//! Trigger families other than the paper's (docs/MODEL.md §9) in the
//! multi-process runtime: the sensor process decides with the scenario's
//! family, the agent (and the sensor's replica) update with the family's
//! silence, every count identity holds, and `replay verify` re-draws every
//! decision — for the stochastic family its random draw — from the
//! recorded true states; the Foxglove copy of each family's recording has
//! every slot and transmission.

use super::recording::{out_file, replay};
use super::{DELTA, assert_ledgers_match, serial};
use etp_tests::{EtpRun, unique_run_id};
use serde_json::Value;

/// `etp run --scenario winding-2d --delta DELTA --trigger FAMILY`, recorded;
/// the run's JSON and the recording's `replay verify` JSON.
fn run_and_verify(family: &str, episodes: &str) -> (Value, Value) {
    // Short: iceoryx2 bounds a service name's length (`etp/<run-id>/…`).
    let id = unique_run_id(&format!("fam-{}", &family[..3]));
    let file = out_file(&id);
    let (ok, out, err) = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--trigger",
            family,
            "--episodes",
            episodes,
            "--seed",
            "11",
            "--record",
            &file.display().to_string(),
            "--episode-details",
        ],
    )
    .finish();
    assert!(ok, "etp run --trigger {family} failed: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"));
    let r = replay(&["verify", &file.display().to_string()]);
    // The Foxglove copy of the family's recording: its agent's ellipses come
    // from the same family-aware re-run, one per slot, and every delivered
    // measurement is a transmission.
    let fox = file.with_extension("fox.mcap");
    let f = replay(&[
        "foxglove",
        &file.display().to_string(),
        &fox.display().to_string(),
    ]);
    let st = &f["foxglove"];
    let counts = &v["recording"]["counts"];
    let n = |x: &Value| {
        x.as_u64()
            .unwrap_or_else(|| panic!("{family}: not a count: {x}"))
    };
    assert!(n(&counts["slot"]) > 0, "{family}: {counts}");
    assert_eq!(
        n(&st["topics"]["/agent"]),
        n(&counts["slot"]),
        "{family}: {st}"
    );
    assert_eq!(
        n(&st["topics"]["/transmissions"]),
        n(&counts["measurement"]),
        "{family}: {st}"
    );
    assert_eq!(
        st["incomplete_episodes"].as_u64(),
        Some(0),
        "{family}: {st}"
    );
    let _ = std::fs::remove_file(&fox);
    let _ = std::fs::remove_file(&file);
    (v, r)
}

fn sum(v: &Value, k: &str) -> u64 {
    v["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .map(|s| s[k].as_u64().unwrap_or_else(|| panic!("no `{k}` in {s}")))
        .sum()
}

/// The verify report passed, re-drew every slot's decision, and the file's
/// identities hold; returns the slots re-run.
fn assert_verified(r: &Value, transmissions: u64) -> u64 {
    assert_eq!(r["identities_hold"].as_bool(), Some(true), "{r}");
    assert_eq!(r["transmissions"].as_u64(), Some(transmissions), "{r}");
    let verify = &r["verify"];
    assert_eq!(verify["passed"].as_bool(), Some(true), "{verify}");
    let slots = verify["explicit_updates"].as_u64().expect("explicit")
        + verify["implicit_updates"].as_u64().expect("implicit");
    assert!(slots > 0, "{verify}");
    assert_eq!(
        verify["decisions_checked"].as_u64(),
        Some(slots),
        "every slot's decision re-drawn: {verify}"
    );
    slots
}

#[test]
fn a_stochastic_run_sends_at_its_rate_counts_exactly_and_replay_redraws_every_decision() {
    let _serial = serial();
    let (v, r) = run_and_verify("stochastic", "40");
    assert_ledgers_match(&v, false);
    let sent = sum(&v, "transmissions");
    assert_eq!(sum(&v, "received"), sent, "ideal radio: every send arrives");
    let slots = assert_verified(&r, sent);
    // winding-2d's sensors measure the position (m = 2): the stochastic
    // trigger sends with probability 1 − (1 + δ⁻²)^(−1) = 1/(1 + δ²) per
    // slot under the filter's model (docs/MODEL.md §9). Slots of one episode
    // are not independent draws of ε but the whitened innovations are
    // (the filter's model holds): a binomial band of ±4σ.
    let delta: f64 = DELTA.parse().expect("delta");
    let expected = 1.0 / (1.0 + delta * delta);
    let rate = sent as f64 / slots as f64;
    let sigma = (expected * (1.0 - expected) / slots as f64).sqrt();
    assert!(
        (rate - expected).abs() <= 4.0 * sigma,
        "stochastic rate {rate:.4} over {slots} slots, expected {expected:.4} ± {:.4}",
        4.0 * sigma
    );
}

#[test]
fn the_deterministic_families_and_send_on_delta_run_as_processes_and_verify_bit_for_bit() {
    let _serial = serial();
    for family in ["variance", "periodic", "send-on-delta"] {
        let (v, r) = run_and_verify(family, "6");
        assert_ledgers_match(&v, false);
        let sent = sum(&v, "transmissions");
        assert_eq!(sum(&v, "received"), sent, "{family}");
        assert_verified(&r, sent);
    }
}
