//! `repair FILE OUT`: a finished copy (summary, indexes, footer) of a
//! possibly unfinished recording, holding every complete record of it; and
//! `filter FILE OUT`: the same copy of a selection (`crate::select`), like
//! `mcap filter`. Both keep every metadata record.

use crate::error::{Error, Result};
use etp_runtime::recording::{self, Contents};
use std::collections::BTreeMap;

/// Write a finished copy of a (possibly unfinished) recording.
pub fn repair(c: &Contents, out: &std::path::Path) -> Result<u64> {
    etp_files::write::write_via_temp(out, |tmp| write_copy(c, tmp, "--repair"))
}

/// Write the (selected) messages of `c` to a new finished recording.
pub fn filter(c: &Contents, out: &std::path::Path) -> Result<u64> {
    etp_files::write::write_via_temp(out, |tmp| write_copy(c, tmp, "filter"))
}

fn write_copy(c: &Contents, tmp: &std::path::Path, what: &str) -> Result<u64> {
    let mut w = crate::copy_writer(c, tmp, recording::PROFILE, what)?;
    let mut ids: BTreeMap<&str, u16> = BTreeMap::new();
    for topic in c.channels.keys() {
        let Some(kind) = recording::kind_of_topic(topic) else {
            return Err(Error::UnknownChannel(topic.clone()));
        };
        // The copy keeps each channel's own encoding (a format-4 or
        // format-5 file stays so: its metadata says so), with this etp's
        // schema of it.
        let encoding = match (c.encoding(topic), c.encodings.get(topic)) {
            (Some(e), _) => e,
            (None, None) => recording::Encoding::Protobuf,
            (None, Some(e)) => {
                return Err(Error::Encoding {
                    topic: topic.clone(),
                    encoding: e.clone(),
                });
            }
        };
        let (name, schema_encoding, data) = encoding.schema(kind)?;
        let schema = w.add_schema(&name, schema_encoding, &data)?;
        let id = w.add_channel(schema, topic, encoding.name(), &BTreeMap::new())?;
        ids.insert(topic, id);
    }
    let mut seq: BTreeMap<u16, u32> = BTreeMap::new();
    for m in &c.messages {
        let Some(&id) = ids.get(m.topic.as_str()) else {
            return Err(Error::UnopenedChannel(m.topic.clone()));
        };
        let s = seq.entry(id).or_default();
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: id,
                sequence: *s,
                log_time: m.log_time,
                publish_time: m.publish_time,
            },
            &m.data,
        )?;
        *s = s.wrapping_add(1);
    }
    w.finish().map_err(|source| Error::Mcap {
        what: format!("finishing the {what} copy"),
        source,
    })?;
    drop(w);
    Ok(c.messages.len() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_copy_keeps_each_messages_times_and_numbers_its_sequence() {
        let mut c = Contents::default();
        c.channels.insert("outcome".into(), "etp.Outcome".into());
        for (i, (log, publish)) in [(30u64, 10u64), (50, 40)].into_iter().enumerate() {
            c.messages.push(recording::RawMessage {
                topic: "outcome".into(),
                sequence: 9,
                log_time: log,
                publish_time: publish,
                data: vec![u8::try_from(i).expect("small")],
                encoding: Some(recording::Encoding::Protobuf),
            });
        }
        let dir = std::env::temp_dir().join(format!("etp-copy-times-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch folder");
        let out = dir.join("copy.mcap");
        assert_eq!(write_copy(&c, &out, "filter").expect("copy"), 2);
        let back = recording::read_lenient("copy", &std::fs::read(&out).expect("read"))
            .expect("the copy reads");
        let times: Vec<(u32, u64, u64)> = back
            .messages
            .iter()
            .map(|m| (m.sequence, m.log_time, m.publish_time))
            .collect();
        assert_eq!(times, [(0, 30, 10), (1, 50, 40)]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
