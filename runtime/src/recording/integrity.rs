//! The metadata of a recording checked against itself: the scenario it holds
//! (`etp.scenario`) is the one its run record (`etp.run` / `scenario_hash`,
//! `scenario_name`) and its strategy (`etp.strategy`: scenario hash and Δ)
//! were made for.
//!
//! In a finished file the data-section CRC already covers the metadata
//! records; an unfinished file has no such CRC, and a file edited with its CRC
//! recomputed passes it: the scenario's content hash (SHA-256 of its parsed
//! content) is what ties a changed cost, noise or threshold to a refusal.

use super::{META_RUN, META_SCENARIO, META_STRATEGY, RecordingError, read::Contents};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Strategy;

/// Key of the scenario's content hash in the `etp.run` record.
pub const META_RUN_SCENARIO_HASH: &str = "scenario_hash";

/// Check that the recorded scenario, the run record and the strategy agree;
/// the recorded scenario (`None` when the file holds none, e.g. a recorder
/// started by hand without `--meta`).
pub fn check_metadata(c: &Contents) -> Result<Option<Scenario>, RecordingError> {
    let bad = |m: String| Err(RecordingError::Metadata(m));
    if let Some(v) = c.meta(META_RUN, "format_version") {
        use super::Encoding;
        let Some(expected) = [Encoding::Protobuf, Encoding::Protobuf5, Encoding::Bincode]
            .into_iter()
            .find(|e| e.format_versions().contains(&v))
        else {
            return bad(format!(
                "format version {v}: this etp reads formats {}, {}, {} and {} (format 2 and \
                 older sent the agent's prior every step; 3 a handover per leg and the sensor's \
                 replica digest in `slot`; since 4 the radio's attempts, deliveries and losses \
                 in `slot` and `ledger`; 5 the same messages in protobuf; 6 with enums and \
                 arrays of the used length; 7 with each message's sender's time as its \
                 publish_time)",
                super::LEGACY_FORMAT_VERSION,
                super::PROTOBUF5_FORMAT_VERSION,
                super::PROTOBUF6_FORMAT_VERSION,
                super::FORMAT_VERSION
            ));
        };
        // Every etp channel is in its format's encoding (a file whose
        // metadata and channels disagree was assembled by hand): its
        // `message_encoding`, and for protobuf its schema (format 5's
        // descriptors or not).
        for (topic, encoding) in &c.encodings {
            if super::kind_of_topic(topic).is_none() {
                continue;
            }
            if encoding != expected.name() {
                return bad(format!(
                    "format {v} has `{}` channels, but `{topic}` is `{encoding}`",
                    expected.name()
                ));
            }
            if let Some(found) = c.encoding(topic)
                && found != expected
            {
                return bad(format!(
                    "format {v}, but the schema of `{topic}` is format {}'s",
                    found.format_version()
                ));
            }
        }
    }
    let Some(text) = c.meta(META_SCENARIO, "toml") else {
        if c.meta(META_RUN, META_RUN_SCENARIO_HASH).is_some()
            || c.metadata.contains_key(META_STRATEGY)
        {
            return bad(format!(
                "the file names a scenario (`{META_RUN}` or `{META_STRATEGY}`) but holds no `{META_SCENARIO}` record"
            ));
        }
        return Ok(None);
    };
    let scenario = match Scenario::from_toml(text) {
        Ok(s) => s,
        Err(e) => {
            return bad(format!(
                "the recorded scenario (`{META_SCENARIO}`) is invalid: {e}"
            ));
        }
    };
    if let Some(h) = c.meta(META_RUN, META_RUN_SCENARIO_HASH)
        && h != scenario.content_hash
    {
        return bad(format!(
            "scenario hash mismatch: `{META_RUN}` records scenario hash {h:.12}… but the recorded \
             scenario (`{META_SCENARIO}`) has content hash {:.12}… (edited or damaged metadata)",
            scenario.content_hash
        ));
    }
    if let Some(name) = c.meta(META_RUN, "scenario_name")
        && name != scenario.name
    {
        return bad(format!(
            "`{META_RUN}` names scenario `{name}` but the recorded scenario is `{}`",
            scenario.name
        ));
    }
    match c.meta(META_STRATEGY, "json") {
        Some(json) => {
            let strategy = Strategy::from_json(json).map_err(|e| {
                RecordingError::Metadata(format!("the recorded strategy (`{META_STRATEGY}`): {e}"))
            })?;
            strategy.policy.check_scenario(&scenario).map_err(|e| {
                RecordingError::Metadata(format!(
                    "scenario hash mismatch: the recorded strategy (`{META_STRATEGY}`) does not \
                     fit the recorded scenario (`{META_SCENARIO}`): {e}"
                ))
            })?;
        }
        None if c.metadata.contains_key(META_STRATEGY) => {
            return bad(format!("the `{META_STRATEGY}` record has no `json`"));
        }
        None => {}
    }
    Ok(Some(scenario))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn contents(toml: &str, run_hash: Option<&str>, strategy: Option<String>) -> Contents {
        let mut c = Contents::default();
        c.metadata.insert(
            META_SCENARIO.into(),
            BTreeMap::from([("toml".to_string(), toml.to_string())]),
        );
        let mut run = BTreeMap::from([("scenario_name".to_string(), "open-2d".to_string())]);
        if let Some(h) = run_hash {
            run.insert(META_RUN_SCENARIO_HASH.into(), h.into());
        }
        c.metadata.insert(META_RUN.into(), run);
        if let Some(s) = strategy {
            c.metadata.insert(
                META_STRATEGY.into(),
                BTreeMap::from([("json".to_string(), s)]),
            );
        }
        c
    }

    #[test]
    fn an_edited_scenario_strategy_or_hash_is_refused() {
        let text = etp_shared::scenario::builtin_text("open-2d").expect("built-in");
        let s = Scenario::from_toml(text).expect("valid");
        let prediction = etp_shared::strategy::Prediction {
            p_target: 1.0,
            p_collision: 0.0,
            p_free: 0.0,
            energy_mean: 1.0,
        };
        let st = Strategy::constant(&s, 0, Some(prediction)).to_json();
        let ok = contents(text, Some(&s.content_hash), Some(st.clone()));
        assert_eq!(
            check_metadata(&ok)
                .expect("consistent")
                .map(|s| s.content_hash),
            Some(s.content_hash.clone())
        );
        // The same file without the run record's hash (format 1 files before
        // it was written) is still checked against the strategy.
        check_metadata(&contents(text, None, Some(st.clone()))).expect("consistent");

        // One value of the scenario changed: both hashes refuse it.
        let edited = text.replacen("cost = 1.0", "cost = 9.0", 1);
        assert_ne!(edited, text, "open-2d has a sensor of cost 1.0");
        for c in [
            contents(&edited, Some(&s.content_hash), None),
            contents(&edited, None, Some(st.clone())),
        ] {
            let e = check_metadata(&c).expect_err("edited scenario").to_string();
            assert!(e.contains("scenario hash mismatch"), "{e}");
        }
        // A strategy whose Δ was edited: its seal (`content_sha256`, the
        // hash of the whole file) refuses it before any field is compared.
        let bent = st.replacen("1.0518", "3.5", 1);
        assert_ne!(bent, st);
        let e = check_metadata(&contents(text, None, Some(bent)))
            .expect_err("edited deltas")
            .to_string();
        assert!(e.contains("content_sha256"), "{e}");
        // No scenario at all: nothing to check, unless something names one.
        assert!(
            check_metadata(&Contents::default())
                .expect("empty")
                .is_none()
        );
        let mut orphan = contents(text, Some(&s.content_hash), None);
        orphan.metadata.remove(META_SCENARIO);
        assert!(check_metadata(&orphan).is_err());
    }

    #[test]
    fn the_format_version_names_the_channels_encoding() {
        use crate::recording::{
            Encoding, FORMAT_VERSION, LEGACY_FORMAT_VERSION, LEGACY_MESSAGE_ENCODING,
            MESSAGE_ENCODING, PROTOBUF5_FORMAT_VERSION,
        };
        let file = |version: &str, encoding: &str| {
            let mut c = Contents::default();
            c.metadata.insert(
                META_RUN.into(),
                BTreeMap::from([("format_version".to_string(), version.to_string())]),
            );
            c.encodings.insert("measurement".into(), encoding.into());
            // Another writer's channel is not etp's to check.
            c.encodings.insert("/camera".into(), "cdr".into());
            c
        };
        assert!(check_metadata(&file(FORMAT_VERSION, MESSAGE_ENCODING)).is_ok());
        assert!(check_metadata(&file(LEGACY_FORMAT_VERSION, LEGACY_MESSAGE_ENCODING)).is_ok());
        for (v, e) in [
            (FORMAT_VERSION, LEGACY_MESSAGE_ENCODING),
            (LEGACY_FORMAT_VERSION, MESSAGE_ENCODING),
        ] {
            let err = check_metadata(&file(v, e)).expect_err("mixed").to_string();
            assert!(err.contains("`measurement`"), "{err}");
        }
        // Format 5 and 6 share `protobuf`: the schema read tells them apart.
        let mut five = file(PROTOBUF5_FORMAT_VERSION, MESSAGE_ENCODING);
        five.etp_encodings
            .insert("measurement".into(), Encoding::Protobuf5);
        assert!(check_metadata(&five).is_ok());
        let mut six_as_five = file(PROTOBUF5_FORMAT_VERSION, MESSAGE_ENCODING);
        six_as_five
            .etp_encodings
            .insert("measurement".into(), Encoding::Protobuf);
        let err = check_metadata(&six_as_five)
            .expect_err("a format-6 schema in a format-5 file")
            .to_string();
        assert!(err.contains("format 7's"), "{err}");
        // Format 6's channels are format 7's.
        let mut six = file(crate::recording::PROTOBUF6_FORMAT_VERSION, MESSAGE_ENCODING);
        six.etp_encodings
            .insert("measurement".into(), Encoding::Protobuf);
        assert!(check_metadata(&six).is_ok());
        let err = check_metadata(&file("8", MESSAGE_ENCODING))
            .expect_err("a newer format")
            .to_string();
        assert!(
            err.contains("format version 8") && err.contains("formats 4, 5, 6 and 7"),
            "{err}"
        );
    }
}
