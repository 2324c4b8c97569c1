//! `etp run --listen EP --remote s0,s3`: the agent host's bridge
//! (`etp-bridge agent-host`, a process of its own so that `etp` itself does
//! not link Zenoh). It is started after the recorder and before everyone
//! else, answers joining sensor hosts with the run's description, and says
//! `ready` once every remote sensor has joined (bounded by
//! `--join-timeout`); its last line is the traffic it carried per sensor.

use super::prepare::Plan;
use super::process::{ProcessExit, sibling_binary, signal, spawn, status_text};
use crate::error::{Context, Error, IoContext, Result};
use etp_runtime::report::{SessionInfo, Stall};
use etp_runtime::wire::traffic::LinkTraffic;
use std::collections::BTreeMap;
use tokio::io::{AsyncBufReadExt, BufReader};
use tokio::process::{Child, ChildStdout};

/// The remote part of a run.
#[derive(Debug, Clone)]
pub struct RemoteSpec {
    pub listen: String,
    /// Indices of the sensors served from other hosts.
    pub remote: Vec<usize>,
    pub join_timeout: f64,
    /// The bridge's link arguments (`--tls DIR` or `--insecure`).
    pub link: Vec<String>,
}

/// What the bridge saw.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct LinkReport {
    /// Per remote sensor: what crossed the link, as carried.
    pub traffic: BTreeMap<String, LinkTraffic>,
    /// Remote sensors lost during the run (name, wall clock ns).
    pub lost: Vec<(String, u64)>,
    /// Messages from the link the bridge refused, by reason (`malformed`,
    /// `other-run`, `wrong-sender`, `duplicate`, …): each is a fault.
    pub refused: BTreeMap<String, u64>,
    /// Per remote sensor: messages still held at the end for an earlier
    /// one that never arrived (a fault too).
    pub held: BTreeMap<String, u64>,
    /// Messages that overtook an earlier one of their sensor on the link
    /// and were delivered after it (the order restored; not a fault).
    pub reordered: u64,
    /// Per remote sensor: puts towards it held up by the host it was granted
    /// to, which stopped reading (bounded by Zenoh's close of a stalled
    /// peer), the host's name, and whether it was closed and refused for the
    /// rest of the run (its sensor then a dead link: the episodes are
    /// degraded, the fault is theirs).
    pub stalled: BTreeMap<String, Stall>,
    /// Connections the agent host's TLS accept loop refused before they
    /// became links, by cause (`unknown-ca`, `expired`, `wrong-role`,
    /// `not-tls`, `timeout`, …; the bridge's `handshakes` line): nothing of
    /// the run came through them, so not a fault of the counts.
    pub handshakes_refused: BTreeMap<String, u64>,
    /// The first refusals in words, with their peer.
    pub handshakes_named: Vec<String>,
    /// Remote sensors the agent host cut as dead links because a wait on
    /// them passed the link's bound: which sensor, which message, how late
    /// (a fault of the run: exit 5 without `--allow-degraded`).
    pub dead_links: Vec<DeadLink>,
    /// Messages of cut sensors that came afterwards (dropped, not delivered).
    pub dropped_after_cut: u64,
    /// The bound on a wait at the end of the run (ms) and the slowest answer
    /// a remote sensor gave (ms), from which it is derived.
    pub wait_bound_ms: u64,
    pub slowest_answer_ms: u64,
}

/// A remote sensor cut because a wait on it passed the bound.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct DeadLink {
    pub sensor: String,
    /// The message that never came (`slot of episode 13 leg 1 step 87`).
    pub message: String,
    /// Why, in words.
    pub why: String,
    /// How long it was waited for, and the bound then (ms).
    pub late_ms: u64,
    pub bound_ms: u64,
    /// A gap's missing sequence number.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub missing_seq: Option<u32>,
}

impl LinkReport {
    /// The stalls in words (empty: none).
    pub fn stalls(&self) -> Option<String> {
        (!self.stalled.is_empty()).then(|| {
            self.stalled
                .iter()
                .map(|(k, s)| {
                    let who = s
                        .host
                        .as_ref()
                        .map_or_else(|| "a peer".to_string(), |h| format!("host {h}"));
                    let mut t = format!(
                        "{k}: {} put(s) waited for {who}, which stopped reading (longest {} ms)",
                        s.puts, s.longest_ms
                    );
                    if s.refused {
                        t.push_str(&format!(
                            "; closed and refused for the rest of the run ({} message(s) of {k} not sent)",
                            s.dropped
                        ));
                    }
                    t
                })
                .collect::<Vec<_>>()
                .join("; ")
        })
    }

