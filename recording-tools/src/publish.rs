//! `--publish [--rate X]`: put a recording's traffic back on iceoryx2, like
//! `ros2 bag play`. Every recorded message is sent, unchanged, on its service
//! under a run id of its own (`etp/<run-id>/<topic>`), at the recorded time
//! offsets divided by X; the services have the limits of the live run
//! (`wire::limits`), so a lagging subscriber makes the replay wait rather than
//! lose messages. Subscribers (`etp-recorder --run-id ID`, a test, a tool)
//! should exist before the replay starts: iceoryx2 delivers to the subscribers
//! present at send time. Before its first message the replay waits until
//! every recorder of the run id has attached to its publishers
//! (`recording::observers`), so a replay that ends within milliseconds
//! leaves every message to the recorder.
//!
//! The recording's metadata records (scenario, strategy, run, prediction) are
//! left in the run's folder (`recording::handover_path`) before the first
//! message: a recorder of that run started without `--meta` writes them into
//! its copy when it finishes, so the copy summarises and `--verify`s like the
//! original. `--loop` repeats the traffic (the time offsets restart).

use crate::error::{Context, Error, IoContext, Result};
use etp_runtime::recording::{self, Contents, Recorded, observers};
use etp_runtime::wire::{self, Notifier, Ports, RunId, ServiceId};
use etp_shared::scenario::Scenario;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// Node name of the replayer.
const REPLAY_NODE: &str = "etp-replay";
/// How long a sample is re-sent to a subscriber whose buffer stays full
/// before it counts as undelivered.
const STALL_LIMIT: Duration = Duration::from_secs(5);

/// `--rate`: a positive speed factor (`inf`: as fast as subscribers take it).
pub fn parse_rate(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if x.is_nan() || x <= 0.0 {
        return Err(format!("the rate must be > 0 (got {s})"));
    }
    Ok(x)
}

/// What a replay published.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Published {
    pub run_id: String,
    pub rate: f64,
    pub messages: u64,
    /// Messages that reached no subscriber.
    pub undelivered: u64,
    pub counts: BTreeMap<String, u64>,
    /// Span of the recorded log times, and the wall time the replay took.
    pub recorded_seconds: f64,
    pub wall_seconds: f64,
    /// Passes over the recording (`--loop`).
    pub loops: u64,
}

