//! synthesize → strategy → validate on open-2d, and every refusal on the way:
//! existing outputs, infeasible requests, corrupted or foreign files.

use super::{Scratch, etp, fails_with, ok_json, s};

#[test]
fn pipeline_predicts_what_simulation_measures_and_refuses_bad_files() {
    let dir = Scratch::new("pipeline");
    let out = dir.path("open");
    let synth = ok_json(&[
        "synthesize",
        "open-2d",
        "--samples",
        "1500",
        "--seed",
        "1",
        "-o",
        s(&out),
        "--json",
    ]);
    assert!(
        synth["front"]["vertices"].as_u64().unwrap_or(0) > 5,
        "{synth}"
    );
    for f in [
        "mdp.bin",
        "front.json",
        "front.png",
        "front.svg",
        "scenario.toml",
        "mdp-kf-convergence.bin",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let front: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("front.json")).expect("front"))
            .expect("json");
    assert!(
        front["kf_convergence"]["vertices"]
            .as_array()
            .is_some_and(|v| !v.is_empty())
    );
    assert_eq!(front["baselines"].as_array().map(Vec::len), Some(5));

    // The selection on the MDP (--quick): the realised ω's exact value is
    // the whole-MDP LP's optimum, and it meets the request there.
    let quick = out.join("quick.json");
    let q = ok_json(&[
        "strategy",
        s(&out),
        "--min-target",
        "0.95",
        "--quick",
        "-o",
        s(&quick),
        "--json",
    ]);
    let exact = &q["diagnostics"]["selection_time"];
    let value = exact["energy_mean"].as_f64().expect("energy");
    let lp = q["diagnostics"]["lp_objective"]
        .as_f64()
        .expect("cross-check");
    assert!(
        (value - lp).abs() <= 1e-6 * value.max(1.0),
        "realised ω {value} vs occupation LP {lp}"
    );
    assert!(exact["p_target"].as_f64().unwrap_or(0.0) >= 0.95 - 1e-9);
    // The default path: the request met by the prediction of its rebuilds.
    let sel = ok_json(&["strategy", s(&out), "--min-target", "0.95", "--json"]);
    assert_eq!(sel["verdict"], "met", "{sel}");
    assert!(
        sel["predicted"]["p_target"].as_f64().unwrap_or(0.0) >= 0.95,
        "{sel}"
    );

    // Validation in-process agrees with the prediction (fixed seed).
    let strategy = out.join("strategy.json");
    let v = ok_json(&["validate", s(&strategy), "--episodes", "3000", "--json"]);
    for (k, tol) in [("p_target", 0.02), ("p_collision", 0.02)] {
        let (p, m) = (
            v["predicted"][k].as_f64().unwrap_or(-1.0),
            v[k].as_f64().unwrap_or(9.0),
        );
        assert!((p - m).abs() <= tol, "{k}: predicted {p}, simulated {m}");
    }
    let (pe, me) = (
        v["predicted"]["energy_mean"].as_f64().unwrap_or(-1.0),
        v["energy_mean"].as_f64().unwrap_or(-1.0),
    );
    assert!(
        (pe - me).abs() <= 0.05 * pe,
        "energy: predicted {pe}, simulated {me}"
    );
    // The per-sensor prediction is the MDP's (strategy.json `leg_energy`):
    // it adds up to the predicted energy, and `etp run` prints the same.
    let per_sensor: Vec<f64> = v["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .map(|x| {
            x["predicted_energy"]
                .as_f64()
                .expect("predicted_energy from the MDP")
        })
        .collect();
    let episodes = v["episodes"].as_f64().expect("episodes");
    assert!(
        (per_sensor.iter().sum::<f64>() - pe * episodes).abs() <= 1e-4 * pe * episodes,
        "{per_sensor:?} vs {pe} × {episodes}"
    );
    let run_id = format!("t{}-pipeline", std::process::id());
    let r = ok_json(&[
        "run",
        s(&strategy),
        "--episodes",
        "2",
        "--run-id",
        &run_id,
        "--json",
    ]);
    assert!(
        r["predicted_energy_from"]
            .as_str()
            .is_some_and(|f| f.contains("MDP")),
        "{}",
        r["predicted_energy_from"]
    );
    for (x, want) in r["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .zip(&per_sensor)
    {
        let got = x["predicted_energy"].as_f64().expect("predicted_energy");
        assert!(
            (got - want * 2.0 / episodes).abs() <= 1e-6 * want.max(1.0),
            "{got} vs {want}"
        );
    }

    // No silent overwrite.
    let plot_args = [
        "validate",
        s(&strategy),
        "--episodes",
        "50",
        "--plot",
        "--plot-episodes",
        "5",
        "--json",
    ];
    ok_json(&plot_args);
    let map = out.join("strategy-map.png");
    let drawn = std::fs::read(&map).expect("map plot");
    fails_with(&plot_args, &["strategy-map", "already exists", "--force"]);
    assert_eq!(std::fs::read(&map).expect("map plot"), drawn);
    let before = std::fs::read(&strategy).expect("strategy");
    fails_with(
        &["strategy", s(&out), "--vertex", "0"],
        &["already exists", "--force"],
    );
    assert_eq!(std::fs::read(&strategy).expect("strategy"), before);

    // A request beyond the MDP's front is out of reach: the strategy at
    // the front's edge is written with its prediction, exit 7 (README).
    let far = etp(&[
        "strategy",
        s(&out),
        "--min-target",
        "0.99999",
        "-o",
        s(&dir.path("x.json")),
    ]);
    let err = String::from_utf8_lossy(&far.stderr);
    assert_eq!(far.status.code(), Some(7), "{err}");
    assert!(
        err.contains("out of reach") && err.contains("against P_tar ≥ 0.99999"),
        "{err}"
    );
    let edge: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path("x.json")).expect("the closest strategy"))
            .expect("strategy JSON");
    assert!(
        edge["predicted"]["p_target"]
            .as_f64()
            .is_some_and(|p| p > 0.9 && p < 0.99999),
        "{}",
        edge["predicted"]
    );
    std::fs::remove_file(dir.path("x.json")).expect("remove x.json");
    fails_with(
        &[
            "strategy",
            s(&out),
            "--vertex",
            "100000",
            "-o",
            s(&dir.path("x.json")),
        ],
        &["vertex 100000"],
    );
    fails_with(
        &["strategy", s(&out), "--min-target", "1.5"],
        &["--min-target"],
    );

    // A strategy whose embedded scenario was edited: the file's seal no
    // longer matches; re-sealed (forged), the scenario hash still refuses it.
    let text = String::from_utf8(before.clone()).expect("utf-8");
    let tampered = text.replacen("k_max = 200", "k_max = 150", 1);
    assert_ne!(tampered, text, "strategy embeds the scenario text");
    std::fs::write(dir.path("tampered.json"), tampered).expect("write");
    fails_with(
        &["validate", s(&dir.path("tampered.json"))],
        &["changed after it was written"],
    );
    let mut forged = etp_shared::strategy::Strategy::from_sealed_json(&text).expect("sealed");
    forged.policy.scenario_toml = forged
        .policy
        .scenario_toml
        .map(|t| t.replacen("k_max = 200", "k_max = 150", 1));
    std::fs::write(dir.path("tampered.json"), forged.to_json()).expect("write");
    fails_with(
        &["validate", s(&dir.path("tampered.json"))],
        &["made for scenario", "hash"],
    );
    // Truncated strategy.
    std::fs::write(dir.path("cut.json"), &before[..before.len() / 2]).expect("write");
    fails_with(&["validate", s(&dir.path("cut.json"))], &["not valid JSON"]);

    // Truncated and corrupted mdp.bin.
    let broken = dir.path("broken");
    std::fs::create_dir_all(&broken).expect("dir");
    let mdp = std::fs::read(out.join("mdp.bin")).expect("mdp");
    std::fs::write(broken.join("mdp.bin"), &mdp[..mdp.len() / 3]).expect("write");
    fails_with(
        &["strategy", s(&broken), "--vertex", "0"],
        &["mdp.bin is corrupted: checksum mismatch"],
    );
    let mut flipped = mdp.clone();
    flipped[0] ^= 0xff;
    std::fs::write(broken.join("mdp.bin"), &flipped).expect("write");
    fails_with(
        &["strategy", s(&broken), "--vertex", "0"],
        &["not an etp MDP file"],
    );
    // A front.json of another MDP is refused.
    std::fs::write(broken.join("mdp.bin"), &mdp).expect("write");
    std::fs::write(broken.join("front.json"), "{\"format_version\": 1}").expect("write");
    fails_with(&["strategy", s(&broken), "--vertex", "0"], &["front.json"]);
    let _ = etp(&["--help"]);
}
