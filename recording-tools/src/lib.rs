//! The recording tools of etpareto: everything `etp replay` does to an MCAP
//! recording, as a library (`etp` parses the arguments and calls).
//!
//! * [`load`] — read a recording (finished or not) into
//!   [`etp_runtime::recording::Contents`]; [`check_output`] refuses an
//!   output that is the input or exists.
//! * [`summary`] — the run's summary from the recording alone (episodes,
//!   outcomes, per-sensor transmissions beside ledgers and received).
//! * [`info`] — what a file holds (like `mcap info`); [`cat`] — one JSON
//!   object per message (also shaped as `mcap cat --json`'s lines);
//!   [`export`] — the per-channel tables.
//! * [`select`] — the `--topics`/`--episodes`/`--start`/`--end` selection.
//! * [`repair`] — a finished copy; [`foxglove`] — a copy Foxglove draws;
//!   [`publish`] — the traffic back on iceoryx2 (like `ros2 bag play`).
//! * [`figure`] — measured against predicted, the data of the report figure
//!   (drawn by `etp`'s plotters code).
//! * [`vocab`] — THE JSON vocabulary shared by every command's `--json`.
//! * [`Error`] — what every tool fails with, one variant per kind of
//!   failure.

pub mod cat;
pub mod error;
pub mod export;
pub mod figure;
pub mod foxglove;
pub mod info;
pub mod publish;
pub mod repair;
pub mod select;
pub mod summary;
pub mod vocab;

pub use error::{Error, Result};

use error::IoContext;
use etp_runtime::recording::{self, Contents};
use std::path::Path;

/// Episodes by recorded outcome (summary and figure count the same way).
#[derive(Debug, Default, Clone, Copy)]
pub struct OutcomeCounts {
    pub target: u64,
    pub collision: u64,
    pub free: u64,
}

impl OutcomeCounts {
    pub fn add(&mut self, outcome: &etp_runtime::wire::agent_to_coordinator::Outcome) {
        use etp_runtime::wire::agent_to_coordinator::Outcome;
        match outcome.outcome {
            Outcome::TARGET => self.target += 1,
            Outcome::COLLISION => self.collision += 1,
            Outcome::FREE => self.free += 1,
            _ => {}
        }
    }
}

/// The MCAP writer of `etp replay`'s copies (zstd, 1 MiB chunks), with the
/// source's metadata records already written.
pub fn copy_writer(
    c: &Contents,
    path: &Path,
    profile: &str,
    what: &str,
) -> Result<mcap::Writer<std::io::BufWriter<std::fs::File>>> {
    let file = std::fs::File::create(path).doing(|| format!("creating {}", path.display()))?;
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(1024 * 1024))
        .profile(profile)
        .library(format!("etp replay {what} {}", env!("CARGO_PKG_VERSION")))
        .create(std::io::BufWriter::new(file))
        .map_err(|source| Error::Mcap {
            what: "starting the MCAP writer".into(),
            source,
        })?;
    for (name, metadata) in &c.metadata {
        w.write_metadata(&mcap::records::Metadata {
            name: name.clone(),
            metadata: metadata.clone(),
        })?;
    }
    Ok(w)
}

/// Read a recording (finished or not).
pub fn load(path: &Path) -> Result<Contents> {
    Ok(load_bytes(path)?.0)
}

/// Read a recording and the file's bytes.
pub fn load_bytes(path: &Path) -> Result<(Contents, Vec<u8>)> {
    let buf = std::fs::read(path).doing(|| format!("reading {}", path.display()))?;
    let c = recording::read_lenient(&path.display().to_string(), &buf)?;
    Ok((c, buf))
}

/// Refuse a file none of whose channels etp writes
/// ([`export::is_etp_channel`]: a Foxglove copy by
/// `etp replay foxglove`, another program's MCAP file): its summary would
/// be an empty run. A file without channels yet (an etp recording cut
/// before its first channel) passes: it is unfinished, not foreign.
pub fn refuse_foreign(file: &Path, c: &Contents) -> Result<()> {
    if c.channels.is_empty() || c.channels.keys().any(|t| export::is_etp_channel(c, t)) {
        return Ok(());
    }
    let seen: std::collections::BTreeSet<&str> = c.encodings.values().map(String::as_str).collect();
    Err(Error::Foreign {
        file: file.to_path_buf(),
        channels: c.channels.len(),
        encodings: seen.into_iter().collect::<Vec<_>>().join(", "),
    })
}

/// Refuse an output path that exists (unless `force`) or is the input.
pub fn check_output(input: &Path, out: &Path, force: bool) -> Result<()> {
    if out == input
        || std::fs::canonicalize(out)
            .ok()
            .is_some_and(|o| std::fs::canonicalize(input).ok() == Some(o))
    {
        return Err(Error::OutputIsInput(out.to_path_buf()));
    }
    etp_files::write::existing_folder_of(out, "output")?;
    Ok(etp_files::write::refuse_existing(out, force)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kinds and texts `etp replay` prints after `error: ` (`{:#}` of
    /// anyhow: the words, then each cause after `: `).
    #[test]
    fn a_missing_input_and_an_output_onto_it_are_told_apart_by_kind_and_text() {
        let dir = std::env::temp_dir().join(format!("etp-tools-errors-{}", std::process::id()));
        let missing = dir.join("absent.mcap");
        let e = load(&missing).expect_err("a missing file does not load");
        assert!(
            matches!(&e, Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound),
            "{e:?}"
        );
        assert_eq!(
            format!("{:#}", anyhow::Error::from(e)),
            format!(
                "reading {}: No such file or directory (os error 2)",
                missing.display()
            )
        );
        let e = check_output(&missing, &missing, false).expect_err("the input is no output");
        assert!(
            matches!(&e, Error::OutputIsInput(p) if *p == missing),
            "{e:?}"
        );
        assert_eq!(
            format!("{:#}", anyhow::Error::from(e)),
            format!(
                "{} is the recording being read: choose another output",
                missing.display()
            )
        );
    }
}
