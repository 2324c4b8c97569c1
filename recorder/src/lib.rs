//! The `etp-recorder` process: subscribes to every publish-subscribe service of a run and
//! writes one MCAP file (format: `etp_runtime::recording`).
//!
//! Spawned by `etp run --record` before the other processes. It first creates
//! its output exclusively (`create_new`: an existing file — another run's
//! recording — is never opened, let alone truncated; the error names the path
//! and nothing is started), prints `ready` on stdout once every subscriber
//! exists, then records until SIGTERM/SIGINT (or its parent's death), drains
//! what is left, calls `finish()` and prints one JSON object
//! `{"path", "counts": {topic: n}, "messages", "bytes"}`. A closed stdout
//! (its parent died) is not an error: the file is finished all the same.
//! It never polls: it waits on every wake-up event of the run at once (each
//! publication is followed by one; one `wire::Waiter` over all of them), at
//! most 100 ms at a time for the flush, and drains its subscribers when woken.
//! zstd chunks of 128 KiB plus a flush every 100 ms: a crash loses at most the
//! last ~100 ms (`etp replay` calls such a file unfinished, exit 3, and
//! `--repair` finishes it). Logs go to stderr through `tracing` (`RUST_LOG`,
//! default `warn`; start, finish and counts at `info`).
//! A message's `log_time` is when the recorder took it off its subscriber,
//! its `publish_time` when its sender published it (the sample's user
//! header, `etp_runtime::wire::stamp`).

use anyhow::{Context, Result};
use clap::Parser;
use etp_runtime::recording::{self, Kind, observers};
use etp_runtime::shell::{self, Done};
use etp_runtime::wire::{self, Ports, RunId, ServiceId, Waiter, Wake};
use mcap::records::{MessageHeader, Metadata};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Record every message of an etpareto run to MCAP (spawned by `etp run --record`).
#[derive(Debug, Parser)]
#[command(name = "etp-recorder", version, about)]
pub struct Cli {
    /// Run id: records the services `etp/<run-id>/…` (of an `etp run
    /// --run-id ID`, or of an `etp replay FILE --publish --run-id ID`).
    #[arg(long)]
    run_id: String,
    /// Scenario (built-in name or TOML path): gives the number of sensors.
    #[arg(long)]
    scenario: String,
    /// Output MCAP file; must not exist (it is created exclusively).
    #[arg(long)]
    out: PathBuf,
    /// A JSON file `{record name: {key: value}}` written as the file's
    /// metadata records (`etp run --record` passes the run's: `etp.run`,
    /// `etp.scenario`, `etp.strategy`, `etp.prediction`, `etp.config`; see
    /// recordings/README.md). Without it, the metadata that `etp replay
    /// --publish` left for this run id is written when the recording ends, so
    /// a re-recorded replay summarises and verifies like the original.
    #[arg(long, value_name = "FILE")]
    meta: Option<PathBuf>,
}

/// Flush period, and the longest the recorder sleeps without a notification
/// (a publication not followed by a wake-up would wait at most this long).
const FLUSH_EVERY: Duration = Duration::from_millis(100);
const CHUNK: u64 = 128 * 1024;
/// What the recorder writes: the current format, every channel protobuf.
const ENCODING: recording::Encoding = recording::Encoding::Protobuf;

fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

struct Channel {
    id: u16,
    topic: String,
    drain: Box<dyn recording::ports::EncodedSubscriber>,
    count: u32,
    /// What the last pass took from the queue (each with its sender's
    /// time), and when.
    batch: Vec<(wire::stamp::PublishTime, recording::Recorded)>,
    received_at: u64,
}

/// Create the output exclusively: fails if anything exists at `path`.
fn create_output(path: &Path) -> Result<File> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .with_context(|| {
            format!(
                "cannot record to {}: the file could not be created exclusively \
                 (another run recording to it? use a new path, or `etp run --force` to replace it)",
                path.display()
            )
        })
}

/// The MCAP writer the recorder writes through.
type Writer = mcap::Writer<BufWriter<File>>;

/// Record to `file` (created by the caller) until told to stop.
fn run(cli: &Cli, file: File, ready: &mut bool) -> Result<serde_json::Value> {
    let run = RunId::new(&cli.run_id)?;
    let scenario = etp_runtime::load_scenario(&cli.scenario)?;
    let sensors = scenario.sensors.len();
    let node = wire::create_node(&run, wire::RECORDER_NODE)?;
    let ports = Ports {
        node: &node,
        run: &run,
        sensors,
    };
    let mut w = start_writer(cli, file)?;
    let mut channels = open_channels(&mut w, &ports, sensors)?;
    let waiter = Waiter::over(
        ServiceId::all_events(sensors)
            .into_iter()
            .map(|s| ports.listener(s))
            .collect::<Result<Vec<_>, _>>()?,
    )?;
    w.flush().context("flushing the MCAP header")?;
    // Announced before `ready`: a replay that starts after it waits until
    // this recorder has attached to its publishers (`observers`).
    observers::announce(&run).context("announcing the recorder in the run's folder")?;
    let _announced = Announced(&run);
    {
        let mut out = std::io::stdout().lock();
        writeln!(out, "ready")
            .and_then(|()| out.flush())
            .context("telling the parent `ready` on stdout")?;
    }
    *ready = true;
    tracing::info!(
        run = %run,
        path = %cli.out.display(),
        channels = channels.len(),
        "recording"
    );
    let handed_over = record_until_stopped(cli, &ports, &waiter, &mut w, &mut channels)?;
    finish_recording(cli, &run, w, &channels, handed_over)
}

