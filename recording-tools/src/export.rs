//! `--export DIR [--format csv|jsonl]` (and the rows of `crate::cat`): the
//! recording's messages decoded into typed rows (`etp_runtime::recording::table`), readable with
//! no etp code (pandas `read_csv` / `read_json(lines=True)`, polars, the
//! Python csv and json modules).
//!
//! `--export` writes one file per channel, `DIR/<topic with / as ->.<ext>`
//! (`outcome.csv`, `sensor-0-truth.csv`), rows in the channel's order, and
//! `DIR/tables.json`: the source, the recording's metadata records and, per
//! table, its topic, file, schema, row count and typed columns.

use crate::error::{Context, Error, IoContext, Result, Words};
use etp_runtime::recording::table::{Cell, Column, Names, Table, csv_quote};
use etp_runtime::recording::{self, Contents, Kind};
use etp_shared::scenario::Scenario;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Table file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// Comma-separated values with a header row (RFC 4180; empty cell = null).
    #[default]
    Csv,
    /// JSON Lines: one object per row, keys in column order.
    Jsonl,
}

impl std::str::FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "csv" => Ok(Format::Csv),
            "jsonl" => Ok(Format::Jsonl),
            other => Err(format!("unknown table format `{other}`: csv or jsonl")),
        }
    }
}

impl Format {
    /// Every format's name, as its `FromStr` reads it.
    pub const NAMES: [&'static str; 2] = ["csv", "jsonl"];

    fn ext(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Jsonl => "jsonl",
        }
    }
}

/// The sensors' names (from the recorded scenario; `sensor-<i>` without
/// one) and the scenario's state dimension (arrays are cut to it).
pub fn names(c: &Contents) -> (Names, Option<usize>) {
    let scenario = c
        .meta(recording::META_SCENARIO, "toml")
        .and_then(|t| Scenario::from_toml(t).ok());
    let sensors = scenario
        .as_ref()
        .map(|s| s.sensors.iter().map(|x| x.name.clone()).collect())
        .unwrap_or_default();
    (Names { sensors }, scenario.map(|s| s.dim))
}

/// The file of a channel's table.
pub fn table_file(topic: &str, format: Format) -> String {
    format!("{}.{}", topic.replace('/', "-"), format.ext())
}

/// Is `topic` one of etp's channels in one of etp's encodings (protobuf
/// since format 5, bincode before; decoded into typed rows), rather than a
/// channel of another MCAP writer?
pub fn is_etp_channel(c: &Contents, topic: &str) -> bool {
    recording::kind_of_topic(topic).is_some()
        && c.encodings
            .get(topic)
            .is_none_or(|e| recording::Encoding::of(e).is_some())
}

pub(crate) fn tables(c: &Contents, dim: Option<usize>) -> Result<BTreeMap<String, Table>> {
    let mut out = BTreeMap::new();
    for topic in c.channels.keys().filter(|t| is_etp_channel(c, t)) {
        let kind: Kind =
            recording::kind_of_topic(topic).ok_or_else(|| Error::UnknownChannel(topic.clone()))?;
        let t = Table::of(kind, dim).map_err(|why| Error::Table {
            topic: topic.clone(),
            source: Words(why),
        })?;
        out.insert(topic.clone(), t);
    }
    Ok(out)
}

/// What `--export` wrote.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Exported {
    pub dir: String,
    pub format: &'static str,
    pub tables: u64,
    pub rows: u64,
    pub bytes: u64,
}

fn header_line(cols: &[Column], format: Format) -> Option<String> {
    match format {
        Format::Csv => Some(
            cols.iter()
                .map(|c| csv_quote(&c.name))
                .collect::<Vec<_>>()
                .join(","),
        ),
        Format::Jsonl => None,
    }
}

fn row_line(t: &Table, row: &[Cell], format: Format) -> String {
    match format {
        Format::Csv => row.iter().map(Cell::to_csv).collect::<Vec<_>>().join(","),
        Format::Jsonl => t.json_line(&[], row),
    }
}