/// Publish every message of `c` under `run` at `rate` × the recorded speed,
/// `repeat` times in all (`None` once, `Some(0)` until interrupted).
pub fn publish(c: &Contents, run: &RunId, rate: f64, repeat: Option<u64>) -> Result<Published> {
    let text = c
        .meta(recording::META_SCENARIO, "toml")
        .ok_or(Error::NoScenario)?;
    let scenario = Scenario::from_toml(text).map_err(|source| Error::Scenario {
        what: "the recorded scenario".into(),
        source,
    })?;
    // Decode everything first: a damaged payload stops the replay before it starts.
    let mut order: Vec<(u64, &str, Recorded)> = Vec::with_capacity(c.messages.len());
    for m in &c.messages {
        let r = m
            .decode()
            .at_message(|| format!("message at log time {}", m.log_time))?;
        order.push((m.log_time, m.topic.as_str(), r));
    }
    // The recorder drains channel by channel: restore the global time order
    // (stable, so a channel's own order is kept).
    order.sort_by_key(|(t, _, _)| *t);

    let node = wire::create_node(run, REPLAY_NODE)?;
    let ports = Ports {
        node: &node,
        run,
        sensors: scenario.sensors.len(),
    };
    let mut senders: BTreeMap<&str, (Box<dyn recording::ports::DecodedPublisher>, ServiceId)> =
        BTreeMap::new();
    let mut wakes: BTreeMap<ServiceId, Notifier> = BTreeMap::new();
    for topic in c.channels.keys() {
        let s = recording::service_of_topic(topic)
            .ok_or_else(|| Error::UnknownChannel(topic.clone()))?;
        let wake = s.reader_wake();
        if let std::collections::btree_map::Entry::Vacant(slot) = wakes.entry(wake) {
            slot.insert(ports.notifier(wake).map_err(|source| Error::Port {
                what: format!("opening the wake-up of `{topic}`"),
                source,
            })?);
        }
        senders.insert(
            topic.as_str(),
            (
                recording::ports::decoded_publisher(&ports, s).map_err(|source| Error::Port {
                    what: format!("opening `{topic}`"),
                    source,
                })?,
                wake,
            ),
        );
    }
    let token = hand_over_metadata(c, run)?;
    // Wake every reader, then wait until each recorder of this run id has
    // attached to every publisher: a sample sent before then is lost if
    // this replay ends first (`recording::observers`).
    for n in wakes.values() {
        n.notify().map_err(|e| Error::Publish {
            what: "waking the readers".into(),
            detail: format!("{e:?}"),
        })?;
    }
    observers::await_attached(run, token, observers::ATTACH_LIMIT, || {
        wire::termination_requested(&node)
    })?;
    let t0 = order.first().map_or(0, |(t, _, _)| *t);
    let t_end = order.last().map_or(0, |(t, _, _)| *t);
    let start = Instant::now();
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    let (mut messages, mut undelivered, mut loops) = (0u64, 0u64, 0u64);
    let forever = repeat == Some(0);
    // Channels that reached a subscriber at least once.
    let mut delivered: std::collections::BTreeSet<&str> = std::collections::BTreeSet::new();
    'passes: while forever || loops < repeat.unwrap_or(1) {
        let pass_start = Instant::now();
        for (t, topic, r) in &order {
            if messages % 256 == 0 && wire::termination_requested(&node) {
                if forever {
                    break 'passes;
                }
                return Err(Error::Interrupted { messages });
            }
            let due = Duration::try_from_secs_f64((t - t0) as f64 * 1e-9 / rate)
                .map_err(|source| Error::Rate { rate, source })?;
            if let Some(wait) = due.checked_sub(pass_start.elapsed()) {
                std::thread::sleep(wait);
            }
            let Some((sender, wake)) = senders.get(topic) else {
                return Err(Error::UnopenedChannel(topic.to_string()));
            };
            let notify = || -> Result<()> {
                // As the live publisher did: readers (and the recorder) wake on it.
                if let Some(n) = wakes.get(wake) {
                    n.notify().map_err(|e| Error::Publish {
                        what: format!("notifying the readers of `{topic}`"),
                        detail: format!("{e:?}"),
                    })?;
                }
                Ok(())
            };
            let publishing = |source| Error::Send {
                what: format!("publishing on `{topic}`"),
                source,
            };
            let mut reached = sender.send(r.clone()).map_err(publishing)?;
            notify()?;
            // iceoryx2 returns 0 (a silent drop) when a subscriber's buffer
            // is full: on a channel that has a subscriber, wait for it to
            // drain and send again (nobody got this sample, so no duplicate).
            let retry_until = Instant::now() + STALL_LIMIT;
            while reached == 0 && delivered.contains(topic) && Instant::now() < retry_until {
                std::thread::sleep(Duration::from_micros(200));
                reached = sender.send(r.clone()).map_err(publishing)?;
                notify()?;
            }
            if reached > 0 {
                delivered.insert(topic);
            }
            undelivered += u64::from(reached == 0);
            messages += 1;
            *counts.entry(topic.to_string()).or_default() += 1;
        }
        loops += 1;
        if order.is_empty() && forever {
            return Err(Error::request("--loop: nothing to publish"));
        }
    }
    let wall_seconds = start.elapsed().as_secs_f64();
    drop(senders);
    drop(wakes);
    drop(node);
    // Leaves the run's folder to any subscriber still alive.
    etp_runtime::cleanup::remove_run(run);
    Ok(Published {
        run_id: run.to_string(),
        rate,
        messages,
        undelivered,
        counts,
        recorded_seconds: (t_end - t0) as f64 * 1e-9,
        wall_seconds,
        loops,
    })
}

/// Leave the recording's metadata for the run's recorder (see the module doc).
fn hand_over_metadata(c: &Contents, run: &RunId) -> Result<observers::Token> {
    let path = recording::handover_path(run);
    let text = serde_json::to_string(&c.metadata).map_err(|source| Error::Json {
        what: "encoding the metadata".into(),
        source,
    })?;
    // Written beside and renamed: a recorder reading it meanwhile sees the
    // whole file or none.
    let beside = path.with_extension("json.part");
    std::fs::write(&beside, text).doing(|| format!("writing {}", beside.display()))?;
    std::fs::rename(&beside, &path).doing(|| format!("renaming to {}", path.display()))?;
    observers::handover_token(run).ok_or(Error::HandoverVanished(path))
}
