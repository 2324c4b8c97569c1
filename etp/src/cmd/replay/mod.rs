//! `etp replay FILE`: the run's summary from a recording alone (episodes,
//! outcomes, per-sensor transmissions = `measurement` messages beside the
//! sensors' ledgers and what the agent received, energy vs prediction). Works
//! on an unfinished file (crashed recorder): every complete record is read.
//! `--repair OUT` writes a finished copy; `--verify` re-runs the estimator
//! (`etp_runtime::recording::verify`); `--publish` puts the traffic back on
//! iceoryx2 (`publish.rs`); `--foxglove OUT` writes a copy that Foxglove
//! draws (`foxglove.rs`); `--info` (`info.rs`), `--cat` and `--export DIR`
//! (`export.rs`), `--plot` (`figure.rs`), on the messages selected by
//! `--topics`, `--episodes`, `--start`/`--end` (`select.rs`). Exit codes: 0 complete file, 3 unfinished file
//! (cut anywhere by a crash or a copy: summary of every complete record
//! printed), 1 error — including a damaged file (bad chunk, data or summary
//! CRC, undecodable record, metadata whose scenario hashes disagree), which
//! only `--repair` reads (salvaging the records before the damage). Output
//! goes through [`emit`]: a closed stdout never panics.


use anyhow::{Context, Result, bail};
use etp_recording_tools::{
    check_output, export, figure, foxglove, info, load_bytes, publish, repair, select, summary,
};
use etp_runtime::recording::{self, Contents};
use etp_runtime::wire::RunId;
use serde_json::json;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// An MCAP recording (`etp run --record`).
    pub file: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write a finished copy (summary, indexes, footer) of the file to OUT.
    #[arg(long, value_name = "OUT")]
    pub repair: Option<PathBuf>,
    /// Re-run the agent's estimator on the recorded measurements and silent
    /// slots and check it reproduces every recorded belief bit for bit
    /// (exit code 1 if not).
    #[arg(long)]
    pub verify: bool,
    /// Re-publish the recorded traffic on iceoryx2 (like `ros2 bag play`), at
    /// the recorded timing divided by `--rate`, on the services of run
    /// `--run-id` (start subscribers such as `etp-recorder --run-id ID` first).
    #[arg(long)]
    pub publish: bool,
    /// Speed of `--publish`: 1 = recorded timing, 2 = twice as fast, `inf` =
    /// as fast as the subscribers take it.
    #[arg(long, default_value = "1", value_parser = publish::parse_rate, requires = "publish")]
    pub rate: f64,
    /// Run id (services `etp/<run-id>/…`) for `--publish`; default: a fresh one.
    #[arg(long, requires = "publish")]
    pub run_id: Option<String>,
    /// Write a copy for Foxglove to OUT: JSON messages with Foxglove's
    /// schemas (map, agent with 3σ ellipse, paths, transmissions, outcomes).
    #[arg(long, value_name = "OUT")]
    pub foxglove: Option<PathBuf>,
    /// Times of the `--foxglove` copy: `step` (10 ms per plant step, smooth
    /// playback at 1×) or `recorded` (the recorder's time stamps).
    #[arg(long, value_enum, default_value = "step", requires = "foxglove")]
    pub foxglove_clock: foxglove::Clock,
    /// Repeat `--publish`: `--loop` until interrupted (Ctrl-C, SIGTERM),
    /// `--loop N` N times in all.
    #[arg(long = "loop", value_name = "N", num_args = 0..=1, default_missing_value = "0", requires = "publish")]
    pub repeat: Option<u64>,
    /// Write one table per channel into DIR (decoded, typed columns, codes
    /// as names; `DIR/tables.json` describes them).
    #[arg(long, value_name = "DIR")]
    pub export: Option<PathBuf>,
    /// Table format of `--export`.
    #[arg(long, value_enum, default_value = "csv", requires = "export")]
    pub format: export::Format,
    /// Print every (selected) message decoded, as one JSON object per line,
    /// in log-time order (instead of the summary).
    #[arg(long, conflicts_with_all = ["json", "info"])]
    pub cat: bool,
    /// Print what the file holds (size, compression, time span, schemas,
    /// messages per channel, metadata) instead of the summary.
    #[arg(long)]
    pub info: bool,
    /// Only these channels (comma-separated topics; `*` matches any text,
    /// e.g. `outcome,sensor/*/handover`).
    #[arg(long, value_delimiter = ',', value_name = "TOPICS")]
    pub topics: Vec<String>,
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
    /// Draw measured vs predicted (per-sensor energy per episode, outcomes,
    /// 95 % intervals) to `<FILE without .mcap>-report.png` and `.svg`.
    #[arg(long)]
    pub plot: bool,
    /// Overwrite output files that exist.
    #[arg(long)]
    pub force: bool,
}

impl Args {
    fn selection(&self) -> select::Selection {
        select::Selection {
            topics: self.topics.clone(),
            episodes: self.episodes,
            start: self.start,
            end: self.end,
        }
    }
}

/// Exit code of `etp replay` on an unfinished recording (summary printed).
pub const EXIT_UNFINISHED: u8 = 3;

