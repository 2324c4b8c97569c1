//! `etp run --record`: the recorder process (`etp-recorder`), started before
//! the others and stopped (SIGTERM: it drains, calls `finish()` and reports
//! its counts) after they ended.
//!
//! The output file is created exclusively by the recorder itself
//! (`create_new`), before any other process of the run starts: of two runs
//! recording to one path at once, the second's recorder cannot create it and
//! that run fails before starting anything, leaving the first's file alone.
//! [`claim`] is only the early, friendly check (and `--force`'s removal).

use super::prepare::Plan;
use super::process::{ProcessExit, sibling_binary, signal, status_text};
use anyhow::{Context, Result, anyhow, bail};
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
    pub path: PathBuf,
    /// Messages recorded per channel (empty when the recorder did not finish).
    pub counts: BTreeMap<String, u64>,
    pub bytes: u64,
    /// False when the recorder died (the file is unfinished: see `etp replay --repair`).
    pub finished: bool,
}

/// The early check of `--record PATH` (before the run is prepared): an
/// existing file is refused unless `force`, which removes it now so that the
/// recorder can create it exclusively. Not the guarantee: another run may
/// create the file after this check; the recorder's `create_new` refuses then.
pub fn claim(path: &Path, force: bool) -> Result<()> {
    crate::output::refuse_existing(path, force)?;
    if force {
        match std::fs::remove_file(path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                return Err(e).with_context(|| format!("--force: removing {}", path.display()));
            }
        }
    }
    Ok(())
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
        .with_context(|| format!("reading {}", plan.scenario_path.display()))?;
    let strategy = std::fs::read_to_string(&plan.strategy_path)
        .with_context(|| format!("reading {}", plan.strategy_path.display()))?;
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
    ]))
}

/// Where the per-sensor predicted energy comes from (report and recording).
pub fn prediction_source(plan: &Plan) -> String {
    plan.prediction_from.clone()
}

/// A started recorder.
pub struct Recorder {
    path: PathBuf,
    pid: u32,
    stdout: BufReader<ChildStdout>,
    waiter: tokio::task::JoinHandle<Option<std::process::ExitStatus>>,
    stopping: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// Spawn the recorder and wait until it subscribed to every service.
pub async fn start(plan: &Plan, out: &Path) -> Result<Recorder> {
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let meta = plan.dir.join("recording-meta.json");
    std::fs::write(&meta, serde_json::to_string(&metadata(plan)?)?)
        .with_context(|| format!("writing {}", meta.display()))?;
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
        .with_context(|| format!("spawning {}", bin.display()))?;
    let pid = child.id().unwrap_or(0);
    let mut stdout = BufReader::new(child.stdout.take().context("recorder stdout")?);
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
        bail!(
            "cannot record to {}: the recorder did not start ({}; its error is above); \
             nothing of the run was started",
            out.display(),
            status.map_or_else(|| "killed".to_string(), |st| status_text(&st))
        );
    }
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
            .map_err(|e| anyhow!("recorder report: {e}"))?;
        Ok((
            Recording {
                path: self.path,
                finished: counts.is_some(),
                counts: counts.unwrap_or_default(),
                bytes,
            },
            exit,
        ))
    }
}
