//! `etp run --record`: the recorder process (`etp-recorder`), started before
//! the others and stopped (SIGTERM: it drains, calls `finish()` and reports
//! its counts) after they ended.
//!
//! Nothing is replaced before the run that replaces it succeeded. The
//! recorder writes a new file beside the target, `<target>.<run-id>.partial`
//! (created exclusively by the recorder, before any other process of the run
//! starts); [`Target::commit`] moves it onto the target at the end:
//!
//! * a run that fails before it ran (bad arguments, a remote join that timed
//!   out, no report) removes its partial file: the target is untouched;
//! * a finished recording replaces the target only if the target is still
//!   what it was when the run started — absent (then it is linked into
//!   place without replacing: `link(2)` fails on an existing name), or the
//!   same file (device and inode) that `--force` allowed to replace. A
//!   target created, replaced or removed during the run (another run
//!   recording to the same path, typically) is left alone; this run's
//!   recording stays at its partial name, and the run says so and exits 4;
//! * an unfinished recording (the recorder died) never replaces an existing
//!   target (it stays at its partial name, for `etp replay repair`); with
//!   no target it is moved into place as before;
//! * the partial file itself must still be the file the recorder created: a
//!   partial file removed or replaced during the run is reported (exit 4).
//!
//! Left open: between the identity check and `rename(2)` of a `--force`
//! replacement another writer may still slip in (Linux has no "rename if
//! the target is inode N"); the window is microseconds, not the run's length.

use super::prepare::Plan;
use super::process::{ProcessExit, sibling_binary, signal, status_text};
use crate::error::{Context, Error, IoContext, Result};
use etp_runtime::recording;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncReadExt, BufReader};
use tokio::process::ChildStdout;

/// How long the recorder gets to subscribe, and to finish after SIGTERM.
const READY_TIMEOUT: Duration = Duration::from_secs(30);
const FINISH_TIMEOUT: Duration = Duration::from_secs(30);

/// What the recorder reported.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Recording {
    /// Where the recording is at the end: the target, or the partial file
    /// when it could not replace the target (see [`Target::commit`]).
    pub path: PathBuf,
    /// Messages recorded per channel (empty when the recorder did not finish).
    pub counts: BTreeMap<String, u64>,
    pub bytes: u64,
    /// False when the recorder died (the file is unfinished: see `etp replay repair`).
    pub finished: bool,
    /// The file the recorder created (identity taken once it was ready).
    #[serde(skip)]
    file: Option<FileId>,
    /// Why the recording is not at its target (set by [`Target::commit`]).
    #[serde(skip)]
    pub problem: Option<String>,
}

/// A file's identity: "the same file", not "a file at the same path".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FileId {
    dev: u64,
    ino: u64,
}