pub fn run(a: Args) -> Result<()> {
    if let Some(out) = &a.repair {
        check_output(&a.file, out, a.force)?;
    }
    if let Some(out) = &a.foxglove {
        check_output(&a.file, out, a.force)?;
        if a.repair.as_ref() == Some(out) {
            bail!("--repair and --foxglove both write {}", out.display());
        }
    }
    let selection = a.selection();
    if !selection.is_all() {
        for (on, flag) in [
            (a.verify, "--verify"),
            (a.repair.is_some(), "--repair"),
            (a.foxglove.is_some(), "--foxglove"),
        ] {
            if on {
                bail!(
                    "{flag} reads the whole recording: --topics, --episodes, --start and --end \
                     select messages for the summary, --info, --cat, --export and --publish only"
                );
            }
        }
    }
    let (mut c, buf) = load_bytes(&a.file)?;
    // A damaged file is refused unless the user asked to salvage it.
    if c.damaged && a.repair.is_none() {
        bail!(
            "{} is damaged: {}; {} complete messages precede the damage \
             (`etp replay {} --repair OUT` salvages them)",
            a.file.display(),
            c.truncated.as_deref().unwrap_or("unreadable record"),
            c.messages.len(),
            a.file.display()
        );
    }
    // The metadata must describe one scenario (hashes of etp.run and of the
    // strategy against the recorded scenario's content).
    if let Err(e) = recording::check_metadata(&c) {
        if a.repair.is_none() {
            bail!(
                "{} is damaged: {e}; `etp replay {} --repair OUT` copies its records anyway",
                a.file.display(),
                a.file.display()
            );
        }
        eprintln!("warning: {e}; the repaired copy keeps this metadata");
    }
    selection.apply(&mut c)?;
    if a.info {
        let v = info::info(&a.file, buf.len() as u64, &c, &recording::layout(&buf));
        drop(buf);
        emit(&if a.json {
            format!("{v}\n")
        } else {
            info::render(&v)
        })?;
        return unfinished_exit(&a, &c);
    }
    drop(buf);
    if a.cat {
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        match export::cat(&c, &mut out) {
            Err(e) if is_broken_pipe(&e) => return Ok(()),
            r => {
                r.context("--cat")?;
            }
        }
        return unfinished_exit(&a, &c);
    }
    let exported = match &a.export {
        Some(dir) => {
            let e = export::export(&c, &a.file, dir, a.format, a.force)
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
            let stem = a.file.with_extension("").with_file_name(format!(
                "{}-report",
                a.file
                    .file_stem()
                    .and_then(|x| x.to_str())
                    .unwrap_or("recording")
            ));
            let png = stem.with_extension("png");
            for p in [&png, &stem.with_extension("svg")] {
                etp_recording_tools::files::refuse_existing(p, a.force)?;
            }
            let names = export::names(&c).0.sensors;
            crate::report_plot::report_plot(&figure::figure(&c, &names)?, &stem)?;
            eprintln!("wrote {} and .svg", png.display());
            Some(png)
        }
        false => None,
    };
    if let Some(out) = &a.repair {
        let n = repair::repair(&c, out)?;
        eprintln!("repaired copy: {} ({n} messages)", out.display());
    }
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
            Some(publish::publish(&c, &run, a.rate, a.repeat).context("--publish")?)
        }
        false => None,
    };
    let verified = if a.verify {
        Some(recording::verify(&c).context("verifying the recording")?)
    } else {
        None
    };
    if a.json {
        let mut s = s;
        if let Some(v) = &verified {
            s["verify"] = json!(v);
            s["verify"]["passed"] = json!(v.passed());
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
        emit(&format!("{s}\n"))?;
    } else {
        let mut text = summary::render(&a.file, &c, &s);
        if let Some(v) = &verified {
            text.push_str(&render_verify(v));
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
        bail!(
            "verify FAILED: {} of the recorded beliefs were not reproduced",
            v.mismatch_count
        );
    }
    unfinished_exit(&a, &c)
}

/// Exit code 3 (with a warning) for an unfinished file, unless repaired.
fn unfinished_exit(a: &Args, c: &Contents) -> Result<()> {
    if !c.finished && a.repair.is_none() {
        return Err(crate::ExitWith {
            code: EXIT_UNFINISHED,
            message: format!(
                "warning: {} is unfinished (its recorder stopped before finishing it): \
                 the summary covers every complete record; `--repair OUT` writes a finished copy",
                a.file.display()
            ),
        }
        .into());
    }
    Ok(())
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Write `text` to stdout. A closed pipe (`etp replay F | head -1`) ends the
/// output quietly; another write error is reported, never a panic.
fn emit(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e).context("writing to stdout"),
        _ => Ok(()),
    }
}

fn render_verify(v: &recording::VerifyReport) -> String {
    let mut t = String::new();
    // Writing into a String cannot fail.
    let _ = write_verify(&mut t, v);
    t
}

fn write_verify(out: &mut String, v: &recording::VerifyReport) -> std::fmt::Result {
    use std::fmt::Write;
    writeln!(
        out,
        "verify: {} · {} decision-point beliefs and {} handovers reproduced bit for bit; \
         the sensors' replicas triggered on the agent's prior in all {} slots checked",
        if v.passed() { "PASSED" } else { "FAILED" },
        v.waypoints_checked,
        v.handovers_checked,
        v.priors_checked
    )?;
    writeln!(
        out,
        "  {} episodes re-run ({} steps: {} measurements, {} silent slots); {} incomplete (end of file), {} degraded skipped",
        v.episodes_checked,
        v.steps,
        v.explicit_updates,
        v.implicit_updates,
        v.episodes_incomplete,
        v.episodes_degraded_skipped
    )?;
    for m in &v.mismatches {
        writeln!(
            out,
            "  MISMATCH episode {} leg {} step {}: {} (max |diff| {:e})",
            m.episode, m.leg, m.step, m.what, m.max_abs_diff
        )?;
    }
    if v.mismatch_count > v.mismatches.len() as u64 {
        writeln!(out, "  … {} mismatches in all", v.mismatch_count)?;
    }
    Ok(())
}
