//! What a file's top-level records say about it (for `etp replay … info`):
//! the header's profile and library, and the chunks' compression and sizes.
//! A plain walk of the framing (opcode u8, length u64 LE, body) that stops at
//! the first record running past the end: it reads what is there and never
//! fails.

use std::collections::BTreeMap;

/// Chunks of one compression.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct ChunkStats {
    pub chunks: u64,
    /// Bytes of the chunk records' payloads as stored, and once uncompressed.
    pub stored_bytes: u64,
    pub uncompressed_bytes: u64,
}

/// The file's header record and its chunks by compression (`""` = none).
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct Layout {
    pub profile: Option<String>,
    pub library: Option<String>,
    pub compression: BTreeMap<String, ChunkStats>,
}

const OP_HEADER: u8 = 0x01;
const OP_CHUNK: u8 = 0x06;

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

/// An MCAP string (u32 length, bytes) at `at`; the offset after it.
fn string_at(b: &[u8], at: usize) -> Option<(String, usize)> {
    let n = u32_at(b, at)? as usize;
    let s = b.get(at + 4..(at + 4).checked_add(n)?)?;
    Some((String::from_utf8_lossy(s).into_owned(), at + 4 + n))
}

/// Walk the top-level records of `buf`.
pub fn layout(buf: &[u8]) -> Layout {
    let mut out = Layout::default();
    let mut at = 8usize;
    while let (Some(&op), Some(len)) = (buf.get(at), u64_at(buf, at + 1)) {
        let start = at + 9;
        let Some(end) = usize::try_from(len)
            .ok()
            .and_then(|l| start.checked_add(l))
            .filter(|&e| e <= buf.len())
        else {
            break;
        };
        let body = &buf[start..end];
        match op {
            OP_HEADER => {
                if let Some((profile, next)) = string_at(body, 0) {
                    out.profile = Some(profile);
                    out.library = string_at(body, next).map(|(l, _)| l);
                }
            }
            OP_CHUNK => {
                // start u64, end u64, uncompressed size u64, crc u32, compression.
                if let (Some(size), Some((compression, next))) =
                    (u64_at(body, 16), string_at(body, 28))
                {
                    let s = out.compression.entry(compression).or_default();
                    s.chunks += 1;
                    s.uncompressed_bytes += size;
                    s.stored_bytes += u64_at(body, next).unwrap_or(0);
                }
            }
            _ => {}
        }
        at = end;
    }
    out
}