/// The identity of what is at `path` (not following a symlink); `None`
/// when nothing is.
fn file_id(path: &Path) -> std::io::Result<Option<FileId>> {
    use std::os::unix::fs::MetadataExt;
    match std::fs::symlink_metadata(path) {
        Ok(m) => Ok(Some(FileId {
            dev: m.dev(),
            ino: m.ino(),
        })),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

/// Where a run's recording goes: recorded to [`Target::partial`] beside
/// [`Target::path`], moved onto it by [`Target::commit`] (module doc).
#[derive(Debug)]
pub struct Target {
    pub path: PathBuf,
    pub partial: PathBuf,
    /// What was at `path` when the run claimed it.
    before: Option<FileId>,
}

impl Target {
    /// Claim `path` for run `run_id` (before anything of the run starts): a
    /// folder is refused by name, with or without `force`; an existing file
    /// is refused unless `force`, and nothing is removed.
    pub fn claim(path: &Path, force: bool, run_id: &str) -> Result<Self> {
        if path.is_dir() {
            return Err(Error::RecordIsFolder(path.to_path_buf()));
        }
        etp_files::write::refuse_existing(path, force)?;
        let before = file_id(path).doing(|| format!("--record {}", path.display()))?;
        let name = path
            .file_name()
            .ok_or_else(|| Error::RecordNotAFile(path.to_path_buf()))?;
        let partial = path.with_file_name(format!("{}.{run_id}.partial", name.to_string_lossy()));
        // Left by a killed run of the same id: its recording, never ours to
        // remove (so that [`Target::abandon`] removes only what this run made).
        if partial.symlink_metadata().is_ok() {
            return Err(Error::PartialExists {
                partial,
                run_id: run_id.to_string(),
            });
        }
        Ok(Self {
            path: path.to_path_buf(),
            partial,
            before,
        })
    }

    /// The run failed before it ran: remove the partial file (the target
    /// was never touched).
    pub fn abandon(&self) {
        match std::fs::remove_file(&self.partial) {
            Ok(()) => tracing::info!("removed {} (the run failed)", self.partial.display()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => tracing::warn!("cannot remove {}: {e}", self.partial.display()),
        }
    }

    /// The run ran: move its recording onto the target by the rules of the
    /// module doc. `rec.path` becomes where the recording is; `rec.problem`
    /// says why it is not at the target (the run then exits 4).
    pub fn commit(&self, rec: &mut Recording) {
        rec.path = self.partial.clone();
        rec.problem = self.move_into_place(rec).err();
        if rec.problem.is_none() {
            rec.path = self.path.clone();
        }
    }

    fn move_into_place(&self, rec: &Recording) -> std::result::Result<(), String> {
        let (target, partial) = (self.path.display(), self.partial.display());
        let now = file_id(&self.partial).map_err(|e| format!("recording {partial}: {e}"))?;
        match now {
            None => {
                return Err(format!(
                    "the recording {partial} was removed during the run (by another process); \
                     nothing of this run is recorded, {target} was not touched"
                ));
            }
            Some(id) if rec.file.is_some_and(|f| f != id) => {
                return Err(format!(
                    "the recording {partial} was replaced by another file during the run; \
                     it is not this run's recording and was not moved to {target}"
                ));
            }
            Some(_) => {}
        }
        if !rec.finished && self.before.is_some() {
            return Err(format!(
                "the recording did not finish: the existing {target} was kept; the unfinished \
                 recording is {partial} (see etp replay repair)"
            ));
        }
        let kept = format!("this run's recording is kept at {partial}");
        let target_now = file_id(&self.path).map_err(|e| format!("{target}: {e}; {kept}"))?;
        match (self.before, target_now) {
            (None, None) => {
                // link(2) never replaces: a file created since the check
                // above still wins, and this run says so.
                match std::fs::hard_link(&self.partial, &self.path) {
                    Ok(()) => {}
                    Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                        return Err(format!(
                            "{target} already exists: it was created during this run by another \
                             writer (another run recording to it?) and was not overwritten; {kept}"
                        ));
                    }
                    Err(e) => return Err(format!("linking {partial} to {target}: {e}; {kept}")),
                }
                std::fs::remove_file(&self.partial)
                    .map_err(|e| format!("removing {partial} after linking it to {target}: {e}"))
            }
            (None, Some(_)) => Err(format!(
                "{target} already exists: it was created during this run by another writer \
                 (another run recording to it?) and was not overwritten; {kept}"
            )),
            (Some(was), Some(is)) if was == is => std::fs::rename(&self.partial, &self.path)
                .map_err(|e| format!("replacing {target} by {partial}: {e}; {kept}")),
            (Some(_), _) => Err(format!(
                "{target} was replaced or removed during this run by another writer (another \
                 run recording to it with --force?) and was not overwritten; {kept}"
            )),
        }
    }
}

/// The default file: `recordings/<scenario>-<run-id>.mcap`.
pub fn default_path(plan: &Plan) -> PathBuf {
    let name: String = plan
        .scenario
        .name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    PathBuf::from("recordings").join(format!("{name}-{}.mcap", plan.run_id))
}

/// The metadata records of a run's recording.
fn metadata(plan: &Plan) -> Result<BTreeMap<String, BTreeMap<String, String>>> {
    let scenario = std::fs::read_to_string(&plan.scenario_path)
        .doing(|| format!("reading {}", plan.scenario_path.display()))?;
    let strategy = std::fs::read_to_string(&plan.strategy_path)
        .doing(|| format!("reading {}", plan.strategy_path.display()))?;
    let prediction = serde_json::json!({
        "sensor_energy_per_episode": plan.sensor_energy_per_episode,
        "sensors": plan.scenario.sensors.iter().map(|s| s.name.clone()).collect::<Vec<_>>(),
        "predict_episodes": plan.predict_episodes,
        "from": prediction_source(plan),
    });
    let one = |k: &str, v: String| BTreeMap::from([(k.to_string(), v)]);
    Ok(BTreeMap::from([
        (
            recording::META_RUN.to_string(),
            BTreeMap::from([
                (
                    "format_version".into(),
                    recording::FORMAT_VERSION.to_string(),
                ),
                (
                    "software_version".into(),
                    format!("etp {}", env!("CARGO_PKG_VERSION")),
                ),
                ("run_id".into(), plan.run_id.to_string()),
                ("seed".into(), plan.seed.to_string()),
                ("episodes".into(), plan.episodes.to_string()),
                // The channel monitor's rate: with the scenario and the
                // episodes, what `replay verify` raises its flags again from.
                (
                    "drift_false_alarm".into(),
                    plan.drift.false_alarm.to_string(),
                ),
                ("scenario_name".into(), plan.scenario.name.clone()),
                (
                    recording::META_RUN_SCENARIO_HASH.into(),
                    plan.scenario.content_hash.clone(),
                ),
            ]),
        ),
        (recording::META_SCENARIO.into(), one("toml", scenario)),
        (recording::META_STRATEGY.into(), one("json", strategy)),
        (
            recording::META_PREDICTION.into(),
            one("json", prediction.to_string()),
        ),
        (
            recording::META_CONFIG.into(),
            one("toml", plan.config_toml.clone()),
        ),
    ])
    .into_iter()
    .chain((!plan.channel_schedule.is_empty()).then(|| {
        let names: Vec<String> = plan
            .scenario
            .sensors
            .iter()
            .map(|s| s.name.clone())
            .collect();
        (
            recording::META_CHANNEL_SCHEDULE.to_string(),
            one("toml", plan.channel_schedule.to_toml(&names)),
        )
    }))
    .collect())
}

/// Where the per-sensor predicted energy comes from (report and recording).
pub fn prediction_source(plan: &Plan) -> String {
    plan.prediction_from.clone()
}

/// A started recorder.
pub struct Recorder {
    path: PathBuf,
    pid: u32,
    file: Option<FileId>,
    stdout: BufReader<ChildStdout>,
    waiter: tokio::task::JoinHandle<Option<std::process::ExitStatus>>,
    stopping: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// Spawn the recorder and wait until it subscribed to every service.
pub async fn start(plan: &Plan, out: &Path) -> Result<Recorder> {
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).doing(|| format!("creating {}", dir.display()))?;
    }
    let meta = plan.dir.join("recording-meta.json");
    std::fs::write(&meta, serde_json::to_string(&metadata(plan)?)?)
        .doing(|| format!("writing {}", meta.display()))?;
    let bin = sibling_binary("etp-recorder")?;
    let mut child = bin
        .command(&[
            "--run-id".to_string(),
            plan.run_id.to_string(),
            "--scenario".into(),
            plan.scenario_path.display().to_string(),
            "--out".into(),
            out.display().to_string(),
            "--meta".into(),
            meta.display().to_string(),
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .kill_on_drop(true)
        .spawn()
        .in_process(|| format!("spawning {}", bin.display()))?;
    let pid = child.id().unwrap_or(0);
    let mut stdout = BufReader::new(
        child
            .stdout
            .take()
            .ok_or_else(|| Error::process("recorder stdout"))?,
    );
    let mut line = String::new();
    let ready = tokio::time::timeout(READY_TIMEOUT, stdout.read_line(&mut line)).await;
    if !matches!(ready, Ok(Ok(n)) if n > 0 && line.trim() == "ready") {
        // EOF: the recorder exited (its error is on stderr); else stop it.
        let status = match ready {
            Ok(Ok(0)) => child.wait().await.ok(),
            _ => {
                let _ = child.kill().await;
                None
            }
        };
        return Err(Error::process(format!(
            "cannot record to {}: the recorder did not start ({}; its error is above); \
             nothing of the run was started",
            out.display(),
            status.map_or_else(|| "killed".to_string(), |st| status_text(&st))
        )));
    }
    // The recorder created `out` exclusively; remember which file that is.
    let file = file_id(out).ok().flatten();
    let stopping = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = stopping.clone();
    let cfg = etp_runtime::wire::config(&plan.run_id)?;
    // If the recorder dies during the run, its ports are removed at once so
    // that publishers waiting on its full buffers go on.
    let waiter = tokio::spawn(async move {
        let st = child.wait().await.ok();
        if !flag.load(std::sync::atomic::Ordering::SeqCst) {
            eprintln!("etp run: the recorder died ({st:?}); the run goes on unrecorded");
            etp_runtime::wire::remove_dead_nodes(&cfg);
        }
        st
    });
    Ok(Recorder {
        path: out.to_path_buf(),
        pid,
        file,
        stdout,
        waiter,
        stopping,
    })
}

impl Recorder {
    /// Stop the recorder (SIGTERM), wait for its report.
    pub async fn stop(mut self) -> Result<(Recording, ProcessExit)> {
        self.stopping
            .store(true, std::sync::atomic::Ordering::SeqCst);
        signal(self.pid, "-TERM");
        let mut out = String::new();
        let read = tokio::time::timeout(FINISH_TIMEOUT, self.stdout.read_to_string(&mut out)).await;
        let status = match tokio::time::timeout(FINISH_TIMEOUT, &mut self.waiter).await {
            Ok(Ok(Some(st))) => status_text(&st),
            _ => {
                signal(self.pid, "-KILL");
                "killed by supervisor".to_string()
            }
        };
        let exit = ProcessExit {
            name: "recorder".into(),
            pid: self.pid,
            status,
        };
        let bytes = std::fs::metadata(&self.path).map_or(0, |m| m.len());
        let parsed: Option<serde_json::Value> = match read {
            Ok(Ok(_)) => serde_json::from_str(out.trim()).ok(),
            _ => None,
        };
        let counts = parsed
            .as_ref()
            .and_then(|v| v.get("counts"))
            .map(|c| serde_json::from_value(c.clone()))
            .transpose()
            .map_err(|e| Error::process(format!("recorder report: {e}")))?;
        Ok((
            Recording {
                path: self.path,
                finished: counts.is_some(),
                counts: counts.unwrap_or_default(),
                bytes,
                file: self.file,
                problem: None,
            },
            exit,
        ))
    }
}
