//! Every kind of MDP etp writes, checked by an independent model checker:
//! Storm (stormpy, in the pinned venv) loads `etp export --format drn` and
//! `--format jani` as written (`storm_check.py`) and
//! * its Pmax=? [F "tar"] and Pmin=? [F "coll"] equal front.json's extremes
//!   (1e-9), on the DRN and the JANI model alike;
//! * its least energy under P_tar ≥ p (and P_coll ≤ c), for queries across
//!   the front, equals `etp strategy --quick`'s MDP value within the
//!   precision Storm is asked for (absolute), and to 1e-9 in its exact
//!   (rational) mode where that is run; both say infeasible alike;
//! * the JANI properties' answers equal the etp values the export wrote
//!   beside them;
//! * its Pareto curve `multi(Pmax=? [F "tar"], R{"energy"}min=? [C])` lies
//!   within front.json's certified ε of etp's front, and etp's vertices lie
//!   in Storm's over-approximation;
//! * the optimal schedulers Storm returns, evaluated by etp's own policy
//!   evaluation, give the values Storm computes on the chains they induce.
//!
//! The built-in scenarios are checked on the syntheses of `exact.rs` (one
//! synthesis for both independent checks); here a random agent of
//! dimension 4 and 6, a lossy radio and a stochastic trigger.

use super::exact::{etp_answers, synthesize};
use super::{Scratch, etp_threads, s};
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::policy::{as_randomised, evaluate};
use serde_json::{Value, json};
use std::io::Write as _;
use std::path::Path;
use std::process::{Command, Stdio};

/// The absolute precision Storm's multi-objective queries are asked for.
const PRECISION: f64 = 1e-6;
/// The precision of Storm's Pareto curve (its points are achievable at any
/// precision; 1e-4 takes a minute on these MDPs).
const PARETO_PRECISION: f64 = 1e-3;