    /// The refused handshakes in words (empty: none).
    pub fn handshakes(&self) -> Option<String> {
        let n: u64 = self.handshakes_refused.values().sum();
        (n > 0).then(|| {
            let by: Vec<String> = self
                .handshakes_refused
                .iter()
                .map(|(k, n)| format!("{n} {k}"))
                .collect();
            let mut s = format!(
                "{n} connection(s) refused at the TLS handshake ({})",
                by.join(", ")
            );
            if let Some(first) = self.handshakes_named.first() {
                s.push_str(&format!("; first named: {first}"));
            }
            s
        })
    }

    /// The link's faults in words (empty: none).
    pub fn faults(&self) -> Option<String> {
        let list = |m: &BTreeMap<String, u64>| {
            m.iter()
                .map(|(k, n)| format!("{n} {k}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let refused: u64 = self.refused.values().sum();
        let held: u64 = self.held.values().sum();
        let dead = self
            .dead_links
            .iter()
            .map(|d| format!("dead link {}: {}", d.sensor, d.why))
            .collect::<Vec<_>>()
            .join("; ");
        let others = self.refusals(refused, held, &list);
        match (others, dead.is_empty()) {
            (o, true) => o,
            (None, false) => Some(dead),
            (Some(o), false) => Some(format!("{dead}; {o}")),
        }
    }

    fn refusals(
        &self,
        refused: u64,
        held: u64,
        list: &dyn Fn(&BTreeMap<String, u64>) -> String,
    ) -> Option<String> {
        match (refused, held) {
            (0, 0) => None,
            (r, 0) => Some(format!(
                "the link refused {r} message(s): {}",
                list(&self.refused)
            )),
            (0, h) => Some(format!(
                "{h} message(s) from the link waited for an earlier one that never came ({})",
                list(&self.held)
            )),
            (r, h) => Some(format!(
                "the link refused {r} message(s): {}; {h} waited for an earlier one that never came ({})",
                list(&self.refused),
                list(&self.held)
            )),
        }
    }
}

pub struct Bridge {
    child: Child,
    pid: u32,
    lines: tokio::io::Lines<BufReader<ChildStdout>>,
}

/// Names → indices of `--remote`, refusing unknown names and duplicates.
pub fn remote_indices(plan: &Plan, names: &[String]) -> Result<Vec<usize>> {
    let mut v = Vec::new();
    for n in names {
        let i = plan
            .scenario
            .sensors
            .iter()
            .position(|s| &s.name == n)
            .ok_or_else(|| {
                Error::request(format!(
                    "--remote: scenario `{}` has no sensor `{n}` (sensors: {})",
                    plan.scenario.name,
                    plan.scenario
                        .sensors
                        .iter()
                        .map(|s| s.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })?;
        if v.contains(&i) {
            return Err(Error::request(format!(
                "--remote: sensor `{n}` named twice"
            )));
        }
        v.push(i);
    }
    Ok(v)
}

/// Start the bridge and wait until every remote sensor joined.
pub async fn start(
    plan: &Plan,
    spec: &RemoteSpec,
    interrupts: &mut super::interrupts::Interrupts,
) -> Result<Bridge> {
    let info = SessionInfo {
        run_id: plan.run_id.to_string(),
        scenario_toml: std::fs::read_to_string(&plan.scenario_path)
            .doing(|| format!("reading {}", plan.scenario_path.display()))?,
        seed: plan.seed,
        sensors: plan
            .scenario
            .sensors
            .iter()
            .map(|s| s.name.clone())
            .collect(),
        remote: spec.remote.clone(),
        link_protocol: etp_runtime::wire::stamp::LINK_PROTOCOL,
        channel_schedule_toml: plan
            .channel_schedule_path
            .as_ref()
            .map(|p| std::fs::read_to_string(p).doing(|| format!("reading {}", p.display())))
            .transpose()?,
    };
    let path = plan.dir.join("session.json");
    std::fs::write(&path, serde_json::to_string(&info)?)
        .doing(|| format!("writing {}", path.display()))?;
    let bin = sibling_binary("etp-bridge")?;
    let mut args = vec![
        "agent-host".into(),
        "--session".into(),
        path.display().to_string(),
        "--listen".into(),
        spec.listen.clone(),
        "--join-timeout".into(),
        spec.join_timeout.to_string(),
    ];
    args.extend(spec.link.iter().cloned());
    let mut child = spawn(&bin, &args, true)?;
    let pid = child.id().unwrap_or(0);
    let mut lines = BufReader::new(
        child
            .stdout
            .take()
            .ok_or_else(|| Error::process("bridge stdout"))?,
    )
    .lines();
    eprintln!(
        "etp run: listening on {} for remote sensor(s) {} (run {}; on their host: etp sensor-host --connect {})",
        spec.listen,
        spec.remote
            .iter()
            .map(|&i| info.sensors[i].as_str())
            .collect::<Vec<_>>()
            .join(", "),
        plan.run_id,
        spec.listen
    );
    loop {
        let line = tokio::select! {
            l = lines.next_line() => l.in_process(|| "reading the bridge")?,
            name = interrupts.next() => {
                // The bridge has run nothing yet: stopped and reaped here.
                let _ = child.kill().await;
                return Err(super::interrupts::before_any_episode(
                    name,
                    "while waiting for the remote sensors to join",
                ));
            }
        };
        match line {
            Some(l) => {
                let v: serde_json::Value = serde_json::from_str(&l).unwrap_or_default();
                if v["event"] == "ready" {
                    return Ok(Bridge { child, pid, lines });
                }
            }
            None => {
                let st = child.wait().await.in_process(|| "waiting for the bridge")?;
                return Err(Error::process(format!(
                    "the remote sensors did not join ({}; the bridge's error is above)",
                    status_text(&st)
                )));
            }
        }
    }
}

impl Bridge {
    /// Stop the bridge (SIGTERM) and read what it carried.
    pub async fn stop(mut self) -> (ProcessExit, LinkReport) {
        signal(self.pid, "-TERM");
        let mut report = LinkReport::default();
        let read = async {
            while let Ok(Some(l)) = self.lines.next_line().await {
                let v: serde_json::Value = serde_json::from_str(&l).unwrap_or_default();
                match v["event"].as_str() {
                    Some("lost") => report.lost.push((
                        v["sensor"].as_str().unwrap_or_default().to_string(),
                        v["unix_ns"].as_u64().unwrap_or(0),
                    )),
                    Some("refused") => {
                        report.refused =
                            serde_json::from_value(v["counts"].clone()).unwrap_or_default();
                        report.held = serde_json::from_value(v["held"].clone()).unwrap_or_default();
                        report.reordered = v["reordered"].as_u64().unwrap_or(0);
                        report.dropped_after_cut = v["dropped_after_cut"].as_u64().unwrap_or(0);
                    }
                    Some("handshakes") => {
                        report.handshakes_refused =
                            serde_json::from_value(v["refused"].clone()).unwrap_or_default();
                        report.handshakes_named =
                            serde_json::from_value(v["named"].clone()).unwrap_or_default();
                    }
                    Some("dead-link") => {
                        if let Ok(d) = serde_json::from_value(v.clone()) {
                            report.dead_links.push(d);
                        }
                    }
                    Some("bound") => {
                        report.wait_bound_ms = v["wait_ms"].as_u64().unwrap_or(0);
                        report.slowest_answer_ms = v["slowest_answer_ms"].as_u64().unwrap_or(0);
                    }
                    Some("stalled") => {
                        report.stalled =
                            serde_json::from_value(v["sensors"].clone()).unwrap_or_default();
                    }
                    Some("traffic") => {
                        report.traffic =
                            serde_json::from_value(v["sensors"].clone()).unwrap_or_default();
                    }
                    _ => {}
                }
            }
        };
        let _ = tokio::time::timeout(std::time::Duration::from_secs(5), read).await;
        let status = match tokio::time::timeout(
            std::time::Duration::from_secs(5),
            self.child.wait(),
        )
        .await
        {
            Ok(Ok(st)) => status_text(&st),
            _ => {
                let _ = self.child.kill().await;
                "killed by supervisor".into()
            }
        };
        (
            ProcessExit {
                name: "bridge".into(),
                pid: self.pid,
                status,
            },
            report,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_text_report_names_a_stalled_host_and_its_refusal() {
        let mut r = LinkReport::default();
        assert_eq!(r.stalls(), None);
        r.stalled.insert(
            "s1".into(),
            Stall {
                puts: 1,
                longest_ms: 5002,
                host: Some("b".into()),
                refused: true,
                dropped: 7,
            },
        );
        let text = r.stalls().unwrap_or_default();
        assert!(
            text.contains(
                "s1: 1 put(s) waited for host b, which stopped reading (longest 5002 ms)"
            ) && text.contains(
                "closed and refused for the rest of the run (7 message(s) of s1 not sent)"
            ),
            "{text}"
        );
    }
}
