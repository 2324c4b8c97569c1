//! `etp replay FILE`: the run's summary from a recording alone (episodes,
//! outcomes, per-sensor transmissions = `measurement` messages beside the
//! sensors' ledgers and what the agent received, energy vs prediction). Works
//! on an unfinished file (crashed recorder): every complete record is read.
//! `--repair OUT` writes a finished copy; `--verify` re-runs the estimator
//! (`etp_runtime::recording::verify`); `--publish` puts the traffic back on
//! iceoryx2 (`publish.rs`); `--foxglove OUT` writes a copy that Foxglove
//! draws (`foxglove.rs`). Exit codes: 0 complete file, 3 unfinished file
//! (cut anywhere by a crash or a copy: summary of every complete record
//! printed), 1 error — including a damaged file (bad chunk, data or summary
//! CRC, undecodable record, metadata whose scenario hashes disagree), which
//! only `--repair` reads (salvaging the records before the damage). Output
//! goes through [`emit`]: a closed stdout never panics.

mod foxglove;
mod publish;
mod repair;
mod summary;

use anyhow::{Context, Result, bail};
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
    /// Overwrite output files that exist.
    #[arg(long)]
    pub force: bool,
}

/// The MCAP writer of `etp replay`'s copies (zstd, 1 MiB chunks), with the
/// source's metadata records already written.
fn copy_writer(
    c: &Contents,
    path: &Path,
    profile: &str,
    what: &str,
) -> Result<mcap::Writer<std::io::BufWriter<std::fs::File>>> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(1024 * 1024))
        .profile(profile)
        .library(format!("etp replay {what} {}", env!("CARGO_PKG_VERSION")))
        .create(std::io::BufWriter::new(file))
        .context("starting the MCAP writer")?;
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
    let buf = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(recording::read_lenient(&path.display().to_string(), &buf)?)
}

/// Refuse an output path that exists (unless `--force`) or is the input.
fn check_output(input: &Path, out: &Path, force: bool) -> Result<()> {
    if out == input
        || std::fs::canonicalize(out)
            .ok()
            .is_some_and(|o| std::fs::canonicalize(input).ok() == Some(o))
    {
        bail!(
            "{} is the recording being read: choose another output",
            out.display()
        );
    }
    crate::output::refuse_existing(out, force)
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
    let c = load(&a.file)?;
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
    let s = summary::summarize(&c)?;
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
            Some(publish::publish(&c, &run, a.rate).context("--publish")?)
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
