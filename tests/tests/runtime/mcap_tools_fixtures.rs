//! The committed recordings of the older formats — format 4 (bincode,
//! `recordings/fixtures/open-2d-4-episodes.mcap`), format 5 (protobuf
//! with plain integers and whole arrays,
//! `recordings/fixtures/open-2d-2-episodes-format-5.mcap`) and format 6
//! (format 7's channels, `publish_time` the recorder's receive time,
//! `recordings/fixtures/open-2d-2-episodes-format-6.mcap`) — read by every
//! tool as a new recording is: summary, verify, info, cat, export, repair,
//! filter and the Foxglove copy; repair and filter keep the file's format.

use super::recording::{read_finished, replay};
use etp_runtime::recording::{self, Encoding};
use etp_tests::unique_run_id;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// `etp replay ARGS` (a command without `--json`) must succeed; its stdout.
fn etp_replay(args: &[&str]) -> String {
    let out = std::process::Command::new(etp_tests::bin_dir().join("etp"))
        .arg("replay")
        .args(args)
        .output()
        .expect("etp replay");
    assert!(
        out.status.success(),
        "etp replay {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../recordings/fixtures")
        .join(name)
}

/// The encoding every etp channel of a file of format `version` is read in.
fn encoding_of(version: &str) -> Encoding {
    [Encoding::Protobuf, Encoding::Protobuf5, Encoding::Bincode]
        .into_iter()
        .find(|e| e.format_versions().contains(&version))
        .unwrap_or_else(|| panic!("format {version}"))
}

/// A file that passes `verify` with `episodes` episodes checked.
fn verifies(file: &Path, episodes: u64) {
    let v = replay(&["verify", &file.display().to_string()]);
    assert_eq!(
        v["verify"]["passed"].as_bool(),
        Some(true),
        "{}: {}",
        file.display(),
        v["verify"]
    );
    assert_eq!(v["verify"]["episodes_checked"].as_u64(), Some(episodes));
}

/// Every tool of `etp replay` reads the recording `file` of format
/// `version` with `episodes` episodes; copies keep its format.
pub(super) fn every_tool_reads(file: &Path, version: &str, episodes: u64) {
    let c = read_finished(file);
    assert_eq!(c.meta(recording::META_RUN, "format_version"), Some(version));
    let expected = encoding_of(version);
    assert!(!c.etp_encodings.is_empty());
    for topic in c.channels.keys() {
        assert_eq!(c.encoding(topic), Some(expected), "{topic}");
    }
    let p = file.display().to_string();
    let summary = replay(&["summary", &p]);
    assert_eq!(summary["counts"]["outcome"].as_u64(), Some(episodes));
    verifies(file, episodes);
    let info = replay(&["info", &p]);
    assert!(info["channels"].as_array().is_some_and(|a| !a.is_empty()));

    // `cat --json`: the file's own protobuf message (format 5: codes as
    // numbers), or the format-6 one (names) for format 6 and bincode.
    let cat = etp_replay(&["cat", &p, "--json", "--topics", "outcome"]);
    let lines: Vec<Value> = cat
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len() as u64, episodes);
    for l in &lines {
        let outcome = &l["data"]["outcome"];
        match expected {
            Encoding::Protobuf5 => assert!(outcome.is_u64(), "{l}"),
            _ => assert!(
                ["TARGET", "COLLISION", "FREE"].contains(&outcome.as_str().unwrap_or_default()),
                "{l}"
            ),
        }
    }

    let dir = std::env::temp_dir().join(format!("etp-test-{}-tools", unique_run_id("fx")));
    std::fs::create_dir_all(&dir).expect("dir");
    let out = dir.join("export");
    etp_replay(&["export", &p, &out.display().to_string()]);
    let outcome = std::fs::read_to_string(out.join("outcome.csv")).expect("outcome.csv");
    assert_eq!(outcome.lines().count() as u64, episodes + 1, "{outcome}");

    // A repaired copy and a filtered one keep the format (its metadata says
    // so; each channel its encoding and schema) and verify.
    let copy = dir.join("copy.mcap");
    etp_replay(&["repair", &p, &copy.display().to_string()]);
    let cc = read_finished(&copy);
    assert_eq!(cc.encodings, c.encodings);
    assert_eq!(cc.etp_encodings, c.etp_encodings);
    assert_eq!(cc.messages.len(), c.messages.len());
    verifies(&copy, episodes);
    let cut = dir.join("cut.mcap");
    etp_replay(&[
        "filter",
        &p,
        &cut.display().to_string(),
        "--episodes",
        "0..1",
    ]);
    let fc = read_finished(&cut);
    assert_eq!(fc.etp_encodings, c.etp_encodings);
    verifies(&cut, 1);

    let fox = dir.join("foxglove.mcap");
    etp_replay(&["foxglove", &p, &fox.display().to_string()]);
    let fc = read_finished(&fox);
    assert!(fc.channels.contains_key("/outcomes"), "{:?}", fc.channels);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_format_4_fixture_is_read_by_every_tool() {
    let path = fixture("open-2d-4-episodes.mcap");
    let c = read_finished(&path);
    for (topic, e) in &c.encodings {
        assert_eq!(e, recording::LEGACY_MESSAGE_ENCODING, "{topic}");
    }
    every_tool_reads(&path, recording::LEGACY_FORMAT_VERSION, 4);
}

#[test]
fn the_format_6_fixture_is_read_by_every_tool_its_publish_times_the_log_times() {
    let path = fixture("open-2d-2-episodes-format-6.mcap");
    let c = read_finished(&path);
    // Format 6 carried no sender's time: the recorder wrote its own twice.
    assert!(!c.messages.is_empty());
    for m in &c.messages {
        assert_eq!(m.publish_time, m.log_time, "{} {}", m.topic, m.sequence);
    }
    every_tool_reads(&path, recording::PROTOBUF6_FORMAT_VERSION, 2);
}

#[test]
fn the_format_5_fixture_is_read_by_every_tool_in_its_own_schemas() {
    let path = fixture("open-2d-2-episodes-format-5.mcap");
    // Its schemas are format 5's descriptors byte for byte (what tells a
    // format-5 channel from a format-6 one), not format 6's.
    let bytes = std::fs::read(&path).expect("fixture");
    let summary = mcap::read::Summary::read(&bytes)
        .expect("summary reads")
        .expect("a summary");
    for c in summary.channels.values() {
        let kind = recording::kind_of_topic(&c.topic).expect("etp topic");
        let schema = c.schema.as_ref().expect("a schema");
        let plain = kind
            .proto_schema_in(recording::ProtoMapping::Plain)
            .expect("format 5 descriptor");
        assert_eq!(schema.data.as_ref(), plain, "{}", c.topic);
        assert_ne!(schema.data.as_ref(), kind.proto_schema().expect("format 6"));
    }
    every_tool_reads(&path, recording::PROTOBUF5_FORMAT_VERSION, 2);
}
