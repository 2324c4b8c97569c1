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

/// Largest record (or decompressed chunk) accepted. Our records are at most a
/// few hundred bytes, metadata (scenario, strategy) some hundred KiB, chunks
/// 1 MiB; the bound keeps a corrupted length from asking for terabytes.
const RECORD_LIMIT: usize = 256 << 20;

/// The records of an MCAP file, chunks flattened, with every length bounded
/// by [`RECORD_LIMIT`] and chunk CRCs checked.
///
/// `mcap::read::ChunkFlattener` sets no record-length limit, so a corrupted
/// record length inside a chunk made it reserve an impossible buffer and
/// panic (found by the `mcap_read` fuzz target); this is the same loop over
/// the sans-io reader with the limit set.
struct Records<'a> {
    buf: &'a [u8],
    reader: mcap::sans_io::LinearReader,
}

impl<'a> Records<'a> {
    fn new(buf: &'a [u8]) -> Self {
        let options = mcap::sans_io::LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(RECORD_LIMIT.max(buf.len()));
        Self {
            buf,
            reader: mcap::sans_io::LinearReader::new_with_options(options),
        }
    }
}

impl Iterator for Records<'_> {
    type Item = Result<mcap::records::Record<'static>, mcap::McapError>;

    fn next(&mut self) -> Option<Self::Item> {
        use mcap::sans_io::LinearReadEvent;
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let len = need.min(self.buf.len());
                    self.reader.insert(len).copy_from_slice(&self.buf[..len]);
                    self.reader.notify_read(len);
                    self.buf = &self.buf[len..];
                }
                Ok(LinearReadEvent::Record { data, opcode }) => {
                    return Some(mcap::parse_record(opcode, data).map(|r| r.into_owned()));
                }
                Err(e) => return Some(Err(e)),
            }
        }
        None
    }
}

/// Read every complete record of a recording (finished or not): a linear
/// read over the flattened chunks that does not need the end magic; where
/// reading stops early is reported in [`Contents::truncated`] (and
/// [`Contents::damaged`]).
pub fn read_lenient(name: &str, buf: &[u8]) -> Result<Contents, RecordingError> {
    use mcap::records::Record;
    if buf.len() < 8 || &buf[..8] != mcap::MAGIC {
        return Err(RecordingError::NotMcap(
            name.into(),
            "no MCAP magic at the start".into(),
        ));
    }
    let reader = Records::new(buf);
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

#[cfg(test)]
mod tests {
    use super::*;

    fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
        let mut r = vec![opcode];
        r.extend_from_slice(&(body.len() as u64).to_le_bytes());
        r.extend_from_slice(body);
        r
    }

    fn string(s: &str) -> Vec<u8> {
        let mut b = (s.len() as u32).to_le_bytes().to_vec();
        b.extend_from_slice(s.as_bytes());
        b
    }

    /// A file whose only chunk (uncompressed, no CRC) holds a record that
    /// claims 2^62 bytes: the fuzzer's crash, reduced. It must be reported as
    /// damage, not panic or try to allocate.
    #[test]
    fn a_huge_record_length_inside_a_chunk_is_damage_not_a_panic() {
        let mut inner = vec![0x05u8];
        inner.extend_from_slice(&(1u64 << 62).to_le_bytes());
        inner.extend_from_slice(&[0; 16]);
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message start time
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message end time
        chunk.extend_from_slice(&(inner.len() as u64).to_le_bytes()); // uncompressed size
        chunk.extend_from_slice(&0u32.to_le_bytes()); // uncompressed CRC: none
        chunk.extend_from_slice(&string("")); // no compression
        chunk.extend_from_slice(&(inner.len() as u64).to_le_bytes());
        chunk.extend_from_slice(&inner);
        let mut file = mcap::MAGIC.to_vec();
        file.extend(record(0x01, &[string("etpareto"), string("test")].concat()));
        file.extend(record(0x06, &chunk));
        let c = read_lenient("crafted", &file).expect("an MCAP file");
        assert!(c.damaged, "{:?}", c.truncated);
        assert!(c.messages.is_empty());
    }

    #[test]
    fn a_file_cut_inside_a_record_is_unfinished_not_damaged() {
        let mut file = mcap::MAGIC.to_vec();
        file.extend(record(0x01, &[string("etpareto"), string("test")].concat()));
        let header_end = file.len();
        file.extend(record(
            0x0C,
            &[string("etp.run"), 0u32.to_le_bytes().to_vec()].concat(),
        ));
        let c = read_lenient("cut", &file[..file.len() - 2]).expect("an MCAP file");
        assert!(!c.damaged && !c.finished, "{:?}", c.truncated);
        assert!(c.truncated.is_some());
        let whole = read_lenient("whole", &file).expect("an MCAP file");
        assert_eq!(whole.metadata.len(), 1);
        assert!(whole.truncated.is_none() && !whole.finished);
        assert!(read_lenient("magic only", &file[..header_end - 3]).is_ok());
        assert!(matches!(
            read_lenient("short", &file[..5]),
            Err(RecordingError::NotMcap(..))
        ));
    }
}
