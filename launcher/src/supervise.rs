//! Spawning and supervising the run's processes with tokio.

use super::interrupts::Interrupts;
use super::prepare::Plan;
use super::process::{ProcessExit, sibling_binary, signal, spawn, status_text};
use crate::error::{Context, Error, Result};
use etp_runtime::report::RunReport;
use std::path::Path;
use std::time::{Duration, Instant};
use tokio::io::AsyncReadExt;
use tokio::process::Child;

/// How long the agent and sensors get to exit after the coordinator ended.
const GRACE: Duration = Duration::from_secs(2);
/// After SIGINT/SIGTERM: how long the coordinator gets to stop the episodes,
/// collect the ledgers of the complete ones and report.
const STOP_GRACE: Duration = Duration::from_secs(15);

/// What the supervisor saw.
#[derive(Debug)]
pub struct Supervised {
    pub report: RunReport,
    pub processes: Vec<ProcessExit>,
    pub wall_seconds: f64,
    /// `--record`: what the recorder wrote.
    pub recording: Option<super::record::Recording>,
    /// SIGINT/SIGTERM stopped the run early (the report covers the
    /// complete episodes).
    pub interrupted: bool,
    /// `--listen`/`--remote`: what the link to the remote sensors carried.
    pub link: Option<super::remote::LinkReport>,
}

/// What a run has besides its processes: where it records, its remote
/// sensors, its live view.
pub struct Attached<'a> {
    /// The recording's partial file (`--record`).
    pub record: Option<&'a Path>,
    /// `--listen`/`--remote`.
    pub remote: Option<&'a super::remote::RemoteSpec>,
    /// The live view's feed socket (`--live`).
    pub live_feed: Option<&'a Path>,
}

pub async fn supervise(
    interrupts: &mut Interrupts,
    plan: &Plan,
    deadline: Duration,
    slot_deadline_ms: Option<u64>,
    attached: Attached<'_>,
    quiet: bool,
) -> Result<Supervised> {
    let Attached {
        record,
        remote,
        live_feed,
    } = attached;
    let started = Instant::now();
    // The recorder first: every subscriber exists before anything is sent.
    let recorder = match record {
        Some(out) => Some(super::record::start(plan, out).await?),
        None => None,
    };
    // Then the bridge of the remote sensors: it returns once they joined.
    let bridge = match remote {
        Some(spec) => match super::remote::start(plan, spec, interrupts).await {
            Ok(b) => Some(b),
            Err(e) => {
                // Nothing ran: the recording, if any, is abandoned.
                if let Some(r) = recorder {
                    let _ = r.stop().await;
                }
                return Err(e);
            }
        },
        None => None,
    };
    let Spawned {
        children,
        mut coordinator,
        progress_file,
    } = spawn_processes(plan, remote, slot_deadline_ms, live_feed)?;
    let run = plan.run_id.as_str().to_string();
    // Episodes finished, from the coordinator's progress file.
    let pb = etp_runtime::progress::bar(plan.episodes, "run", quiet);
    let shown = pb.clone();
    let progress = tokio::spawn(async move {
        loop {
            tokio::time::sleep(Duration::from_millis(200)).await;
            // A few bytes from the page cache: a blocking read is fine here.
            if let Some(n) = std::fs::read_to_string(&progress_file)
                .ok()
                .and_then(|t| t.trim().parse::<u64>().ok())
            {
                shown.set_position(n);
            }
        }
    });
    let coord_pid = coordinator.id().unwrap_or(0);
    let mut stdout = coordinator
        .stdout
        .take()
        .ok_or_else(|| Error::process("coordinator stdout"))?;
    let reader = tokio::spawn(async move {
        let mut s = String::new();
        stdout.read_to_string(&mut s).await.map(|_| s)
    });

    let mut failure: Option<String> = None;
    let mut interrupted: Option<&'static str> = None;
    let coord_status = tokio::select! {
        st = coordinator.wait() => Some(st.in_process(|| "waiting for the coordinator")?),
        name = interrupts.next() => {
            failure = Some(format!("interrupted ({name})"));
            interrupted = Some(name);
            tracing::warn!("{name}: stopping the run after the complete episodes");
            // SIGTERM = Ctrl-C: the coordinator stops the episodes, collects
            // the ledgers of the complete ones and still reports.
            signal(coord_pid, "-INT");
            tokio::time::timeout(STOP_GRACE, coordinator.wait()).await.ok().and_then(Result::ok)
        }
        _ = tokio::time::sleep(deadline) => {
            failure = Some(format!("deadline of {:.0} s passed", deadline.as_secs_f64()));
            None
        }
    };
    progress.abort();
    pb.finish_and_clear();
    let mut processes = reap(coordinator, coord_pid, coord_status, children).await;
    let link = match bridge {
        Some(b) => {
            let (exit, report) = b.stop().await;
            processes.push(exit);
            Some(report)
        }
        None => None,
    };
    let recording = match recorder {
        Some(r) => {
            let (rec, exit) = r.stop().await?;
            processes.push(exit);
            Some(rec)
        }
        None => None,
    };
    let out = tokio::time::timeout(GRACE, reader)
        .await
        .map_err(|_| Error::process("coordinator output not closed"))?
        .in_process(|| "reading coordinator output")?
        .in_process(|| "reading coordinator output")?;
    if let Some(name) = interrupted
        && out.trim().is_empty()
    {
        // The coordinator was stopped before it could report (a signal in
        // its first moments ends it): no episode ran.
        return Err(super::interrupts::before_any_episode(
            name,
            "while the run's processes started",
        ));
    }
    if let Some(f) = failure
        && out.trim().is_empty()
    {
        return Err(Error::process(format!(
            "run {run}: {f}; processes: {}",
            summary(&processes)
        )));
    }
    let report: RunReport = serde_json::from_str(out.trim()).map_err(|e| {
        Error::process(format!(
            "run {run}: the coordinator gave no report ({e}); processes: {}",
            summary(&processes)
        ))
    })?;
    Ok(Supervised {
        report,
        processes,
        wall_seconds: started.elapsed().as_secs_f64(),
        recording,
        interrupted: interrupted.is_some(),
        link,
    })
}