/// Write the tables of `c` into `dir` (created if needed). Existing files of
/// the export are refused unless `force`; nothing is written before that check.
pub fn export(
    c: &Contents,
    source: &Path,
    dir: &Path,
    format: Format,
    force: bool,
) -> Result<Exported> {
    export_with(c, source, dir, format, force, |row| {
        c.messages.iter().try_for_each(row)
    })
}

/// [`export`] of a finished file streamed from disk, one chunk at a time:
/// peak memory does not grow with the recording's length. Two passes (the
/// metadata that names the sensors may follow the messages). The file's
/// contents without its messages are returned.
pub fn export_streaming(
    source: &Path,
    dir: &Path,
    format: Format,
    force: bool,
    selection: &crate::select::Selection,
) -> Result<(Exported, Contents)> {
    let mut t0 = u64::MAX;
    let mut c = recording::stream_finished(source, |m| -> Result<()> {
        t0 = t0.min(m.log_time);
        Ok(())
    })?;
    if c.damaged {
        return Err(damaged(source, &c));
    }
    crate::refuse_foreign(source, &c)?;
    recording::check_metadata(&c)?;
    selection.prepare(&mut c)?;
    let e = export_with(&c, source, dir, format, force, |row| {
        recording::stream_finished(source, |m| -> Result<()> {
            if selection.keeps(&c, t0, &m)? {
                row(&m)?;
            }
            Ok(())
        })
        .map(|_| ())
    })?;
    Ok((e, c))
}

/// The refusal of the damaged file `source` read into `c`.
fn damaged(source: &Path, c: &Contents) -> Error {
    Error::Damaged {
        file: source.to_path_buf(),
        why: c
            .truncated
            .as_deref()
            .unwrap_or("unreadable record")
            .to_string(),
    }
}

/// A message of an etp channel as its table's typed row: THE decoding of
/// `export`, `cat` and [`Rows`].
pub(crate) fn decoded_row(
    t: &Table,
    m: &recording::RawMessage,
    names: &Names,
) -> Result<Vec<Cell>> {
    let rec = m
        .decode()
        .at_message(|| format!("message at log time {}", m.log_time))?;
    Ok(t.row(m.log_time, &rec, names))
}

/// A finished recording's typed rows, read the way [`export_streaming`]
/// reads them (the same checks, tables and decoding) but handed to the
/// caller instead of written: the Python package's `read_recording`.
/// [`Rows::open`] is the first pass (everything but the messages: the
/// metadata that names the sensors may follow them), [`Rows::for_each`]
/// the second, one chunk at a time.
pub struct Rows {
    pub source: PathBuf,
    /// The file without its messages.
    pub contents: Contents,
    /// Topic → table, etp's channels only.
    pub tables: BTreeMap<String, Table>,
    names: Names,
}

impl Rows {
    /// The first pass over the finished file at `source`; a damaged file or
    /// metadata whose hashes disagree is refused as `export` refuses it.
    pub fn open(source: &Path) -> Result<Self> {
        let c = recording::stream_finished(source, |_| -> Result<()> { Ok(()) })?;
        if c.damaged {
            return Err(damaged(source, &c));
        }
        recording::check_metadata(&c)?;
        let (names, dim) = names(&c);
        let tables = tables(&c, dim)?;
        Ok(Self {
            source: source.to_path_buf(),
            contents: c,
            tables,
            names,
        })
    }

    /// The second pass: `row(topic, cells)` for every message of an etp
    /// channel, in file order (cells in the order of its table's columns).
    pub fn for_each(&self, mut row: impl FnMut(&str, Vec<Cell>) -> Result<()>) -> Result<()> {
        recording::stream_finished(&self.source, |m| -> Result<()> {
            match self.tables.get(&m.topic) {
                Some(t) => row(&m.topic, decoded_row(t, &m, &self.names)?),
                // A channel etp did not write has no typed table.
                None if self.contents.channels.contains_key(&m.topic) => Ok(()),
                None => Err(Error::UndeclaredChannel(m.topic.clone())),
            }
        })
        .map(|_| ())
    }
}