/// The MCAP writer over `file`, with the metadata records of `--meta`
/// written first.
fn start_writer(cli: &Cli, file: File) -> Result<Writer> {
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(CHUNK))
        .profile(recording::PROFILE)
        .library(format!(
            "etp-recorder {} (recording format {})",
            env!("CARGO_PKG_VERSION"),
            recording::FORMAT_VERSION
        ))
        .create(BufWriter::new(file))
        .context("starting the MCAP writer")?;
    if let Some(meta) = &cli.meta {
        let text =
            std::fs::read_to_string(meta).with_context(|| format!("reading {}", meta.display()))?;
        let records: BTreeMap<String, BTreeMap<String, String>> =
            serde_json::from_str(&text).with_context(|| format!("parsing {}", meta.display()))?;
        for (name, metadata) in records {
            w.write_metadata(&Metadata { name, metadata })
                .context("writing metadata")?;
        }
    }
    Ok(w)
}

/// One channel per recorded service of the run (each schema written once),
/// each with its subscriber.
fn open_channels(w: &mut Writer, ports: &Ports<'_>, sensors: usize) -> Result<Vec<Channel>> {
    let mut schemas: BTreeMap<Kind, u16> = BTreeMap::new();
    let mut channels = Vec::new();
    for s in ServiceId::recorded(sensors) {
        let Some((topic, kind)) = recording::channel(s) else {
            continue;
        };
        let schema = match schemas.get(&kind) {
            Some(id) => *id,
            None => {
                let (name, encoding, data) = ENCODING.schema(kind)?;
                let id = w.add_schema(&name, encoding, &data)?;
                schemas.insert(kind, id);
                id
            }
        };
        let id = w.add_channel(
            schema,
            &topic,
            ENCODING.name(),
            &BTreeMap::from([("service".to_string(), s.name(ports.run))]),
        )?;
        let drain = recording::ports::encoded_subscriber(ports, s, true)?;
        channels.push(Channel {
            id,
            topic,
            drain,
            count: 0,
            batch: Vec::new(),
            received_at: 0,
        });
    }
    Ok(channels)
}

/// Record until SIGTERM/SIGINT or the parent's death, then drain what is
/// left; returns the metadata a replay handed over, if it was read.
fn record_until_stopped(
    cli: &Cli,
    ports: &Ports<'_>,
    waiter: &Waiter,
    w: &mut Writer,
    channels: &mut [Channel],
) -> Result<Option<HandedOver>> {
    let run = ports.run;
    let parent = std::os::unix::process::parent_id();
    let mut last_flush = Instant::now();
    let mut stopping = false;
    // A replay's metadata, read when its first message arrives: `etp replay
    // publish` leaves the file before its first message, and the run's folder
    // that holds it may be gone by the time this recorder stops.
    let mut handed_over: Option<HandedOver> = None;
    // The replay hand-over this recorder has attached for.
    let mut attached_for: Option<observers::Token> = None;
    loop {
        if let Some(token) = observers::handover_token(run)
            && attached_for != Some(token)
        {
            // Every publisher of the replay exists once its hand-over does.
            for c in channels.iter() {
                c.drain
                    .attach()
                    .with_context(|| format!("attaching to the publishers of {}", c.topic))?;
            }
            observers::acknowledge(run, token).context("acknowledging the replay's hand-over")?;
            attached_for = Some(token);
        }
        let got = record_pass(w, channels)?;
        if got > 0 && handed_over.is_none() && cli.meta.is_none() {
            handed_over = Some(read_handed_over_metadata(run)?);
        }
        if last_flush.elapsed() >= FLUSH_EVERY {
            w.flush().context("flushing the recording")?;
            last_flush = Instant::now();
        }
        if stopping {
            if got == 0 {
                break;
            }
            // One more pass drains what arrived meanwhile.
            continue;
        }
        // SIGCONT after a pause resumes the wait; only SIGINT/SIGTERM stop.
        match waiter
            .wait(ports.node, FLUSH_EVERY)
            .context("waiting for messages")?
        {
            Wake::Notified { .. } | Wake::Silence => {}
            Wake::Terminate => stopping = true,
        }
        if std::os::unix::process::parent_id() != parent {
            stopping = true;
        }
    }
    Ok(handed_over)
}

