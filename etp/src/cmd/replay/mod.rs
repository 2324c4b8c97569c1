//! `etp replay`: the recording tools of `etp_recording_tools`, as
//! subcommands like `ros2 bag` and the `mcap` CLI:
//!
//! `etp replay summary FILE` (also plain `etp replay FILE`), `info`, `cat`,
//! `export FILE DIR`, `filter FILE OUT`, `verify`, `repair FILE OUT`,
//! `publish`, `foxglove FILE OUT`, `plot`: one tool per subcommand, each
//! parsed into the one [`Job`] that runs it.
//!
//! Exit codes (README "Exit codes"): 0 a complete file whose identities
//! hold; 1 an error, a damaged file (only `repair` reads it), a file that
//! is not an etp recording (only `info`, `cat` and `repair` read it) or a failed
//! verification; 3 an unfinished file (cut by a crash or a copy: every
//! complete record is summarised); 4 a count identity fails on the complete
//! episodes (`measurement` messages ≠ ledger transmissions, or ≠ received
//! without a dead link); 5 the file lacks channels a count or a check needs
//! (a filtered copy: what needs them is named, null, not checked). Output
//! goes through `emit`: a closed stdout never panics.

use anyhow::{Context, Result, bail};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use etp_recording_tools::{
    cat, check_output, export, figure, foxglove, info, load_bytes, publish, refuse_foreign, repair,
    select, summary,
};
use etp_runtime::recording::{self, Contents};
use etp_runtime::wire::RunId;
use serde_json::json;
use std::path::{Path, PathBuf};

mod job;
mod output;
pub use job::Job;
use output::{emit, render_verify};

#[derive(Debug, clap::Args)]
#[command(
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = EXIT_CODES
)]
pub struct Args {
    #[command(subcommand)]
    pub action: Option<Action>,
    #[command(flatten)]
    pub plain: Plain,
}

/// `etp replay FILE [--json] [selection]`: the summary.
#[derive(Debug, clap::Args)]
pub struct Plain {
    /// An MCAP recording (`etp run --record`).
    #[arg(required = true)]
    pub file: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub select: SelectArgs,
}

/// `--topics`, `--exclude-topics`, `--episodes`, `--start`, `--end`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SelectArgs {
    /// Only these channels (comma-separated topics; `*` matches any text,
    /// e.g. `outcome,sensor/*/handover`).
    #[arg(long, value_delimiter = ',', value_name = "TOPICS")]
    pub topics: Vec<String>,
    /// Leave out these channels (comma-separated topics; `*` matches any
    /// text, e.g. `sensor/*/truth`); applied after `--topics`.
    #[arg(long, value_delimiter = ',', value_name = "TOPICS")]
    pub exclude_topics: Vec<String>,
    /// Only these episodes (`header.episode`, 0-based): `A..B` (B excluded),
    /// `A..=B`, `A..`, `..B` or `N`.
    #[arg(long, value_parser = select::parse_episodes, value_name = "RANGE")]
    pub episodes: Option<select::Episodes>,
    /// Only messages from this many seconds after the first message on.
    #[arg(long, value_parser = select::parse_offset, value_name = "SECONDS")]
    pub start: Option<f64>,
    /// Only messages up to this many seconds after the first message.
    #[arg(long, value_parser = select::parse_offset, value_name = "SECONDS")]
    pub end: Option<f64>,
}

/// What a tool that writes a file is told: whether it may replace one, and
/// whether it prints what it wrote as one JSON object.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct WriteArgs {
    /// Replace an existing output (written beside, then renamed).
    #[arg(long)]
    pub force: bool,
    /// Print what was written as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `etp replay --help`'s last words (README "Exit codes").
const EXIT_CODES: &str = "Without a subcommand, `etp replay FILE` prints the summary (as `etp \
replay summary FILE`). Exit codes: 0 a complete recording whose count identities hold; 3 an \
unfinished recording (every complete record summarised; `repair` writes a finished copy); 4 a \
count identity fails on the complete episodes; 5 the file lacks channels a count or a check \
needs (a copy filtered by topic); 1 an error: an unreadable or damaged file, a file that is \
not an etp recording (only `info`, `cat` and `repair` read it), an output that exists without \
--force or whose folder does not exist, or `verify` found a difference; 2 a bad command line.";

