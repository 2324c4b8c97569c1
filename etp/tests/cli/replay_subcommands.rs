//! `etp replay`'s subcommands (`info`, `cat`, `filter`, `summary`, …) on the
//! fixture recording, on MCAP files etp did not write (its Foxglove copy and
//! one written by Python's `mcap` package), complete vs partial episodes and
//! the identity exit code.

use super::{Scratch, etp, fails_with, ok_json, s};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/fixtures/open-2d-4-episodes.mcap")
}

fn code(args: &[&str]) -> (Option<i32>, String, String) {
    let out = etp(args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn one_tool_per_subcommand_and_the_old_flags_are_refused() {
    let f = fixture();
    // The flags of the previous release (`etp replay FILE --info`, …) are
    // unknown to the parser: exit 2, nothing written.
    for flag in [
        "--info",
        "--cat",
        "--verify",
        "--publish",
        "--plot",
        "--export",
        "--repair",
        "--foxglove",
    ] {
        let (rc, out, err) = code(&["replay", s(&f), flag, "x"]);
        assert_eq!(rc, Some(2), "{flag}: {err}");
        assert!(out.is_empty() && err.contains(flag), "{flag}: {err}");
    }
    assert!(!Path::new("x").exists());
    let plain = ok_json(&["replay", s(&f), "--json"]);
    assert_eq!(plain, ok_json(&["replay", "summary", s(&f), "--json"]));
    let v = ok_json(&["replay", "verify", s(&f), "--json"]);
    assert_eq!(v["verify"]["passed"], true, "{v}");
    let (rc, out, _) = code(&["replay", "cat", s(&f), "--topics", "outcome"]);
    assert_eq!(rc, Some(0));
    assert_eq!(out.lines().count(), 4);
    // The help names the tools and no rustdoc link.
    let help = String::from_utf8_lossy(&etp(&["replay", "--help"]).stdout).into_owned();
    for tool in [
        "info", "cat", "export", "filter", "verify", "repair", "publish", "foxglove",
    ] {
        assert!(help.contains(tool), "{tool} missing in\n{help}");
    }
    assert!(!help.contains("[`"), "a rustdoc link in\n{help}");
}

/// The fixture summarised: complete episodes, per-sensor received, intervals,
/// identities.
#[test]
fn the_summary_counts_complete_episodes_with_intervals_and_received() {
    let v = ok_json(&["replay", s(&fixture()), "--json"]);
    assert_eq!(v["episodes"], 4);
    assert_eq!(v["partial"]["episodes"], Value::Array(vec![]));
    assert_eq!(v["identities_hold"], true, "{v}");
    for k in [
        "p_target_ci95",
        "p_collision_ci95",
        "p_free_ci95",
        "energy_mean_ci95",
    ] {
        assert!(v[k].as_f64().is_some_and(|x| x >= 0.0), "{k}: {v}");
    }
    let sensors = v["sensors"].as_array().expect("sensors");
    let received: u64 = sensors
        .iter()
        .map(|x| x["received"].as_u64().expect("received"))
        .sum();
    assert_eq!(Some(received), v["received"].as_u64(), "{v}");
    for x in sensors {
        assert_eq!(x["received"], x["measurements"], "{x}");
        assert_eq!(x["transmissions"], x["measurements"], "{x}");
    }
}

/// A file cut inside an episode (what a Ctrl-C or a killed agent leaves):
/// the cut episode is reported apart, never counted; a file whose complete
/// episodes lack their measurements exits 4.
#[test]
fn a_cut_episode_is_partial_and_a_failed_identity_exits_4() {
    let f = fixture();
    let dir = Scratch::new("replay-partial");
    let info = ok_json(&["replay", "info", s(&f), "--json"]);
    let d = info["duration_s"].as_f64().expect("duration");
    // Up to 80 % of the time span: the last episode is cut.
    let cut = dir.path("cut.mcap");
    let end = format!("{}", d * 0.8);
    ok_json(&["replay", "filter", s(&f), s(&cut), "--end", &end, "--json"]);
    let v = ok_json(&["replay", s(&cut), "--json"]);
    let partial = v["partial"]["episodes"].as_array().expect("partial");
    assert_eq!(partial.len(), 1, "{v}");
    assert!(v["episodes"].as_u64() < Some(4), "{v}");
    assert!(v["partial"]["messages"].as_u64() > Some(0));
    assert_eq!(v["identities_hold"], true, "{v}");
    let text = String::from_utf8_lossy(&etp(&["replay", s(&cut)]).stdout).into_owned();
    assert!(text.contains("partial (not counted)"), "{text}");
    // Without the `measurement` channel the identities that need it are not
    // checked (not failed): the channel is named, exit 5.
    let nomeas = dir.path("no-measurements.mcap");
    ok_json(&[
        "replay",
        "filter",
        s(&f),
        s(&nomeas),
        "--topics",
        "outcome,ledger,waypoint",
        "--json",
    ]);
    let (rc, out, err) = code(&["replay", s(&nomeas), "--json"]);
    assert_eq!(rc, Some(5), "{err}");
    let v: Value = serde_json::from_str(&out).expect("json");
    assert_eq!(v["identities_hold"], true, "{v}");
    assert_eq!(v["missing_channels"], serde_json::json!(["measurement"]));
    assert_eq!(v["measurements"], Value::Null);
    assert_eq!(v["episodes"], 4);
    assert!(err.contains("measurement"), "{err}");
}

/// A copy filtered to the `outcome` channel says what it cannot check
/// (issue 52 item 5): the missing channels named, what needs them null (–
/// in the table), no prediction judged on them, `verify` refused by name,
/// never "0 ± 0" or "not reproduced"; exit 5. The same selection asked with
/// `--topics` on the command line is the user's choice: exit 0.
#[test]
fn a_filtered_copy_names_what_it_cannot_check_and_exits_5() {
    let f = fixture();
    let dir = Scratch::new("replay-missing");
    let only = dir.path("outcome-only.mcap");
    ok_json(&[
        "replay",
        "filter",
        s(&f),
        s(&only),
        "--topics",
        "outcome",
        "--json",
    ]);
    let (rc, out, err) = code(&["replay", s(&only), "--json"]);
    assert_eq!(rc, Some(5), "{err}");
    let v: Value = serde_json::from_str(&out).expect("json");
    assert_eq!(
        v["missing_channels"],
        serde_json::json!(["ledger", "measurement", "waypoint"])
    );
    let full = ok_json(&["replay", s(&f), "--json"]);
    // What the outcomes measure is there, the same as the original's.
    for k in ["episodes", "p_target", "p_target_ci95", "p_collision_ci95"] {
        assert_eq!(v[k], full[k], "{k}");
    }
    for k in [
        "energy_mean",
        "energy_mean_ci95",
        "energy",
        "transmissions",
        "measurements",
    ] {
        assert_eq!(v[k], Value::Null, "{k}: {v}");
    }
    assert_eq!(v["identities_hold"], true, "{v}");
    if !v["prediction_check"].is_null() {
        assert!(
            v["prediction_check"]["energy_mean"]["unchecked"].is_string(),
            "{v}"
        );
        assert_eq!(v["prediction_check"]["family_size"], 2, "{v}");
    }
    let (rc, text, _) = code(&["replay", s(&only)]);
    assert_eq!(rc, Some(5));
    assert!(
        text.contains("MISSING channels: ledger, measurement, waypoint"),
        "{text}"
    );
    assert!(!text.contains("± 0") && !text.contains("OUTSIDE"), "{text}");
    let (rc, out, err) = code(&["replay", "verify", s(&only), "--json"]);
    assert_eq!(rc, Some(5), "{err}");
    let v: Value = serde_json::from_str(&out).expect("json");
    assert_eq!(v["verify"]["passed"], Value::Null, "{v}");
    let missing = v["verify"]["missing_channels"].as_array().expect("missing");
    for t in ["control", "waypoint", "sensor/0/threshold"] {
        assert!(missing.iter().any(|m| m == t), "{t}: {v}");
    }
    assert!(
        !err.contains("not reproduced") && err.contains("lacks"),
        "{err}"
    );
    // The same selection asked on the command line: exit 0.
    let (rc, _, err) = code(&["replay", s(&f), "--topics", "outcome", "--json"]);
    assert_eq!(rc, Some(0), "{err}");
}

/// `filter` writes a finished subset with every metadata record that
/// verifies, and the independent Python reader reads it.
#[test]
fn filter_writes_a_subset_that_verifies_and_python_reads() {
    let f = fixture();
    let dir = Scratch::new("replay-filter");
    let out = dir.path("two.mcap");
    let r = ok_json(&[
        "replay",
        "filter",
        s(&f),
        s(&out),
        "--episodes",
        "1..3",
        "--json",
    ]);
    let n = r["filtered"]["messages"].as_u64().expect("messages");
    let v = ok_json(&["replay", "verify", s(&out), "--json"]);
    assert_eq!(v["episodes"], 2, "{v}");
    assert_eq!(v["verify"]["passed"], true, "{v}");
    let a = ok_json(&["replay", "info", s(&f), "--json"]);
    let b = ok_json(&["replay", "info", s(&out), "--json"]);
    assert_eq!(a["metadata"], b["metadata"]);
    assert_eq!(b["finished"], true);
    // Refused when it exists.
    fails_with(
        &["replay", "filter", s(&f), s(&out), "--episodes", "1"],
        &["already exists", "--force"],
    );
    let py = python(
        r#"
import sys, json
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    n = sum(1 for _ in r.iter_messages())
    meta = sorted(m.name for m in r.iter_metadata())
print(json.dumps({"messages": n, "metadata": meta}))
"#,
        &out,
    );
    assert_eq!(py["messages"].as_u64(), Some(n));
    let names: Vec<String> = a["metadata"]
        .as_object()
        .expect("metadata")
        .keys()
        .cloned()
        .collect();
    assert_eq!(py["metadata"], serde_json::json!(names));
}

/// The JSON `script` prints, run by the test set-up's Python with `file`
/// as its argument.
pub(super) fn python(script: &str, file: &Path) -> Value {
    let out = Command::new(crate::pyenv::python())
        .args(["-c", script, s(file)])
        .output()
        .expect("python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("python JSON")
}

/// `info` and `cat` on files etp did not write: its own Foxglove copy (cut to
/// two episodes) and a file from Python's `mcap` writer (json and protobuf
/// channels).
#[test]
fn info_and_cat_read_any_mcap() {
    let dir = Scratch::new("replay-any-mcap");
    let fox = dir.path("fox.mcap");
    ok_json(&[
        "replay",
        "foxglove",
        s(&fixture()),
        s(&fox),
        "--episodes",
        "0..2",
        "--json",
    ]);
    let v = ok_json(&["replay", "info", s(&fox), "--json"]);
    let outcomes = v["channels"]
        .as_array()
        .expect("channels")
        .iter()
        .find(|c| c["topic"] == "/outcomes")
        .cloned()
        .expect("/outcomes");
    assert_eq!(outcomes["message_encoding"], "json", "{v}");
    assert_eq!(outcomes["schema_encoding"], "jsonschema", "{v}");
    assert_eq!(outcomes["messages"], 2, "two episodes: {v}");
    let (rc, out, err) = code(&["replay", "cat", s(&fox), "--topics", "/outcomes"]);
    assert_eq!(rc, Some(0), "{err}");
    let lines: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).expect("json line"))
        .collect();
    assert_eq!(lines.len(), 2);
    assert!(lines[0]["message"].is_object(), "{}", lines[0]);

    let generic = dir.path("generic.mcap");
    let st = Command::new(crate::pyenv::python())
        .args([
            "-c",
            r#"
import sys, json
from mcap.writer import Writer
with open(sys.argv[1], "wb") as f:
    w = Writer(f)
    w.start(profile="", library="python mcap test")
    s = w.register_schema(name="point", encoding="jsonschema", data=b'{"type":"object"}')
    c = w.register_channel(topic="/points", message_encoding="json", schema_id=s)
    b = w.register_channel(topic="/blobs", message_encoding="protobuf", schema_id=s)
    for i in range(3):
        w.add_message(c, log_time=1000 + i, publish_time=1000 + i, data=json.dumps({"x": i}).encode())
    w.add_message(b, log_time=2000, publish_time=2000, data=b"\x08\x01")
    w.add_metadata("note", {"k": "v"})
    w.finish()
"#,
            s(&generic),
        ])
        .status()
        .expect("python");
    assert!(st.success());
    let v = ok_json(&["replay", "info", s(&generic), "--json"]);
    assert_eq!(v["messages"], 4, "{v}");
    assert_eq!(v["episodes"], Value::Null, "{v}");
    let text = String::from_utf8_lossy(&etp(&["replay", "info", s(&generic)]).stdout).into_owned();
    assert!(!text.contains("episodes recorded"), "{text}");
    assert!(text.contains("protobuf") && text.contains("json"), "{text}");
    let (rc, out, err) = code(&["replay", "cat", s(&generic)]);
    assert_eq!(rc, Some(0), "{err}");
    let lines: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).expect("json line"))
        .collect();
    assert_eq!(lines.len(), 4);
    assert_eq!(lines[2]["message"]["x"], 2);
    assert_eq!(lines[3]["message_encoding"], "protobuf");
    assert_eq!(lines[3]["bytes"], 2);
}