fn run_ok(args: &[&str]) {
    let out = etp_threads(args, "2");
    assert!(
        out.status.success(),
        "etp {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("a number, got {v}"))
}

/// Storm's answers on the exports of `dir` (storm_check.py).
fn storm(dir: &Path, request: &Value) -> Value {
    let (drn, jani) = (dir.join("drn"), dir.join("jani"));
    for (out, format) in [(&drn, "drn"), (&jani, "jani")] {
        run_ok(&["export", s(dir), s(out), "--format", format, "--force"]);
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/cli/storm_check.py");
    let mut child = Command::new(super::pyenv::python())
        .arg(script)
        .arg(&drn)
        .arg(&jani)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run python");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(request.to_string().as_bytes())
        .expect("write the request");
    let out = child.wait_with_output().expect("storm_check.py");
    assert!(
        out.status.success(),
        "storm_check.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

/// The least energy of a mixture of front vertices with P_tar ≥ `p` (the
/// front's lower envelope in the (P_tar, energy) plane), None above its top.
fn envelope(vertices: &[(f64, f64)], p: f64) -> Option<f64> {
    let mut best: Option<f64> = None;
    let mut keep = |e: f64| best = Some(best.map_or(e, |b| b.min(e)));
    for &(pa, ea) in vertices {
        if pa >= p {
            keep(ea);
        }
        for &(pb, eb) in vertices {
            if pa < p && p < pb {
                keep(ea + (eb - ea) * (p - pa) / (pb - pa));
            }
        }
    }
    best
}

/// The largest disagreements found, for the report.
#[derive(Debug, Default)]
pub(super) struct Agreement {
    pub extremes: f64,
    pub least_energy: f64,
    pub least_energy_exact: Option<f64>,
    pub pareto_excess: f64,
    pub schedulers: f64,
}

/// Storm's answers on the synthesis in `dir` against etp's: `answers` from
/// [`etp_answers`], `exact` to also run Storm's rational arithmetic.
pub(super) fn agrees_with_storm(
    name: &str,
    dir: &Path,
    answers: &[super::exact::Answer],
    exact: bool,
) -> Agreement {
    let request = json!({
        "queries": answers.iter().map(|(q, _)| json!([q.0, q.1])).collect::<Vec<_>>(),
        "precision": PRECISION,
        "pareto_precision": PARETO_PRECISION,
        "exact": exact,
    });
    let st = storm(dir, &request);
    let mdp = Mdp::decode(&std::fs::read(dir.join("mdp.bin")).expect("mdp.bin")).expect("mdp");
    let front: Value =
        serde_json::from_slice(&std::fs::read(dir.join("front.json")).expect("front.json"))
            .expect("json");
    let mut agreement = Agreement::default();

    // The model Storm built is the one exported.
    let states = mdp.states.len() + 3;
    let choices = mdp.states.iter().map(|s| s.choices.len()).sum::<usize>() + 3;
    for m in [&st["model"], &st["jani_model"]] {
        assert_eq!(m["rewards"], json!(["energy"]), "{name}: {m}");
        for label in ["init", "coll", "tar", "free"] {
            assert!(
                m["labels"]
                    .as_array()
                    .is_some_and(|l| l.contains(&json!(label))),
                "{name}: no label {label}: {m}"
            );
        }
    }
    assert_eq!(st["model"]["states"], json!(states), "{name}");
    assert_eq!(st["model"]["choices"], json!(choices), "{name}");
    assert_eq!(st["model"]["initial"], json!([mdp.initial]), "{name}");

    // Extremes: Storm on both models against front.json's vertices.
    let vertices = front["vertices"].as_array().expect("vertices");
    let objective = |key: &str| -> Vec<f64> {
        vertices
            .iter()
            .map(|v| num(&v["objectives"][key]))
            .collect()
    };
    let max_target = objective("p_target").into_iter().fold(0.0, f64::max);
    let min_collision = objective("p_collision").into_iter().fold(1.0, f64::min);
    for (storm_value, etp_value, what) in [
        (num(&st["max_target"]), max_target, "Pmax F tar"),
        (
            num(&st["jani"]["max_target"]),
            max_target,
            "JANI Pmax F tar",
        ),
        (num(&st["min_collision"]), min_collision, "Pmin F coll"),
        (
            num(&st["jani"]["min_collision"]),
            min_collision,
            "JANI Pmin F coll",
        ),
    ] {
        let d = (storm_value - etp_value).abs();
        assert!(
            d <= 1e-9,
            "{name} {what}: Storm {storm_value} vs front.json {etp_value}"
        );
        agreement.extremes = agreement.extremes.max(d);
    }

    // The JANI properties: Storm's answers against etp's, written beside them.
    let jani: Value =
        serde_json::from_slice(&std::fs::read(dir.join("jani/model.jani")).expect("model.jani"))
            .expect("json");
    for p in jani["properties"].as_array().expect("properties") {
        let pname = p["name"].as_str().expect("name");
        let answer = &st["jani"][pname];
        let comment = p["comment"].as_str().unwrap_or("");
        if pname.starts_with("infeasible") {
            assert_eq!(answer, &json!(false), "{name} {pname}: {answer}");
        } else if let Some(e) = comment
            .split("(etp: ")
            .nth(1)
            .and_then(|t| t.trim_end_matches(')').parse::<f64>().ok())
        {
            // Storm's default precision here: 1e-4, absolute.
            let d = (num(answer) - e).abs();
            assert!(d <= 1e-4, "{name} {pname}: Storm {answer} vs etp {e}");
        } else {
            // The Pareto curve: checked on the DRN model below.
            assert!(pname.starts_with("pareto"), "{name} {pname}: {comment}");
        }
    }

    // Least energy under constraints, against `etp strategy --quick`.
    let storm_least = st["least_energy"].as_array().expect("least_energy");
    let exact_least = st["least_energy_exact"].as_array();
    assert_eq!(exact_least.is_some(), exact, "{name}: exact mode ran?");
    for (k, ((p, c), ours)) in answers.iter().enumerate() {
        let theirs = storm_least[k].as_f64();
        match (ours, theirs) {
            (Some(a), Some(b)) => {
                let d = (a - b).abs();
                assert!(
                    d <= PRECISION,
                    "{name} P>={p} P_coll<={c:?}: etp {a} vs Storm {b} (precision {PRECISION})"
                );
                agreement.least_energy = agreement.least_energy.max(d);
            }
            (None, None) => {}
            _ => panic!(
                "{name} P>={p} P_coll<={c:?}: feasibility differs: etp {ours:?}, Storm {theirs:?}"
            ),
        }
        if let Some(ex) = exact_least {
            let b = ex[k].as_f64();
            match (ours, b) {
                (Some(a), Some(b)) => {
                    let d = (a - b).abs() / b.abs().max(1.0);
                    assert!(
                        d <= 1e-9,
                        "{name} P>={p} P_coll<={c:?}: etp {a} vs exact Storm {b}"
                    );
                    let m = agreement.least_energy_exact.get_or_insert(0.0);
                    *m = m.max(d);
                }
                (None, None) => {}
                _ => panic!(
                    "{name} P>={p} P_coll<={c:?}: feasibility differs: etp {ours:?}, exact Storm {b:?}"
                ),
            }
        }
    }

    // Pareto curve against the certified front.
    let eps = num(&front["epsilon"]);
    let eps_energy = num(&front["epsilon_energy"]);
    let plane: Vec<(f64, f64)> = objective("p_target")
        .into_iter()
        .zip(objective("energy"))
        .collect();
    let points = st["pareto"]["points"].as_array().expect("points");
    assert!(!points.is_empty(), "{name}: no Pareto point");
    for pt in points {
        let (p, e) = (num(&pt[0]), num(&pt[1]));
        // Achievable (P_tar, energy) raised by ε is dominated by the front.
        let best = envelope(&plane, p - eps - 1e-12)
            .unwrap_or_else(|| panic!("{name}: Storm reaches P_tar {p} beyond etp's front"));
        let excess = best - e;
        assert!(
            excess <= eps_energy + 1e-9,
            "{name}: Storm's point (P_tar {p}, energy {e}) is below etp's front ({best}) by more than ε = {eps_energy}"
        );
        agreement.pareto_excess = agreement.pareto_excess.max(excess);
    }
    for (p, e) in &plane {
        for h in st["pareto"]["over"].as_array().expect("over") {
            let (a, b, off) = (num(&h[0]), num(&h[1]), num(&h[2]));
            assert!(
                a * p + b * e <= off + 1e-9 * (1.0 + e.abs()),
                "{name}: etp's vertex (P_tar {p}, energy {e}) outside Storm's over-approximation {h}"
            );
        }
    }

    // Storm's schedulers, evaluated by etp.
    for sc in st["schedulers"].as_array().expect("schedulers") {
        let choices: Vec<u16> = sc["choices"]
            .as_array()
            .expect("choices")
            .iter()
            .take(mdp.states.len())
            .map(|c| u16::try_from(c.as_u64().expect("a choice")).expect("u16"))
            .collect();
        let v = evaluate(&mdp, &as_randomised(&mdp, &choices), CostModel::Counted);
        let what = &sc["formula"];
        for (etp_value, key) in [
            (v.p_target, "p_target"),
            (v.p_collision, "p_collision"),
            (v.energy, "energy"),
        ] {
            let storm_value = num(&sc[key]);
            let d = (etp_value - storm_value).abs() / storm_value.abs().max(1.0);
            assert!(
                d <= 1e-9,
                "{name} scheduler of {what}: {key} etp {etp_value} vs Storm {storm_value}"
            );
            agreement.schedulers = agreement.schedulers.max(d);
        }
    }
    eprintln!("{name}: Storm agreement {agreement:?}");
    agreement
}

#[test]
fn storm_agrees_on_random_agents_a_lossy_radio_and_a_stochastic_trigger() {
    let scratch = Scratch::new("storm");
    let mut cases: Vec<(String, String, Vec<&str>)> = Vec::new();
    for (n, seed) in [("4", "3"), ("6", "2")] {
        let file = scratch.path(&format!("random-{n}.toml"));
        run_ok(&[
            "scenario",
            "random",
            "--dim-agent",
            n,
            "--seed",
            seed,
            "-o",
            s(&file),
        ]);
        cases.push((format!("random n={n}"), s(&file).to_string(), Vec::new()));
    }
    cases.push((
        "lossy".into(),
        "winding-2d".into(),
        vec!["--loss", "0.3", "--retries", "1"],
    ));
    cases.push((
        "stochastic".into(),
        "winding-2d".into(),
        vec!["--trigger", "stochastic"],
    ));
    for (k, (name, scenario, extra)) in cases.iter().enumerate() {
        let dir = scratch.path(&format!("case{k}"));
        synthesize(scenario, extra, &dir);
        let answers = etp_answers(&dir);
        agrees_with_storm(name, &dir, &answers, false);
    }
}