/// One recording tool.
#[derive(Debug, clap::Subcommand)]
pub enum Action {
    /// The run's summary: complete episodes, outcomes, per-sensor
    /// transmissions beside ledgers and received, energy vs prediction.
    Summary {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        select: SelectArgs,
    },
    /// What the file holds (size, compression, time span, schemas, messages
    /// per channel and their publish-to-record times, metadata), like `mcap info`.
    Info {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        select: SelectArgs,
    },
    /// Every (selected) message decoded, one JSON object per line, in
    /// log-time order: its typed row (as `export --format jsonl`), or with
    /// --json the line `mcap cat --json` prints.
    Cat {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// Lines shaped as `mcap cat --json`'s: topic, sequence, log_time,
        /// publish_time (seconds) and data (the protobuf message as JSON).
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        select: SelectArgs,
    },
    /// One table per channel into DIR (decoded, typed columns, codes as
    /// names; `DIR/tables.json` describes them).
    Export {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// The folder of the tables (created if missing; a table that exists is
        /// replaced only with --force).
        dir: PathBuf,
        /// The tables' format: `csv` or `jsonl` (one JSON object per line).
        #[arg(long, default_value = "csv",
              value_parser = PossibleValuesParser::new(export::Format::NAMES).try_map(|s| s.parse::<export::Format>()))]
        format: export::Format,
        #[command(flatten)]
        write: WriteArgs,
        #[command(flatten)]
        select: SelectArgs,
    },
    /// Write the selected messages (all metadata kept) to a new, finished
    /// recording OUT, like `mcap filter`.
    Filter {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// The new recording (MCAP); its folder must exist.
        out: PathBuf,
        #[command(flatten)]
        write: WriteArgs,
        #[command(flatten)]
        select: SelectArgs,
    },
    /// Re-run the agent's estimator on the recorded measurements and silent
    /// slots; every recorded belief must be reproduced bit for bit (exit 1 if
    /// not).
    Verify {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Write a finished copy (summary, indexes, footer) of an unfinished or
    /// damaged file: every complete record before the cut or the damage.
    Repair {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// The finished copy (MCAP); its folder must exist.
        out: PathBuf,
        #[command(flatten)]
        write: WriteArgs,
    },
    /// Re-publish the recorded traffic on iceoryx2 (like `ros2 bag play`).
    Publish {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// 1 = recorded timing, 2 = twice as fast, `inf` = as fast as the
        /// subscribers take it.
        #[arg(long, default_value = "1", value_parser = publish::parse_rate)]
        rate: f64,
        /// Run id (services `etp/<run-id>/…`); default: a fresh one.
        #[arg(long)]
        run_id: Option<String>,
        /// Repeat: `--loop` until interrupted, `--loop N` N times in all (N ≥ 1).
        #[arg(long = "loop", value_name = "N", num_args = 0..=1,
              default_missing_value = UNTIL_INTERRUPTED, value_parser = loops)]
        repeat: Option<u64>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        select: SelectArgs,
    },
    /// Write a copy Foxglove draws (map, agent with 3σ ellipse, paths,
    /// transmissions, outcomes) to OUT; `--episodes` cuts it.
    Foxglove {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// The Foxglove copy (MCAP, JSON messages); its folder must exist.
        out: PathBuf,
        /// `step` (10 ms per plant step) or `recorded` (recorder time stamps).
        #[arg(long, default_value = "step",
              value_parser = PossibleValuesParser::new(foxglove::Clock::NAMES).try_map(|s| s.parse::<foxglove::Clock>()))]
        clock: foxglove::Clock,
        /// Only these episodes (`A..B`, `A..=B`, `A..`, `..B` or `N`).
        #[arg(long, value_parser = select::parse_episodes, value_name = "RANGE")]
        episodes: Option<select::Episodes>,
        #[command(flatten)]
        write: WriteArgs,
    },
    /// Draw measured vs predicted (per-sensor energy per episode, outcomes,
    /// 95 % intervals) to `<FILE without .mcap>-replay.png` and `.svg`, or
    /// to `-o STEM`.
    Plot {
        /// An MCAP recording (`etp run --record`).
        file: PathBuf,
        /// Figure file stem: writes STEM.png and STEM.svg (its folder must
        /// exist; default: `<FILE without .mcap>-replay`).
        #[arg(short = 'o', long = "out", value_name = "STEM")]
        out: Option<PathBuf>,
        #[command(flatten)]
        write: WriteArgs,
    },
}

