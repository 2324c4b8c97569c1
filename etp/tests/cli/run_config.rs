//! `etp run --config RUN.toml`: the launch file of a run, its refusals, and
//! its copy in the recording's metadata (`etp.config`).

use super::{Scratch, fails_with, ok_json, s};

#[test]
fn a_run_file_runs_flags_win_and_the_recording_keeps_it() {
    let dir = Scratch::new("run-config");
    let file = dir.path("run.toml");
    let run_id = format!("t{}-config", std::process::id());
    std::fs::write(
        &file,
        format!(
            "scenario = \"open-2d\"\ndelta = 1.0518\nepisodes = 3\nseed = 9\npredict_episodes = 50\nrun_id = \"{run_id}\"\nrecord = \"run.mcap\"\n"
        ),
    )
    .expect("run file");
    // --episodes on the command line wins over the file's 3.
    let v = ok_json(&["run", "--config", s(&file), "--episodes", "1", "--json"]);
    assert_eq!(v["episodes"].as_u64(), Some(1));
    assert_eq!(v["seed"].as_u64(), Some(9), "from the file");
    assert_eq!(v["scenario"].as_str(), Some("open-2d"));
    let rec = dir.path("run.mcap");
    assert!(
        rec.is_file(),
        "record = \"run.mcap\" is relative to the run file"
    );
    let tables = dir.path("t");
    ok_json(&[
        "replay",
        "export",
        s(&rec),
        s(&tables),
        "--topics",
        "outcome",
        "--json",
    ]);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tables.join("tables.json")).expect("tables"))
            .expect("json");
    let config = manifest["metadata"]["etp.config"]["toml"]
        .as_str()
        .expect("etp.config");
    let parsed: toml::Table = toml::from_str(config).expect("etp.config is TOML");
    assert_eq!(parsed["episodes"].as_integer(), Some(1), "{config}");
    assert_eq!(parsed["seed"].as_integer(), Some(9), "{config}");
    assert_eq!(parsed["scenario"].as_str(), Some("open-2d"), "{config}");
    // Stored to run again from anywhere as a new run: no run id (this
    // run's id is in `etp.run`), the recording's path absolute.
    assert!(parsed.get("run_id").is_none(), "{config}");
    assert_eq!(
        manifest["metadata"]["etp.run"]["run_id"].as_str(),
        Some(run_id.as_str()),
        "{manifest}"
    );
    let stored = std::path::PathBuf::from(parsed["record"].as_str().expect("record"));
    assert!(stored.is_absolute(), "{config}");
    assert_eq!(
        stored.canonicalize().expect("stored path"),
        rec.canonicalize().expect("recording")
    );
    // Refusals name the file and the key; nothing runs.
    std::fs::write(&file, "scenario = \"open-2d\"\nepisodez = 3\n").expect("run file");
    fails_with(&["run", "--config", s(&file)], &["run.toml", "episodez"]);
    std::fs::write(&file, "delta = 1.0518\n").expect("run file");
    fails_with(
        &["run", "--config", s(&file)],
        &["`delta` needs `scenario`"],
    );
    fails_with(
        &["run", "--config", s(&dir.path("none.toml"))],
        &["none.toml"],
    );
}
