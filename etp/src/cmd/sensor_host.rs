//! `etp sensor-host --connect tcp/ADDR:PORT [--sensor s0 …]`: this host's
//! part of a run across hosts. Its bridge (`etp-bridge sensor-host`) fetches
//! the run from the agent host (scenario, seed, which sensors are remote:
//! nothing is copied by hand) and carries the sensors' services; then the
//! sensor processes start here, in an iceoryx2 domain of their own (so a
//! sensor host beside `etp run` on one machine never mixes with it). The
//! command ends when its sensors end (the run's STOP) or when the agent host
//! is gone (the bridge says so; the sensors see their coordinator vanish),
//! and removes every file it made.

use anyhow::{Context, Result, bail};
use etp_launcher::process::{ProcessExit, sibling_binary, signal, spawn_env, status_text};
use etp_runtime::cleanup;
use etp_runtime::wire::{IPC_DOMAIN_ENV, RunId};
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, BufReader};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The agent host's endpoint (its `etp run --listen`), e.g. `tls/10.0.0.1:7447`.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: String,
    /// Sensors to serve here (names; repeat; default: every remote sensor of the run).
    #[arg(long = "sensor", value_name = "NAME")]
    pub sensors: Vec<String>,
    /// Seconds to wait for the agent host to answer (> 0).
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0, value_parser = crate::values::seconds)]
    pub join_timeout: f64,
    /// Print one JSON object at the end.
    #[arg(long)]
    pub json: bool,
    /// The link's protection.
    #[command(flatten)]
    pub link: crate::run_args::LinkArgs,
    /// This host's name in the key folder (`etp certs init --sensor-host NAME`).
    #[arg(long, value_name = "NAME", requires = "tls", default_value = etp_runtime::link_keys::DEFAULT_SENSOR_HOST)]
    pub name: String,
}

/// How long the sensors get to exit once the bridge has ended.
const GRACE: Duration = Duration::from_secs(5);

pub fn run(a: Args) -> Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let domain = format!("h{}", std::process::id());
    let dir = etp_files::folders::private("sensor-host")?.join(&domain);
    let r = rt.block_on(serve(&a, &domain, &dir));
    let _ = std::fs::remove_dir_all(&dir);
    let (summary, ok) = r?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "sensor host · run {} · sensors {}",
            summary["run_id"].as_str().unwrap_or("?"),
            summary["sensors"]
        );
        for p in summary["processes"].as_array().into_iter().flatten() {
            println!(
                "  {:<12} {}",
                p["name"].as_str().unwrap_or("?"),
                p["status"]
            );
        }
        println!("  traffic carried: {}", summary["traffic"]);
    }
    if !ok {
        bail!("a process of this sensor host failed (see above)");
    }
    Ok(())
}