/// Exit code of `etp replay` on an unfinished recording (summary printed).
pub const EXIT_UNFINISHED: u8 = 3;
/// Exit code of `etp replay` when a count identity fails on the complete
/// episodes.
pub const EXIT_IDENTITY: u8 = 4;
/// Exit code of `etp replay` on a recording that lacks channels a count or a
/// check needs (a copy filtered by topic): what it holds is printed, what
/// needs the missing channels is named and not checked.
pub const EXIT_MISSING_CHANNELS: u8 = 5;

/// `--loop` given without N (the publisher's 0: until interrupted).
const UNTIL_INTERRUPTED: &str = "until-interrupted";

/// `--loop [N]`: N ≥ 1 times in all, or without N until interrupted. A
/// typed `--loop 0` is refused: it would have looped without end.
fn loops(s: &str) -> Result<u64, String> {
    if s == UNTIL_INTERRUPTED {
        return Ok(0);
    }
    crate::values::whole::<u64>(1, None)(s)
        .map_err(|e| format!("{e} (`--loop` alone: until interrupted)"))
}

pub fn run(a: Args) -> Result<()> {
    let job = match a.action {
        Some(action) => action.job(),
        None => Action::Summary {
            file: a.plain.file.context("no recording given")?,
            json: a.plain.json,
            select: a.plain.select,
        }
        .job(),
    };
    run_job(job)
}

