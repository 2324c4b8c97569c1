//! Reading a recording back: every complete record, in file order, from a
//! finished file or from the unfinished file of a crashed recorder.

use super::RecordingError;
use std::collections::BTreeMap;

/// One message read back from a file.
#[derive(Debug, Clone)]
pub struct RawMessage {
    pub topic: String,
    /// The message's per-channel `sequence`.
    pub sequence: u32,
    pub log_time: u64,
    /// Its `publish_time` (ns since the Unix epoch).
    pub publish_time: u64,
    pub data: Vec<u8>,
    /// Its channel's encoding, `None` for one etp does not write.
    pub encoding: Option<super::Encoding>,
}

impl RawMessage {
    /// Decode the payload by its channel's encoding (format 6 or 5
    /// protobuf, or format 4 bincode).
    pub fn decode(&self) -> Result<super::Recorded, RecordingError> {
        match self.encoding {
            Some(e) => e.decode(&self.topic, &self.data),
            None => Err(RecordingError::Decode {
                topic: self.topic.clone(),
                reason: "its channel's message encoding is not one etp writes".into(),
            }),
        }
    }
}

/// Everything a (possibly unfinished) recording holds, in file order.
#[derive(Debug, Clone, Default)]
pub struct Contents {
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Channel topic → schema name.
    pub channels: BTreeMap<String, String>,
    /// Schema name → schema encoding.
    pub schemas: BTreeMap<String, String>,
    /// Channel topic → message encoding (`bincode2-serde-legacy` in etp's
    /// own recordings; `json`, `protobuf`, … in other MCAP files).
    pub encodings: BTreeMap<String, String>,
    /// Channel topic → its encoding as etp reads it (format 6 or 5
    /// protobuf, told apart by the schema; bincode), for the channels etp
    /// writes.
    pub etp_encodings: BTreeMap<String, super::Encoding>,
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

