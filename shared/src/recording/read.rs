//! Reading a recording back: every complete record, in file order, from a
//! finished file or from the unfinished file of a crashed recorder.

use super::RecordingError;
use std::collections::BTreeMap;

/// One message read back from a file.
#[derive(Debug, Clone)]
pub struct RawMessage {
    pub topic: String,
    pub log_time: u64,
    pub data: Vec<u8>,
}

/// Everything a (possibly unfinished) recording holds, in file order.
#[derive(Debug, Clone, Default)]
pub struct Contents {
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Channel topic → schema name.
    pub channels: BTreeMap<String, String>,
    pub messages: Vec<RawMessage>,
    /// True when the file ends with a footer and the end magic.
    pub finished: bool,
    /// Why reading stopped early (the tail of an unfinished file, or damage).
    pub truncated: Option<String>,
    /// Reading stopped at a damaged record (bad CRC, undecodable record, a
    /// message on an undeclared channel) rather than at the end of the data:
    /// the file is corrupt, not merely unfinished.
    pub damaged: bool,
}

impl Contents {
    /// Messages per channel topic.
    pub fn counts(&self) -> BTreeMap<String, u64> {
        let mut c: BTreeMap<String, u64> = self.channels.keys().map(|t| (t.clone(), 0)).collect();
        for m in &self.messages {
            *c.entry(m.topic.clone()).or_default() += 1;
        }
        c
    }

    /// A metadata value.
    pub fn meta(&self, record: &str, key: &str) -> Option<&str> {
        self.metadata.get(record)?.get(key).map(String::as_str)
    }
}

/// Read every complete record of a recording (finished or not): the linear
/// reader with `IgnoreEndMagic` over the flattened chunks; a damaged tail
/// stops the reading and is reported in [`Contents::truncated`].
pub fn read_lenient(name: &str, buf: &[u8]) -> Result<Contents, RecordingError> {
    use mcap::read::{ChunkFlattener, Options};
    use mcap::records::Record;
    if buf.len() < 8 || &buf[..8] != mcap::MAGIC {
        return Err(RecordingError::NotMcap(
            name.into(),
            "no MCAP magic at the start".into(),
        ));
    }
    let reader =
        ChunkFlattener::new_with_options(buf, Options::IgnoreEndMagic | Options::ValidateChunkCrcs)
            .map_err(|e| RecordingError::NotMcap(name.into(), e.to_string()))?;
    let mut out = Contents::default();
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut topics: BTreeMap<u16, String> = BTreeMap::new();
    for rec in reader {
        let rec = match rec {
            Ok(r) => r,
            Err(e) => {
                // A crashed writer leaves a record cut by the end of the file;
                // anything else — or a cut record in a file that does end
                // with the end magic (a corrupted length) — is damage.
                let ends_with_magic = buf.len() >= 16 && buf[buf.len() - 8..] == *mcap::MAGIC;
                out.damaged = !matches!(e, mcap::McapError::UnexpectedEof) || ends_with_magic;
                out.truncated = Some(e.to_string());
                break;
            }
        };
        match rec {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                let schema = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                out.channels.insert(c.topic.clone(), schema);
                topics.insert(c.id, c.topic);
            }
            Record::Message { header, data } => {
                let Some(topic) = topics.get(&header.channel_id) else {
                    out.truncated = Some(format!(
                        "message on unknown channel id {}",
                        header.channel_id
                    ));
                    out.damaged = true;
                    break;
                };
                out.messages.push(RawMessage {
                    topic: topic.clone(),
                    log_time: header.log_time,
                    data: data.into_owned(),
                });
            }
            Record::Metadata(m) => {
                out.metadata.insert(m.name, m.metadata);
            }
            Record::Footer(_) => out.finished = true,
            _ => {}
        }
    }
    out.finished &= buf.len() >= 8 && &buf[buf.len() - 8..] == mcap::MAGIC;
    Ok(out)
}