fn run_job(a: Job) -> Result<()> {
    let file = a.file.clone().context("no recording given")?;
    for out in [&a.repair, &a.foxglove, &a.filter].into_iter().flatten() {
        check_output(&file, out, a.force)?;
    }
    // `verify`, `repair` and `foxglove` take no selection but episodes
    // (their parsers have none): they read whole recordings.
    let selection = a.selection();
    // `export` alone on a finished file streams it: memory stays flat
    // however long the recording.
    if let Some(dir) = a.export.as_ref().filter(|_| a.only)
        && recording::ends_finished(&file).unwrap_or(false)
    {
        let (e, _) = export::export_streaming(&file, dir, a.format, a.force, &selection)
            .with_context(|| format!("exporting to {}", dir.display()))?;
        eprintln!(
            "exported {} rows in {} tables to {} ({} bytes)",
            e.rows, e.tables, e.dir, e.bytes
        );
        if a.json {
            emit(&format!("{}\n", json!({ "exported": e })))?;
        }
        return Ok(());
    }
    // The summary alone of a whole finished file streams it too.
    if a.summary_alone()
        && selection.is_all()
        && recording::ends_finished(&file).unwrap_or(false)
        && let Some((s, c)) = summary::summarize_file(&file)?
    {
        refuse_foreign(&file, &c)?;
        if let Err(e) = recording::check_metadata(&c) {
            bail!(
                "{} is damaged: {e}; `etp replay repair {} OUT` copies its records anyway",
                file.display(),
                file.display()
            );
        }
        emit(&if a.json {
            format!("{s}\n")
        } else {
            summary::render(&file, &c, &s)
        })?;
        return summary_exit(&a, &file, &c, &s);
    }
    let (mut c, buf) = load_bytes(&file)?;
    // A damaged file is refused unless the user asked to salvage it.
    if c.damaged && a.repair.is_none() {
        bail!(
            "{} is damaged: {}; {} complete messages precede the damage \
             (`etp replay repair {} OUT` salvages them)",
            file.display(),
            c.truncated.as_deref().unwrap_or("unreadable record"),
            c.messages.len(),
            file.display()
        );
    }
    // The metadata must describe one scenario (hashes of etp.run and of the
    // strategy against the recorded scenario's content).
    if let Err(e) = recording::check_metadata(&c) {
        if a.repair.is_none() {
            bail!(
                "{} is damaged: {e}; `etp replay repair {} OUT` copies its records anyway",
                file.display(),
                file.display()
            );
        }
        eprintln!("warning: {e}; the repaired copy keeps this metadata");
    }
    // `info` and `cat` read any MCAP file; `repair` copies any file's records.
    if !(a.info || a.cat) && a.repair.is_none() {
        refuse_foreign(&file, &c)?;
    }
    selection.apply(&mut c)?;
    if a.info {
        let v = info::info(&file, buf.len() as u64, &c, &recording::layout(&buf));
        drop(buf);
        emit(&if a.json {
            format!("{v}\n")
        } else {
            info::render(&v)
        })?;
        return unfinished_exit(&a, &file, &c);
    }
    drop(buf);
    if a.cat {
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        let shape = if a.json {
            cat::Shape::Mcap
        } else {
            cat::Shape::Rows
        };
        match cat::cat(&c, &mut out, shape) {
            Err(e) if e.is_broken_pipe() => return Ok(()),
            r => {
                r.context("cat")?;
            }
        }
        return unfinished_exit(&a, &file, &c);
    }
    let exported = match &a.export {
        Some(dir) => {
            let e = export::export(&c, &file, dir, a.format, a.force)
                .with_context(|| format!("exporting to {}", dir.display()))?;
            eprintln!(
                "exported {} rows in {} tables to {} ({} bytes)",
                e.rows, e.tables, e.dir, e.bytes
            );
            Some(e)
        }
        None => None,
    };
    let s = summary::summarize(&c)?;
    let plotted = match a.plot {
        true => {
            let stem = match &a.plot_out {
                Some(stem) => {
                    etp_files::write::existing_folder_of(stem, "-o")?;
                    stem.clone()
                }
                None => file.with_extension("").with_file_name(format!(
                    "{}-replay",
                    file.file_stem()
                        .and_then(|x| x.to_str())
                        .unwrap_or("recording")
                )),
            };
            let png = stem.with_extension("png");
            for p in [&png, &stem.with_extension("svg")] {
                etp_files::write::refuse_existing(p, a.force)?;
            }
            let names = export::names(&c).0.sensors;
            etp_figures::report_plot(&figure::figure(&c, &names)?, &stem)?;
            eprintln!("wrote {} and .svg", png.display());
            Some(png)
        }
        false => None,
    };
    if let Some(out) = &a.repair {
        let n = repair::repair(&c, out)?;
        eprintln!("repaired copy: {} ({n} messages)", out.display());
    }
    let filtered = match &a.filter {
        Some(out) => {
            let n = repair::filter(&c, out)?;
            eprintln!("filtered copy: {} ({n} messages)", out.display());
            Some(n)
        }
        None => None,
    };
    let fox = match &a.foxglove {
        Some(out) => {
            let st = foxglove::write_foxglove(&c, out, a.foxglove_clock)
                .with_context(|| format!("writing the Foxglove copy {}", out.display()))?;
            eprintln!(
                "foxglove copy: {} ({} messages)",
                out.display(),
                st.messages
            );
            Some(st)
        }
        None => None,
    };
    let published = match a.publish {
        true => {
            let run = match &a.run_id {
                Some(id) => RunId::new(id)?,
                None => RunId::generate(),
            };
            eprintln!(
                "publishing {} messages on services etp/{run}/… at rate {}",
                c.messages.len(),
                a.rate
            );
            Some(publish::publish(&c, &run, a.rate, a.repeat).context("publish")?)
        }
        false => None,
    };
    // A copy without the channels the re-run needs cannot be verified: say
    // which, never "not reproduced".
    let unverifiable = if a.verify {
        recording::verify_missing_channels(&c)
    } else {
        Vec::new()
    };
    let verified = if a.verify && unverifiable.is_empty() {
        Some(recording::verify(&c).context("verifying the recording")?)
    } else {
        None
    };
    if a.json {
        let mut s = s.clone();
        if let Some(v) = &verified {
            s["verify"] = json!(v);
            s["verify"]["passed"] = json!(v.passed());
        }
        if !unverifiable.is_empty() {
            s["verify"] = json!({"passed": null, "missing_channels": unverifiable});
        }
        if let Some(p) = &published {
            s["published"] = json!(p);
        }
        if let Some(f) = &fox {
            s["foxglove"] = json!(f);
        }
        if let Some(e) = &exported {
            s["exported"] = json!(e);
        }
        if let Some(p) = &plotted {
            s["plot"] = json!(p);
        }
        if let (Some(n), Some(out)) = (filtered, &a.filter) {
            s["filtered"] = json!({"file": out, "messages": n});
        }
        emit(&format!("{s}\n"))?;
    } else if !a.only {
        let mut text = summary::render(&file, &c, &s);
        if let Some(v) = &verified {
            text.push_str(&render_verify(v));
        }
        if !unverifiable.is_empty() {
            text.push_str(&format!(
                "verify: NOT POSSIBLE · the recording lacks the channels the re-run needs: {} (a filtered copy: verify the original)\n",
                unverifiable.join(", ")
            ));
        }
        if let Some(p) = &published {
            text.push_str(&format!(
                "published {} messages on run {} in {:.2} s (recorded span {:.2} s, rate {}); {} reached no subscriber\n",
                p.messages, p.run_id, p.wall_seconds, p.recorded_seconds, p.rate, p.undelivered
            ));
        }
        emit(&text)?;
    }
    if let Some(v) = verified
        && !v.passed()
    {
        let first = v.mismatches.first().map_or(String::new(), |m| {
            format!(
                " (first: episode {} leg {} step {}: {})",
                m.episode, m.leg, m.step, m.what
            )
        });
        bail!(
            "verify FAILED: {} of the {} re-run episodes were not reproduced{first}",
            v.mismatch_count,
            v.episodes_checked
        );
    }
    if !unverifiable.is_empty() {
        return Err(etp_runtime::shell::ExitWith {
            code: EXIT_MISSING_CHANNELS,
            message: format!(
                "error: {}: nothing verified: the recording lacks {}",
                file.display(),
                unverifiable.join(", ")
            ),
        }
        .into());
    }
    summary_exit(&a, &file, &c, &s)
}