    /// The encoding etp reads a channel in: as read from the file, else
    /// from its `message_encoding` alone (a `Contents` assembled by hand).
    pub fn encoding(&self, topic: &str) -> Option<super::Encoding> {
        self.etp_encodings.get(topic).copied().or_else(|| {
            self.encodings
                .get(topic)
                .and_then(|e| super::Encoding::of(e))
        })
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

/// Largest single read into the record reader's buffer.
const READ_STEP: usize = 1 << 20;

/// The records of an MCAP file, chunks flattened, with every length bounded
/// by [`RECORD_LIMIT`] and chunk CRCs checked.
///
/// `mcap::read::ChunkFlattener` sets no record-length limit, so a corrupted
/// record length inside a chunk made it reserve an impossible buffer and
/// panic (found by the `mcap_read` fuzz target); this is the same loop over
/// the sans-io reader with the limit set.
struct Records<R> {
    src: R,
    reader: mcap::sans_io::LinearReader,
}

impl<R: std::io::Read> Records<R> {
    /// Records of `src` (a byte slice, or a file read as it goes), no record
    /// longer than `max(RECORD_LIMIT, size)`.
    fn new(src: R, size: usize) -> Self {
        let options = mcap::sans_io::LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_validate_data_section_crc(true)
            .with_validate_summary_section_crc(true)
            .with_record_length_limit(RECORD_LIMIT.max(size));
        Self {
            src,
            reader: mcap::sans_io::LinearReader::new_with_options(options),
        }
    }
}

impl<R: std::io::Read> Iterator for Records<R> {
    type Item = Result<mcap::records::Record<'static>, mcap::McapError>;

    fn next(&mut self) -> Option<Self::Item> {
        use mcap::sans_io::LinearReadEvent;
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    // The reader may ask for far more than the next record
                    // (up to its length limit); a short read is allowed, and
                    // asking for 1 MiB at most keeps its buffer that small.
                    match self.src.read(self.reader.insert(need.min(READ_STEP))) {
                        Ok(n) => self.reader.notify_read(n),
                        Err(e) => return Some(Err(e.into())),
                    }
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

/// MCAP opcodes the framing scan needs.
const OP_FOOTER: u8 = 0x02;
const OP_CHUNK: u8 = 0x06;

/// Where the top-level records of a file end, from their framing alone
/// (opcode u8, length u64 LE, body).
#[derive(Debug, Clone, PartialEq, Eq)]
enum Framing {
    /// Every record is complete, the footer is followed by the end magic.
    Finished,
    /// The records up to byte `intact` are complete; the file ends there
    /// (`cut: None`) or inside the record that starts there (`cut: Some`).
    Open { intact: usize, cut: Option<String> },
    /// The footer is followed by something other than the end magic.
    AfterFooter(String),
}

/// Walk the top-level records. A writer that dies leaves a prefix of a valid
/// file: complete records, then at most one record that ends past the end of
/// the file — a record header or body cut short by the write, or the chunk
/// the mcap writer had open, whose length is still its placeholder
/// `u64::MAX` (it seeks back to fill it in only when the chunk is finished).
fn framing(buf: &[u8]) -> Framing {
    let mut at = mcap::MAGIC.len();
    while at < buf.len() {
        let rest = buf.len() - at;
        if rest < 9 {
            return Framing::Open {
                intact: at,
                cut: Some(format!(
                    "the file ends inside a record header at byte {at} ({rest} of 9 bytes)"
                )),
            };
        }
        let opcode = buf[at];
        let mut len_bytes = [0u8; 8];
        len_bytes.copy_from_slice(&buf[at + 1..at + 9]);
        let len = u64::from_le_bytes(len_bytes);
        if opcode == OP_CHUNK && len == u64::MAX {
            return Framing::Open {
                intact: at,
                cut: Some(format!(
                    "the last chunk (byte {at}) was never finished: its length is the \
                     writer's placeholder 0x{len:X}"
                )),
            };
        }
        let end = u64::try_from(at + 9)
            .ok()
            .and_then(|start| start.checked_add(len))
            .filter(|&end| end <= buf.len() as u64);
        let Some(end) = end else {
            return Framing::Open {
                intact: at,
                cut: Some(format!(
                    "the record at byte {at} (opcode 0x{opcode:02x}) claims {len} bytes, \
                     the file holds {}",
                    rest - 9
                )),
            };
        };
        at = end as usize;
        if opcode == OP_FOOTER {
            let tail = &buf[at..];
            return if tail == mcap::MAGIC {
                Framing::Finished
            } else if mcap::MAGIC.starts_with(tail) {
                Framing::Open {
                    intact: at,
                    cut: Some(format!(
                        "the file ends inside the end magic ({} of 8 bytes)",
                        tail.len()
                    )),
                }
            } else {
                Framing::AfterFooter(format!(
                    "{} bytes after the footer are not the end magic",
                    tail.len()
                ))
            };
        }
    }
    Framing::Open {
        intact: at,
        cut: None,
    }
}

/// Read every complete record of a recording (finished or not).
///
/// A file is *unfinished* when it is a prefix of a valid file, cut anywhere
/// (inside a record, inside a chunk, in the writer's open chunk, in the
/// summary): every complete record before the cut is read (a cut chunk is
/// skipped whole: its CRC cannot be checked), and the cut is reported in
/// [`Contents::truncated`]. A file is *damaged* ([`Contents::damaged`]) when
/// a complete record fails a check: a bad chunk, data-section or
/// summary-section CRC, an undecodable record, a message on an undeclared
/// channel, a finished file (end magic) whose records do not add up, or a
/// footer without a data-end record.
pub fn read_lenient(name: &str, buf: &[u8]) -> Result<Contents, RecordingError> {
    if buf.len() < 8 || &buf[..8] != mcap::MAGIC {
        return Err(RecordingError::NotMcap(
            name.into(),
            "no MCAP magic at the start".into(),
        ));
    }
    let mut out = Contents::default();
    let ends_with_magic = buf.len() >= 16 && buf[buf.len() - 8..] == *mcap::MAGIC;
    let readable = match framing(buf) {
        Framing::Finished => buf,
        Framing::Open { intact, cut } => {
            if let Some(cut) = cut {
                // A finished file (end magic) whose records overrun it has a
                // corrupted length, not a cut.
                out.damaged = ends_with_magic;
                out.truncated = Some(cut);
            }
            &buf[..intact]
        }
        Framing::AfterFooter(why) => {
            out.damaged = true;
            out.truncated = Some(why);
            buf
        }
    };
    let mut messages = Vec::new();
    let footer = collect(
        Records::new(readable, buf.len()),
        &mut out,
        |m| -> Result<(), RecordingError> {
            messages.push(m);
            Ok(())
        },
    )?;
    out.messages = messages;
    out.finished = footer && !out.damaged && ends_with_magic;
    Ok(out)
}

/// Does the file at `path` start and end with the MCAP magic (a finished
/// file, unless damaged)?
pub fn ends_finished(path: &std::path::Path) -> std::io::Result<bool> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path)?;
    let len = f.metadata()?.len();
    if len < 16 {
        return Ok(false);
    }
    let (mut head, mut tail) = ([0u8; 8], [0u8; 8]);
    f.read_exact(&mut head)?;
    f.seek(SeekFrom::End(-8))?;
    f.read_exact(&mut tail)?;
    Ok(head == *mcap::MAGIC && tail == *mcap::MAGIC)
}

/// Read a finished recording from disk one chunk at a time, handing every
/// message to `on_message` in file order instead of keeping it: memory does
/// not grow with the recording's length. The returned [`Contents`] holds
/// everything but the messages. A record that fails a check stops the
/// stream and marks the file damaged (as [`read_lenient`] does).
pub fn stream_finished<E: From<RecordingError>>(
    path: &std::path::Path,
    on_message: impl FnMut(RawMessage) -> Result<(), E>,
) -> Result<Contents, E> {
    let name = path.display().to_string();
    let io = |e: std::io::Error| RecordingError::NotMcap(name.clone(), e.to_string());
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    let mut src = std::io::BufReader::new(file);
    let mut magic = [0u8; 8];
    std::io::Read::read_exact(&mut src, &mut magic).map_err(io)?;
    if magic != *mcap::MAGIC {
        return Err(RecordingError::NotMcap(name, "no MCAP magic at the start".into()).into());
    }
    let mut out = Contents::default();
    let records = Records::new(
        std::io::Read::chain(mcap::MAGIC, src),
        usize::try_from(size).unwrap_or(usize::MAX),
    );
    let footer = collect(records, &mut out, on_message)?;
    out.finished = footer && !out.damaged;
    Ok(out)
}

/// Fold the records into `out`, messages to `on_message`; true when the
/// footer was read.
fn collect<E: From<RecordingError>>(
    reader: impl Iterator<Item = Result<mcap::records::Record<'static>, mcap::McapError>>,
    out: &mut Contents,
    mut on_message: impl FnMut(RawMessage) -> Result<(), E>,
) -> Result<bool, E> {
    use mcap::records::Record;
    let mut schemas: BTreeMap<u16, (String, Vec<u8>)> = BTreeMap::new();
    let mut topics: BTreeMap<u16, (String, Option<super::Encoding>)> = BTreeMap::new();
    let mut data_end = false;
    let mut footer = false;
    for rec in reader {
        let rec = match rec {
            Ok(r) => r,
            Err(e) => {
                // Every record fed to the reader is complete: any error is damage.
                out.damaged = true;
                out.truncated = Some(e.to_string());
                break;
            }
        };
        match rec {
            Record::Schema { header, data } => {
                out.schemas
                    .insert(header.name.clone(), header.encoding.clone());
                schemas.insert(header.id, (header.name, data.into_owned()));
            }
            Record::Channel(c) => {
                let (schema, schema_data) = schemas
                    .get(&c.schema_id)
                    .map(|(n, d)| (n.clone(), d.as_slice()))
                    .unwrap_or_default();
                out.channels.insert(c.topic.clone(), schema);
                out.encodings
                    .insert(c.topic.clone(), c.message_encoding.clone());
                let encoding =
                    super::Encoding::of_channel(&c.message_encoding, &c.topic, schema_data);
                if let Some(e) = encoding {
                    out.etp_encodings.insert(c.topic.clone(), e);
                }
                topics.insert(c.id, (c.topic, encoding));
            }
            Record::Message { header, data } => {
                let Some((topic, encoding)) = topics.get(&header.channel_id) else {
                    out.truncated = Some(format!(
                        "message on unknown channel id {}",
                        header.channel_id
                    ));
                    out.damaged = true;
                    break;
                };
                on_message(RawMessage {
                    topic: topic.clone(),
                    sequence: header.sequence,
                    log_time: header.log_time,
                    publish_time: header.publish_time,
                    data: data.into_owned(),
                    encoding: *encoding,
                })?;
            }
            Record::Metadata(m) => {
                out.metadata.insert(m.name, m.metadata);
            }
            Record::DataEnd(_) => data_end = true,
            Record::Footer(_) => footer = true,
            _ => {}
        }
    }
    if footer && !data_end && !out.damaged {
        out.damaged = true;
        out.truncated = Some("the file has a footer but no data-end record".into());
    }
    Ok(footer)
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

    /// The committed fixture: a finished recording of a real 4-episode run.
    const FIXTURE: &[u8] = include_bytes!("../../../recordings/fixtures/open-2d-4-episodes.mcap");

    #[test]
    fn every_prefix_of_a_recording_is_unfinished_never_damaged() {
        let whole = read_lenient("whole", FIXTURE).expect("an MCAP file");
        assert!(whole.finished && !whole.damaged && whole.truncated.is_none());
        let mut last = 0;
        let mut cut_reasons = std::collections::BTreeSet::new();
        for at in (8..FIXTURE.len()).step_by(59) {
            let c = read_lenient("prefix", &FIXTURE[..at]).expect("an MCAP file");
            assert!(!c.damaged, "cut at {at}: {:?}", c.truncated);
            assert!(!c.finished, "cut at {at}");
            assert!(c.messages.len() >= last, "cut at {at}");
            last = c.messages.len();
            if let Some(t) = &c.truncated {
                cut_reasons.insert(t.split(' ').take(5).collect::<Vec<_>>().join(" "));
            }
        }
        assert_eq!(last, whole.messages.len(), "the summary holds no message");
        assert!(cut_reasons.len() >= 2, "{cut_reasons:?}");
    }

    /// Bit flips anywhere in a finished file (every 89th byte, rotating
    /// bits): each is damage (or not an MCAP file at all), never a clean
    /// read — the data-section CRC covers the metadata and chunk headers,
    /// the summary CRC the summary, the framing check the footer and magic.
    #[test]
    fn every_bit_flip_of_a_finished_recording_is_damage() {
        for (i, at) in (0..FIXTURE.len()).step_by(89).enumerate() {
            let mut bad = FIXTURE.to_vec();
            bad[at] ^= 1 << (i % 8);
            match read_lenient("flipped", &bad) {
                Err(RecordingError::NotMcap(..)) => assert!(at < 8, "byte {at}"),
                Err(e) => panic!("byte {at}: {e}"),
                Ok(c) => assert!(
                    c.damaged && !c.finished,
                    "bit {} of byte {at} flipped: read as {} ({:?})",
                    i % 8,
                    if c.finished { "finished" } else { "unfinished" },
                    c.truncated
                ),
            }
        }
        // The last byte of the end magic too.
        let mut bad = FIXTURE.to_vec();
        let last = bad.len() - 1;
        bad[last] ^= 1;
        assert!(read_lenient("magic", &bad).expect("an MCAP file").damaged);
    }

    #[test]
    fn the_open_chunk_of_a_killed_writer_is_a_cut() {
        // Complete records, then what the mcap writer leaves of the chunk it
        // had open: its placeholder header (length, sizes, CRC all ones).
        let mut file = mcap::MAGIC.to_vec();
        file.extend(record(0x01, &[string("etpareto"), string("test")].concat()));
        let complete = read_lenient("header", &file).expect("an MCAP file");
        file.push(OP_CHUNK);
        file.extend_from_slice(&u64::MAX.to_le_bytes());
        file.extend_from_slice(&[0; 16]);
        file.extend_from_slice(&u64::MAX.to_le_bytes());
        file.extend_from_slice(&u32::MAX.to_le_bytes());
        file.extend_from_slice(&string("zstd"));
        file.extend_from_slice(&u64::MAX.to_le_bytes());
        file.extend_from_slice(&[0x28, 0xb5, 0x2f, 0xfd, 0, 0, 0]);
        let c = read_lenient("killed", &file).expect("an MCAP file");
        assert!(!c.damaged && !c.finished, "{:?}", c.truncated);
        assert!(
            c.truncated
                .as_deref()
                .is_some_and(|t| t.contains("placeholder")),
            "{:?}",
            c.truncated
        );
        assert_eq!(c.messages.len(), complete.messages.len());
        // The same bytes followed by an end magic claim to be finished: damage.
        file.extend_from_slice(mcap::MAGIC);
        assert!(
            read_lenient("claims finished", &file)
                .expect("mcap")
                .damaged
        );
    }
}