/// `replay plot` and `run --plot` write different files.
#[test]
fn replay_plot_has_its_own_file_name() {
    let dir = Scratch::new("replay-plot");
    let rec = dir.path("r.mcap");
    std::fs::copy(fixture(), &rec).expect("copy");
    ok_json(&["replay", "plot", s(&rec), "--json"]);
    assert!(dir.path("r-replay.png").is_file() && dir.path("r-replay.svg").is_file());
    assert!(!dir.path("r-report.png").exists());
}

/// The `etp replay` commands of a README code block, as argument lists:
/// comments, `[optional]` parts and pipes dropped, the recording names of
/// the examples mapped to `file`, single quotes removed.
fn readme_replay_commands(text: &str, file: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut in_code = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_code = !in_code;
            continue;
        }
        let cmd = line.trim();
        let indented = line.starts_with("    ");
        if !(in_code || indented) || !cmd.starts_with("etp replay ") {
            continue;
        }
        let mut cmd = cmd.split(" #").next().unwrap_or(cmd).to_string();
        cmd = cmd.split(" |").next().unwrap_or(&cmd).to_string();
        while let (Some(a), Some(b)) = (cmd.find('['), cmd.find(']')) {
            if b < a {
                break;
            }
            cmd.replace_range(a..=b, "");
        }
        let args: Vec<String> = cmd
            .split_whitespace()
            .skip(1)
            .map(|w| {
                let w = w.trim_matches('\'');
                match w {
                    "FILE"
                    | "out/w/run.mcap"
                    | "out/lossy.mcap"
                    | "recordings/winding-2d-<run-id>.mcap"
                    | "crashed.mcap" => file.to_string(),
                    _ => w.replace("out/w/", "w-"),
                }
            })
            .collect();
        out.push(args);
    }
    out
}