async fn serve(a: &Args, domain: &str, dir: &std::path::Path) -> Result<(serde_json::Value, bool)> {
    let env = [(IPC_DOMAIN_ENV, domain)];
    let mut args = vec![
        "sensor-host".to_string(),
        "--connect".into(),
        a.connect.clone(),
        "--dir".into(),
        dir.display().to_string(),
        "--join-timeout".into(),
        a.join_timeout.to_string(),
    ];
    for s in &a.sensors {
        args.extend(["--sensor".to_string(), s.clone()]);
    }
    args.extend(a.link.protection().bridge_args(&a.connect, &a.name)?);
    if a.link.tls.is_some() {
        args.extend(["--name".to_string(), a.name.clone()]);
    }
    let bin = sibling_binary("etp-bridge")?;
    let mut bridge = spawn_env(&bin, &args, true, &env)?;
    let bridge_pid = bridge.id().unwrap_or(0);
    let mut lines = BufReader::new(bridge.stdout.take().context("bridge stdout")?).lines();
    let joined = loop {
        match lines.next_line().await.context("reading the bridge")? {
            Some(l) => {
                let v: serde_json::Value = serde_json::from_str(&l).unwrap_or_default();
                if v["event"] == "joined" {
                    break v;
                }
            }
            None => {
                let st = bridge.wait().await.context("waiting for the bridge")?;
                bail!(
                    "could not join ({}; the bridge's error is above)",
                    status_text(&st)
                );
            }
        }
    };
    let run_id = joined["run_id"].as_str().unwrap_or_default().to_string();
    eprintln!(
        "etp sensor-host: joined run {run_id} at {}: serving {}",
        a.connect, joined["sensors"]
    );
    let sensor_bin = sibling_binary("etp-sensor-node")?;
    let mut children = Vec::new();
    for name in joined["sensors"].as_array().into_iter().flatten() {
        let name = name.as_str().unwrap_or_default().to_string();
        let mut args = vec![
            "--run-id".to_string(),
            run_id.clone(),
            "--scenario".into(),
            joined["scenario"].as_str().unwrap_or_default().to_string(),
            "--sensor".into(),
            name.clone(),
            "--seed".into(),
            joined["seed"].as_u64().unwrap_or(0).to_string(),
        ];
        if let Some(schedule) = joined["channel_schedule"].as_str() {
            args.extend(["--channel-schedule".into(), schedule.to_string()]);
        }
        children.push((
            format!("sensor {name}"),
            spawn_env(&sensor_bin, &args, false, &env)?,
        ));
    }
    // Until the sensors end (the run's STOP) or the bridge does (agent host
    // gone, or a signal).
    let mut tail = BridgeTail::default();
    let mut sigterm = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .context("installing the SIGTERM handler")?;
    let all_sensors = async {
        for (_, c) in children.iter_mut() {
            let _ = c.wait().await;
        }
    };
    let bridge_lines = async {
        while let Ok(Some(l)) = lines.next_line().await {
            if tail.note(&l) == "agent-host-gone" {
                eprintln!("etp sensor-host: the agent host is gone");
            }
        }
    };
    tokio::select! {
        () = all_sensors => {}
        () = bridge_lines => {}
        _ = tokio::signal::ctrl_c() => {}
        _ = sigterm.recv() => {}
    }
    for (_, c) in &children {
        if let Some(pid) = c.id() {
            signal(pid, "-TERM");
        }
    }
    let mut processes = Vec::new();
    let grace_end = tokio::time::Instant::now() + GRACE;
    let mut ok = true;
    for (name, mut c) in children {
        let pid = c.id().unwrap_or(0);
        let status = match tokio::time::timeout_at(grace_end, c.wait()).await {
            Ok(Ok(st)) => status_text(&st),
            _ => {
                let _ = c.kill().await;
                "killed by supervisor".into()
            }
        };
        ok &= status == "exit 0";
        processes.push(ProcessExit { name, pid, status });
    }
    signal(bridge_pid, "-TERM");
    let rest = async {
        while let Ok(Some(l)) = lines.next_line().await {
            tail.note(&l);
        }
    };
    let _ = tokio::time::timeout(GRACE, rest).await;
    let status = match tokio::time::timeout(GRACE, bridge.wait()).await {
        Ok(Ok(st)) => status_text(&st),
        _ => {
            let _ = bridge.kill().await;
            "killed by supervisor".into()
        }
    };
    ok &= status == "exit 0";
    processes.push(ProcessExit {
        name: "bridge".into(),
        pid: bridge_pid,
        status,
    });
    if let Ok(run) = RunId::in_domain(&run_id, Some(domain)) {
        cleanup::remove_run(&run);
    }
    // What the agent host's side sent that this host refused (garbage,
    // another run's, a sender that may not send it): a fault of the link.
    let BridgeTail {
        traffic,
        refused,
        stalled,
    } = tail;
    let refused_any = refused
        .as_object()
        .is_some_and(|m| m.values().any(|n| n.as_u64() != Some(0)));
    if refused_any {
        eprintln!("etp sensor-host: the link refused messages: {refused}");
        ok = false;
    }
    Ok((
        serde_json::json!({
            "run_id": run_id,
            "connect": a.connect,
            "sensors": joined["sensors"],
            "processes": processes,
            "traffic": traffic,
            "refused": refused,
            "stalled": stalled,
        }),
        ok,
    ))
}

/// What the bridge's last lines say (`traffic`, `refused`, `stalled`).
struct BridgeTail {
    traffic: serde_json::Value,
    refused: serde_json::Value,
    stalled: serde_json::Value,
}

impl Default for BridgeTail {
    fn default() -> Self {
        Self {
            traffic: serde_json::Value::Null,
            refused: serde_json::json!({}),
            stalled: serde_json::json!({}),
        }
    }
}

impl BridgeTail {
    /// Take one line of the bridge; its event's name (empty if none).
    fn note(&mut self, line: &str) -> String {
        let v: serde_json::Value = serde_json::from_str(line).unwrap_or_default();
        match v["event"].as_str() {
            Some("traffic") => self.traffic = v["sensors"].clone(),
            Some("refused") => self.refused = v["counts"].clone(),
            Some("stalled") => self.stalled = v["sensors"].clone(),
            _ => {}
        }
        v["event"].as_str().unwrap_or_default().to_string()
    }
}