fn summary(p: &[ProcessExit]) -> String {
    p.iter()
        .map(|x| format!("{} {}", x.name, x.status))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The run's local processes.
struct Spawned {
    /// The sensors' and the agent's, named.
    children: Vec<(String, Child)>,
    coordinator: Child,
    /// Where the coordinator counts the episodes finished.
    progress_file: std::path::PathBuf,
}

/// The run's local processes, spawned: each local sensor and the agent
/// first (the coordinator waits for their hello), then the coordinator;
/// with the coordinator's progress file.
fn spawn_processes(
    plan: &Plan,
    remote: Option<&super::remote::RemoteSpec>,
    slot_deadline_ms: Option<u64>,
    live_feed: Option<&Path>,
) -> Result<Spawned> {
    let run = plan.run_id.as_str().to_string();
    let scenario = plan.scenario_path.display().to_string();
    let common = |extra: &[String]| -> Vec<String> {
        let mut v = vec![
            "--run-id".to_string(),
            run.clone(),
            "--scenario".to_string(),
            scenario.clone(),
        ];
        v.extend_from_slice(extra);
        v
    };
    // Sensors and agent first: the coordinator waits for their hello.
    let mut children: Vec<(String, Child)> = Vec::new();
    let sensor_bin = sibling_binary("etp-sensor-node")?;
    for (i, s) in plan.scenario.sensors.iter().enumerate() {
        if remote.is_some_and(|r| r.remote.contains(&i)) {
            continue;
        }
        let mut extra = vec![
            "--sensor".into(),
            s.name.clone(),
            "--seed".into(),
            plan.seed.to_string(),
        ];
        if let Some(p) = &plan.channel_schedule_path {
            extra.extend(["--channel-schedule".into(), p.display().to_string()]);
        }
        let args = common(&extra);
        children.push((
            format!("sensor {}", s.name),
            spawn(&sensor_bin, &args, false)?,
        ));
    }
    // The monitor's horizon is the run's episodes; its model, the run's
    // scenario text (the channel the prediction is for).
    let mut agent_extra = vec![
        "--episodes".to_string(),
        plan.episodes.to_string(),
        "--drift-false-alarm".to_string(),
        plan.drift.false_alarm.to_string(),
    ];
    if let Some(ms) = slot_deadline_ms {
        agent_extra.extend(["--slot-deadline".to_string(), ms.to_string()]);
    }
    if let Some(feed) = live_feed {
        agent_extra.extend(["--live-feed".to_string(), feed.display().to_string()]);
    }
    let agent_args = common(&agent_extra);
    children.push((
        "agent".into(),
        spawn(&sibling_binary("etp-agent")?, &agent_args, false)?,
    ));
    let progress_file = plan.dir.join("progress");
    let coord_args = common(&[
        "--strategy".into(),
        plan.strategy_path.display().to_string(),
        "--episodes".into(),
        plan.episodes.to_string(),
        "--seed".into(),
        plan.seed.to_string(),
        "--progress".into(),
        progress_file.display().to_string(),
        "--on-drift".into(),
        plan.drift.on_drift.name().into(),
    ]);
    let coordinator = spawn(&sibling_binary("etp-coordinator")?, &coord_args, true)?;
    Ok(Spawned {
        children,
        coordinator,
        progress_file,
    })
}

/// Every process's exit: the coordinator's (killed if it did not end),
/// then the others', each within [`GRACE`] (asked to terminate first when
/// the coordinator did not exit 0).
async fn reap(
    mut coordinator: Child,
    coord_pid: u32,
    coord_status: Option<std::process::ExitStatus>,
    children: Vec<(String, Child)>,
) -> Vec<ProcessExit> {
    let mut processes = Vec::new();
    match coord_status {
        Some(st) => processes.push(ProcessExit {
            name: "coordinator".into(),
            pid: coord_pid,
            status: status_text(&st),
        }),
        None => {
            let _ = coordinator.kill().await;
            processes.push(ProcessExit {
                name: "coordinator".into(),
                pid: coord_pid,
                status: "killed by supervisor".into(),
            });
        }
    }
    // The others exit on the coordinator's stop. If it did not end cleanly,
    // ask them to terminate now (they also notice its death by themselves).
    if processes.first().is_none_or(|p| p.status != "exit 0") {
        for (_, child) in &children {
            if let Some(pid) = child.id() {
                signal(pid, "-TERM");
            }
        }
    }
    let grace_end = tokio::time::Instant::now() + GRACE;
    for (name, mut child) in children {
        let pid = child.id().unwrap_or(0);
        let status = match tokio::time::timeout_at(grace_end, child.wait()).await {
            Ok(Ok(st)) => status_text(&st),
            _ => {
                let _ = child.kill().await;
                "killed by supervisor".into()
            }
        };
        processes.push(ProcessExit { name, pid, status });
    }
    processes
}