/// Every `etp replay` command the READMEs show runs (on the fixture, in a
/// scratch folder) and exits 0.
#[test]
fn every_replay_command_of_the_readmes_runs() {
    let dir = Scratch::new("replay-readme");
    let rec = dir.path("run.mcap");
    std::fs::copy(fixture(), &rec).expect("copy");
    // `--run-id copy`: a run id of this test's own, cleaned up at the end.
    let copy = super::RunLeftovers::new("replaycmds");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut ran = 0;
    for readme in ["README.md", "recordings/README.md"] {
        let text = std::fs::read_to_string(root.join(readme)).expect("README");
        for mut args in readme_replay_commands(&text, s(&rec)) {
            for a in &mut args {
                if a == "copy" {
                    *a = copy.0.clone();
                }
            }
            let out = Command::new(env!("CARGO_BIN_EXE_etp"))
                .args(&args)
                .current_dir(&dir.0)
                .output()
                .expect("etp");
            assert!(
                out.status.success(),
                "{readme}: etp {args:?} failed: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            ran += 1;
        }
    }
    assert!(ran >= 20, "only {ran} commands found");
}

/// `replay info` gives per channel its messages, their rate over the file's
/// span and their payload bytes (as `mcap info`).
#[test]
fn info_gives_each_channels_rate_and_bytes() {
    let v = ok_json(&["replay", "info", s(&fixture()), "--json"]);
    let span = v["duration_s"].as_f64().expect("span");
    assert!(span > 0.0, "{v}");
    let channels = v["channels"].as_array().expect("channels");
    let mut bytes = 0;
    for c in channels {
        let n = c["messages"].as_u64().expect("messages");
        let rate = c["rate_hz"].as_f64().expect("rate");
        assert!(
            (rate - n as f64 / span).abs() <= 1e-9 * rate.max(1.0),
            "{c}"
        );
        let b = c["bytes"].as_u64().expect("bytes");
        assert_eq!(n == 0, b == 0, "{c}");
        bytes += b;
    }
    assert!(
        bytes > 0 && bytes < v["bytes"].as_u64().expect("file size") * 20,
        "{v}"
    );
    let out = etp(&["replay", "info", s(&fixture())]);
    let text = String::from_utf8_lossy(&out.stdout);
    let outcome = text
        .lines()
        .find(|l| l.trim_start().starts_with("outcome "))
        .expect("the outcome channel's line");
    assert!(
        outcome.contains("Hz") && outcome.contains(" B "),
        "{outcome}"
    );
}

/// `filter --exclude-topics` leaves those channels out (and names a
/// pattern that matches none); the copy is refused nothing else.
#[test]
fn filter_excludes_topics() {
    let dir = Scratch::new("replay-exclude");
    let out = dir.path("no-truth.mcap");
    ok_json(&[
        "replay",
        "filter",
        s(&fixture()),
        s(&out),
        "--exclude-topics",
        "sensor/*/truth,control",
        "--json",
    ]);
    let before = ok_json(&["replay", "info", s(&fixture()), "--json"]);
    let after = ok_json(&["replay", "info", s(&out), "--json"]);
    let topics = |v: &Value| -> Vec<String> {
        v["channels"]
            .as_array()
            .expect("channels")
            .iter()
            .map(|c| c["topic"].as_str().expect("topic").to_string())
            .collect()
    };
    let kept: Vec<String> = topics(&before)
        .into_iter()
        .filter(|t| t != "control" && !(t.starts_with("sensor/") && t.ends_with("/truth")))
        .collect();
    assert!(kept.len() < topics(&before).len(), "{before}");
    assert_eq!(topics(&after), kept);
    fails_with(
        &[
            "replay",
            "filter",
            s(&fixture()),
            s(&dir.path("x.mcap")),
            "--exclude-topics",
            "nosuch",
        ],
        &["--exclude-topics", "`nosuch` matches no channel"],
    );
}

/// A copy that is not an etp recording (the Foxglove copy) is refused by
/// the tools that need etp's channels, by name and with exit 1, never
/// summarised as a run of 0 episodes; `info` and `cat` still read it.
#[test]
fn a_file_that_is_not_an_etp_recording_is_refused_by_name() {
    let dir = Scratch::new("replay-foreign");
    let fox = dir.path("fox.mcap");
    ok_json(&["replay", "foxglove", s(&fixture()), s(&fox), "--json"]);
    let tables = dir.path("tables");
    for args in [
        vec!["replay", s(&fox)],
        vec!["replay", "summary", s(&fox), "--json"],
        vec!["replay", "verify", s(&fox)],
        vec!["replay", "plot", s(&fox)],
        vec!["replay", "export", s(&fox), s(&tables)],
    ] {
        let (rc, out, err) = code(&args);
        assert_eq!(rc, Some(1), "{args:?}: {err}");
        assert!(err.contains("is not an etp recording"), "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?}: {out}");
    }
    assert!(!tables.exists(), "export wrote tables of a foreign file");
    let (rc, _, err) = code(&["replay", "info", s(&fox)]);
    assert_eq!(rc, Some(0), "{err}");
}

/// `replay plot -o STEM` writes STEM.png and STEM.svg; an output into a
/// folder that does not exist is refused by name, never made.
#[test]
fn outputs_go_where_the_user_said_into_folders_that_exist() {
    let dir = Scratch::new("replay-out");
    let stem = dir.path("figure");
    ok_json(&["replay", "plot", s(&fixture()), "-o", s(&stem), "--json"]);
    assert!(dir.path("figure.png").is_file() && dir.path("figure.svg").is_file());
    let missing = dir.path("no/such");
    for args in [
        vec!["replay", "plot", s(&fixture()), "-o"],
        vec!["replay", "filter", s(&fixture())],
        vec!["replay", "repair", s(&fixture())],
        vec!["replay", "foxglove", s(&fixture())],
    ] {
        let target = missing.join("out.mcap");
        let mut args = args.clone();
        args.push(s(&target));
        let (rc, _, err) = code(&args);
        assert_eq!(rc, Some(1), "{args:?}: {err}");
        assert!(err.contains("does not exist"), "{args:?}: {err}");
        assert!(!dir.path("no").exists(), "{args:?} made the folder");
    }
}