/// One pass over the subscribers: what each holds, written to the file;
/// returns how many messages it wrote.
fn record_pass(w: &mut Writer, channels: &mut [Channel]) -> Result<usize> {
    let mut got = 0usize;
    // Every queue emptied first (copies), then encoded and written:
    // protobuf encoding is slower than a copy, and a publisher that
    // ends (a replay, the run's last messages) must not outrun it.
    for c in channels.iter_mut() {
        c.batch.clear();
        c.drain
            .take(&mut c.batch)
            .with_context(|| format!("receiving on {}", c.topic))?;
        c.received_at = now_ns();
    }
    for c in channels.iter_mut() {
        let t = c.received_at;
        for (sent, r) in &c.batch {
            let data = ENCODING
                .encode_recorded(r)
                .with_context(|| format!("encoding a message of {}", c.topic))?;
            w.write_to_known_channel(
                &MessageHeader {
                    channel_id: c.id,
                    sequence: c.count,
                    log_time: t,
                    // The sender's clock: on another host it may be
                    // ahead of this one; nothing is ordered by it.
                    publish_time: *sent,
                },
                &data,
            )
            .with_context(|| format!("writing a message of {}", c.topic))?;
            c.count = c.count.wrapping_add(1);
        }
        got += c.batch.len();
    }
    Ok(got)
}

/// Write a replay's metadata (without `--meta`), finish the file and
/// summarise it: `{"path", "messages", "counts", "bytes"}`.
fn finish_recording(
    cli: &Cli,
    run: &RunId,
    mut w: Writer,
    channels: &[Channel],
    handed_over: Option<HandedOver>,
) -> Result<serde_json::Value> {
    if cli.meta.is_none() {
        let records = match handed_over {
            Some(records) => records,
            None => read_handed_over_metadata(run)?,
        };
        for (name, metadata) in records {
            w.write_metadata(&Metadata { name, metadata })
                .context("writing metadata")?;
        }
    }
    let summary = w.finish().context("finishing the recording")?;
    drop(w);
    let counts: BTreeMap<String, u64> = channels
        .iter()
        .map(|c| (c.topic.clone(), u64::from(c.count)))
        .collect();
    let bytes = std::fs::metadata(&cli.out).map_or(0, |m| m.len());
    let messages = summary.stats.map_or(0, |s| s.message_count);
    tracing::info!(
        path = %cli.out.display(),
        messages,
        bytes,
        ?counts,
        "recording finished"
    );
    Ok(serde_json::json!({
        "path": cli.out.display().to_string(),
        "messages": messages,
        "counts": counts,
        "bytes": bytes,
    }))
}

/// Withdraws the recorder's announcement however it stops.
struct Announced<'a>(&'a RunId);

impl Drop for Announced<'_> {
    fn drop(&mut self) {
        observers::withdraw(self.0);
    }
}

/// Metadata records by name, as `etp replay publish` hands them over.
type HandedOver = BTreeMap<String, BTreeMap<String, String>>;

/// The metadata that `etp replay publish` left for this run (none if it left
/// none): a recorder started by hand without `--meta` on a replay's run id
/// makes a copy that carries the original's scenario, strategy and run
/// record, so it passes `etp replay verify`.
fn read_handed_over_metadata(run: &RunId) -> Result<HandedOver> {
    let path = recording::handover_path(run);
    let Ok(text) = std::fs::read_to_string(&path) else {
        return Ok(BTreeMap::new());
    };
    let mut records: HandedOver =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    // The copy's channels are this recorder's (the current format), whatever the
    // replayed file's format was.
    if let Some(run) = records.get_mut(recording::META_RUN)
        && run.contains_key("format_version")
    {
        run.insert(
            "format_version".into(),
            recording::FORMAT_VERSION.to_string(),
        );
    }
    tracing::info!(path = %path.display(), records = records.len(), "metadata of the replay");
    Ok(records)
}

/// The recorder process, as the process shell runs it (`main` of
/// `etp-recorder`, and `etp process etp-recorder`); its summary JSON is its
/// line on stdout (a closed stdout is not an error: the file is finished all
/// the same).
pub struct RecorderProcess;

impl shell::Process for RecorderProcess {
    const NAME: &'static str = "etp-recorder";
    type Args = Cli;
    fn parse(argv: Vec<std::ffi::OsString>) -> Self::Args {
        clap::Parser::parse_from(argv)
    }
    type Error = anyhow::Error;
    fn body(cli: &Cli) -> anyhow::Result<Done> {
        let file = create_output(&cli.out)?;
        let mut ready = false;
        let r = run(cli, file, &mut ready);
        if r.is_err() && !ready {
            // Nothing was recorded: remove the file this process created (and
            // only it: create_new guarantees it is ours).
            let _ = std::fs::remove_file(&cli.out);
        }
        r.map(|v| Done::Line {
            text: v.to_string(),
            required: false,
        })
    }
}