/// The export, its messages handed in by `messages` (from memory or streamed).
fn export_with(
    c: &Contents,
    source: &Path,
    dir: &Path,
    format: Format,
    force: bool,
    messages: impl FnOnce(&mut dyn FnMut(&recording::RawMessage) -> Result<()>) -> Result<()>,
) -> Result<Exported> {
    let (names, dim) = names(c);
    let tables = tables(c, dim)?;
    let files: BTreeMap<&str, PathBuf> = tables
        .keys()
        .map(|t| (t.as_str(), dir.join(table_file(t, format))))
        .collect();
    let manifest = dir.join("tables.json");
    etp_files::write::output_folder(dir)?;
    for p in files.values().chain([&manifest]) {
        etp_files::write::refuse_existing(p, force)?;
    }
    let mut writers: BTreeMap<&str, (std::io::BufWriter<std::fs::File>, PathBuf, u64)> =
        BTreeMap::new();
    for (topic, path) in &files {
        let tmp = etp_files::write::temp_sibling(path);
        let f = etp_files::write::create_exclusive(&tmp)?;
        let mut w = std::io::BufWriter::new(f);
        if let Some(h) = header_line(&tables[*topic].columns, format) {
            writeln!(w, "{h}").doing(|| format!("writing {}", tmp.display()))?;
        }
        writers.insert(topic, (w, tmp, 0));
    }
    let result = messages(&mut |m: &recording::RawMessage| -> Result<()> {
        let (Some(t), Some((w, tmp, n))) =
            (tables.get(&m.topic), writers.get_mut(m.topic.as_str()))
        else {
            // A channel etp did not write has no typed table (`cat` shows it).
            if c.channels.contains_key(&m.topic) {
                return Ok(());
            }
            return Err(Error::UndeclaredChannel(m.topic.clone()));
        };
        let row = decoded_row(t, m, &names)?;
        writeln!(w, "{}", row_line(t, &row, format))
            .doing(|| format!("writing {}", tmp.display()))?;
        *n += 1;
        Ok(())
    });
    let mut rows = 0u64;
    let mut bytes = 0u64;
    let mut described = Vec::new();
    for (topic, (mut w, tmp, n)) in writers {
        let flushed = w.flush().doing(|| format!("writing {}", tmp.display()));
        if result.is_err() || flushed.is_err() {
            let _ = std::fs::remove_file(&tmp);
            flushed?;
            continue;
        }
        let path = &files[topic];
        std::fs::rename(&tmp, path).doing(|| format!("moving {} into place", path.display()))?;
        bytes += std::fs::metadata(path).map_or(0, |m| m.len());
        rows += n;
        let t = &tables[topic];
        described.push(json!({
            "topic": topic,
            "file": table_file(topic, format),
            "schema": t.kind.schema_name(),
            "rows": n,
            "columns": t.columns,
        }));
    }
    result?;
    // A JSON value's alternate form is `serde_json::to_string_pretty`'s text.
    let text = json!({
        "source": source.display().to_string(),
        "format": format.ext(),
        "metadata": c.metadata,
        "codes": codes(),
        "tables": described,
    });
    etp_files::write::write_new(&manifest, format!("{text:#}\n").as_bytes(), force)?;
    Ok(Exported {
        dir: dir.display().to_string(),
        format: format.ext(),
        tables: tables.len() as u64,
        rows,
        bytes,
    })
}

/// How the exported tables show the codes (also in `recordings/README.md`).
fn codes() -> Value {
    json!({
        "sender": "a sensor's name, `coordinator` or `agent`",
        "outcome": "target | collision | free",
        "kind (control)": "start | stop",
        "kind (threshold)": "open | close | stop",
        "sensor, dead_sensor": "a sensor's name (dead_sensor: empty / null = none)",
        "delivered, degraded, prev_degraded": "true | false",
        "arrays": "one column per entry up to the scenario's dimension n: y_<i>, x_<i>, mean_<i>, cov_<row>_<col> (row-major)",
        "log_time_ns": "the recorder's time stamp (ns since the Unix epoch)",
    })
}