/// The exit of a summary `s`: 4 when an identity fails, 5 when the file
/// lacks channels the summary needs (a filtered copy; not for a
/// `--topics` selection, which asked for it), 3 for an unfinished file.
fn summary_exit(a: &Job, file: &Path, c: &Contents, s: &serde_json::Value) -> Result<()> {
    // A selection of channels leaves the identities' other side out.
    if !a.only
        && a.select.topics.is_empty()
        && a.select.exclude_topics.is_empty()
        && s["identities_hold"] == json!(false)
    {
        return Err(etp_runtime::shell::ExitWith {
            code: EXIT_IDENTITY,
            message: format!(
                "error: {}: a count identity fails on the complete episodes: {}",
                file.display(),
                s["identity_failures"]
            ),
        }
        .into());
    }
    // An unfinished file may not have reached its channels' records yet:
    // exit 3 says that first.
    if !a.only
        && c.finished
        && a.select.topics.is_empty()
        && a.select.exclude_topics.is_empty()
        && let Some(missing) = s["missing_channels"].as_array().filter(|m| !m.is_empty())
    {
        let names: Vec<&str> = missing.iter().filter_map(|m| m.as_str()).collect();
        return Err(etp_runtime::shell::ExitWith {
            code: EXIT_MISSING_CHANNELS,
            message: format!(
                "warning: {}: the recording lacks the channels {}: the summary counts what it holds; \
                 what needs them is null and not checked",
                file.display(),
                names.join(", ")
            ),
        }
        .into());
    }
    unfinished_exit(a, file, c)
}

/// Exit code 3 (with a warning) for an unfinished file, unless repaired.
fn unfinished_exit(a: &Job, file: &Path, c: &Contents) -> Result<()> {
    if !c.finished && a.repair.is_none() && a.filter.is_none() {
        return Err(etp_runtime::shell::ExitWith {
            code: EXIT_UNFINISHED,
            message: format!(
                "warning: {} is unfinished (its recorder stopped before finishing it): \
                 the summary covers every complete record; `etp replay repair FILE OUT` \
                 writes a finished copy",
                file.display()
            ),
        }
        .into());
    }
    Ok(())
}
