//! A sensor host's end: connects to the agent host, fetches the run
//! ([`SessionInfo`]: scenario, seed, which sensors are remote), claims its
//! sensors (the agent host grants each to one host only; a refusal ends
//! this end with an error before any sensor starts), sets up the
//! local side of those sensors' services and says `joined` (its parent,
//! `etp sensor-host`, then starts the sensor processes). Each local sensor's
//! hello goes up and is followed by its liveliness token; the agent host's
//! token is watched: when it vanishes (run over, host dead, link cut) the
//! proxies of the coordinator and agent on this host go, and the local
//! sensors see their coordinator gone and exit.

use crate::admit::Admission;
use crate::forward::{Counters, Inbound, Incoming, Outbound, Stalls, subscribe};
use crate::session::{
    SESSION_KEY, SessionInfo, agent_host_alive_key, config, down_keys, join_key, sensor_alive_key,
};
use crate::{BridgeError, emit};
use etp_runtime::wire::traffic::Direction;
use etp_runtime::wire::{self, AGENT_NODE, COORDINATOR_NODE, Ports, RunId, ServiceId};
use iceoryx2::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};
use zenoh::Wait;

/// `etp-bridge sensor-host`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// The agent host's Zenoh endpoint, e.g. `tcp/10.0.0.1:7447`.
    #[arg(long)]
    pub connect: String,
    /// Sensors this host serves (names; default: every remote sensor of the run).
    #[arg(long = "sensor")]
    pub sensors: Vec<String>,
    /// Folder for the run's scenario (created if missing).
    #[arg(long)]
    pub dir: PathBuf,
    #[command(flatten)]
    pub host: crate::session::HostArgs,
}

/// How often the local sensors' liveness is checked (a dead one's token is
/// withdrawn, so the agent host sees a dead link).
const LIVENESS_CHECK: Duration = Duration::from_millis(50);

/// Ask the agent host for the run until it answers or `timeout` passes.
fn fetch(
    session: &zenoh::Session,
    a: &Args,
    timeout: Duration,
) -> Result<SessionInfo, BridgeError> {
    let started = Instant::now();
    loop {
        let replies = session
            .get(SESSION_KEY)
            .timeout(Duration::from_millis(500))
            .wait()
            .map_err(|e| BridgeError::Zenoh(format!("query {SESSION_KEY}: {e}")))?;
        while let Ok(r) = replies.recv() {
            if let Ok(sample) = r.result() {
                let bytes = sample.payload().to_bytes();
                return serde_json::from_slice(&bytes)
                    .map_err(|e| BridgeError::Protocol(format!("the run's description: {e}")));
            }
        }
        if started.elapsed() >= timeout {
            return Err(BridgeError::Join(format!(
                "no agent host answered at {} within {:.0} s (is `etp run … --listen {}` running?)",
                a.connect,
                timeout.as_secs_f64(),
                a.connect
            )));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Claim each of `served` from the agent host, in this host's name `host`
/// (the key's; with TLS, access control checks it is the certificate's) and
/// with this session's Zenoh id, until it answers or `timeout` passes. A refusal (another host serves the
/// sensor, or this one may not) is an error: nothing has started yet.
fn claim(
    session: &zenoh::Session,
    info: &SessionInfo,
    served: &[usize],
    host: &str,
    timeout: Duration,
) -> Result<(), BridgeError> {
    let zid = session.zid().to_string();
    let started = Instant::now();
    for &i in served {
        let name = info
            .sensors
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("#{i}"));
        let key = join_key(&info.run_id, i, host);
        loop {
            let replies = session
                .get(&key)
                .payload(crate::session::claim_payload(&zid))
                .timeout(Duration::from_millis(500))
                .wait()
                .map_err(|e| BridgeError::Zenoh(format!("query {key}: {e}")))?;
            let mut answer = None;
            while let Ok(r) = replies.recv() {
                answer = Some(match r.result() {
                    Ok(_) => Ok(()),
                    Err(e) => Err(String::from_utf8_lossy(&e.payload().to_bytes()).into_owned()),
                });
            }
            match answer {
                Some(Ok(())) => break,
                Some(Err(why)) => {
                    return Err(BridgeError::Join(format!(
                        "sensor {name}: the agent host refused this host's claim: {why}"
                    )));
                }
                None if started.elapsed() >= timeout => {
                    return Err(BridgeError::Join(format!(
                        "sensor {name}: the agent host did not answer this host's claim within {:.0} s (with --tls: does the key folder's hosts.json let this host's --name serve it?)",
                        timeout.as_secs_f64()
                    )));
                }
                None => std::thread::sleep(Duration::from_millis(100)),
            }
        }
    }
    Ok(())
}

/// The Zenoh session to the agent host (its certificate checked first, with
/// TLS).
fn connect(a: &Args) -> Result<zenoh::Session, BridgeError> {
    let identity = a
        .host
        .link
        .resolve(&a.connect, crate::session::End::SensorHost)?;
    if let Some(id) = &identity {
        crate::tls_check::check_agent_host(&a.connect, id, a.host.join_wait())?;
    }
    let session = zenoh::open(config(
        None,
        Some(&a.connect),
        a.host.lease(),
        identity.as_ref(),
        None,
    )?)
    .wait()
    .map_err(|e| BridgeError::Zenoh(format!("connecting to {}: {e}", a.connect)))?;
    Ok(session)
}

/// The sensors this host serves: those named (each must be a remote sensor
/// of the run), or every remote sensor.
fn served_sensors(a: &Args, info: &SessionInfo) -> Result<Vec<usize>, BridgeError> {
    if a.sensors.is_empty() {
        Ok(info.remote.clone())
    } else {
        a.sensors
            .iter()
            .map(|n| {
                info.sensors
                    .iter()
                    .position(|s| s == n)
                    .filter(|i| info.remote.contains(i))
                    .ok_or_else(|| {
                        BridgeError::Input(format!(
                            "sensor `{n}` is not a remote sensor of run {} (remote: {})",
                            info.run_id,
                            info.remote
                                .iter()
                                .filter_map(|&i| info.sensors.get(i).cloned())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ))
                    })
            })
            .collect::<Result<_, _>>()
    }
}

/// Write the run's scenario (and its channel schedule, checked) into
/// `--dir`; returns the scenario's path and the schedule's, if any.
fn write_run_files(a: &Args, info: &SessionInfo) -> Result<(PathBuf, Option<String>), BridgeError> {
    std::fs::create_dir_all(&a.dir)
        .map_err(|e| BridgeError::Input(format!("creating {}: {e}", a.dir.display())))?;
    let scenario = a.dir.join("scenario.toml");
    std::fs::write(&scenario, &info.scenario_toml)
        .map_err(|e| BridgeError::Input(format!("writing {}: {e}", scenario.display())))?;
    // The run's channel changes: checked here as the sensors will read them
    // (what came over the link is not trusted), written beside the scenario.
    let schedule = match &info.channel_schedule_toml {
        None => None,
        Some(text) => {
            let path = a.dir.join("channel-schedule.toml");
            let scenario = etp_shared::scenario::Scenario::from_toml(&info.scenario_toml)
                .map_err(|e| BridgeError::Protocol(format!("the run's scenario: {e}")))?;
            etp_shared::radio::schedule::ChannelSchedule::parse(
                text,
                "the run's channel schedule",
                &scenario.radio,
                &info.sensors,
            )
            .map_err(|e| BridgeError::Protocol(e.to_string()))?;
            std::fs::write(&path, text)
                .map_err(|e| BridgeError::Input(format!("writing {}: {e}", path.display())))?;
            Some(path.display().to_string())
        }
    };
    Ok((scenario, schedule))
}

/// The proxies of the coordinator and the agent on this host.
type Proxies = (Node<ipc::Service>, Node<ipc::Service>);

/// A sensor host's end: joins the run, serves its sensors until the run is
/// over, then reports what it refused and forwarded.
pub fn run(a: &Args) -> Result<(), BridgeError> {
    let session = connect(a)?;
    let info = fetch(&session, a, a.host.join_wait())?;
    if let Some(why) = crate::session::other_protocol(
        Some(info.link_protocol),
        Some(etp_runtime::wire::stamp::LINK_PROTOCOL),
    ) {
        return Err(BridgeError::Join(why));
    }
    let served = served_sensors(a, &info)?;
    let host = a
        .host
        .link
        .name
        .as_deref()
        .unwrap_or(etp_runtime::link_keys::DEFAULT_SENSOR_HOST);
    claim(&session, &info, &served, host, a.host.join_wait())?;
    let (scenario, schedule) = write_run_files(a, &info)?;
    let run = RunId::new(&info.run_id)?;
    let sensors = info.sensors.len();
    let node = wire::create_node(&run, "etp-bridge-in")?;
    // The coordinator and the agent live on the agent host: their proxies
    // live here while it does (the sensors' watchdog looks for them).
    let mut proxies = Some((
        wire::create_node(&run, COORDINATOR_NODE)?,
        wire::create_node(&run, AGENT_NODE)?,
    ));
    let ports = Ports {
        node: &node,
        run: &run,
        sensors,
    };
    let inbound = Inbound::new(&ports, &ServiceId::forwarded(Direction::Down, &served))?;
    let (tx, rx) = std::sync::mpsc::channel();
    let _subs = subscribe(
        &session,
        &served
            .iter()
            .map(|&i| down_keys(run.as_str(), host, i))
            .collect::<Vec<_>>(),
        &agent_host_alive_key(run.as_str()),
        tx.clone(),
    )?;
    let counters = Counters::default();
    let stalls = Stalls::default();
    let mut admission = Admission::towards_sensors(run.tag(), &served);
    let stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = std::sync::mpsc::channel::<()>();
    let hello_tx = tx.clone();
    let outbound = Outbound::new(&run, sensors, Direction::Up, &served).spawn(
        "etp-bridge-out".into(),
        &session,
        &counters,
        &stalls,
        &stop,
        // Its subscribers (`hello` among them) exist: the sensors may start
        // and say hello.
        move || {
            let _ = ready_tx.send(());
        },
        move |s, h, _| {
            if s == ServiceId::Hello {
                let _ = hello_tx.send(Incoming::Hello(h.sender as usize));
            }
        },
    );
    // Until the outbound direction's ports exist (or it failed: its error
    // comes with the join below).
    let _ = ready_rx.recv();
    emit(&serde_json::json!({
        "event": "joined",
        "run_id": info.run_id,
        "seed": info.seed,
        "scenario": scenario.display().to_string(),
        "channel_schedule": schedule,
        "sensors": served.iter().filter_map(|&i| info.sensors.get(i).cloned()).collect::<Vec<_>>(),
    }));
    // A sensor that said hello is up: its token announces it to the agent
    // host, for as long as its process lives here.
    let mut tokens: std::collections::BTreeMap<usize, zenoh::liveliness::LivelinessToken> =
        std::collections::BTreeMap::new();
    let serving = Serving {
        session: &session,
        node: &node,
        run: &run,
        inbound: &inbound,
        counters: &counters,
    };
    serving.until_over(&rx, &mut admission, &mut tokens, &mut proxies)?;
    drop(proxies);
    drop(tokens);
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let out = outbound
        .join()
        .map_err(|_| BridgeError::Wire("the outbound thread panicked".into()))?;
    crate::emit_refused(&admission, &info.sensors);
    crate::emit_traffic(&counters, &stalls, &info.sensors);
    out
}

/// What a sensor host serves its sensors with.
struct Serving<'a> {
    session: &'a zenoh::Session,
    node: &'a Node<ipc::Service>,
    run: &'a RunId,
    inbound: &'a Inbound,
    counters: &'a Counters,
}

impl Serving<'_> {
    /// Forward towards the local sensors and announce each that said hello,
    /// until termination, the parent's death or the agent host's end (its
    /// proxies then go at once); a failure ends this end at once.
    fn until_over(
        &self,
        rx: &std::sync::mpsc::Receiver<Incoming>,
        admission: &mut Admission,
        tokens: &mut std::collections::BTreeMap<usize, zenoh::liveliness::LivelinessToken>,
        proxies: &mut Option<Proxies>,
    ) -> Result<(), BridgeError> {
        let Serving {
            session,
            node,
            run,
            inbound,
            counters,
        } = *self;
        let parent = std::os::unix::process::parent_id();
        let mut last_check = Instant::now();
        loop {
            if wire::termination_requested(node) || std::os::unix::process::parent_id() != parent {
                return Ok(());
            }
            // Listing the nodes costs about a millisecond: not on every message.
            if last_check.elapsed() >= LIVENESS_CHECK {
                last_check = Instant::now();
                tokens.retain(|&i, _| {
                    let alive = wire::liveness(node.config(), &wire::sensor_node_name(i))
                        == wire::Liveness::Alive;
                    if !alive {
                        tracing::info!(sensor = i, "local sensor gone: its token is withdrawn");
                    }
                    alive
                });
            }
            match rx.recv_timeout(Duration::from_millis(20)) {
                Ok(Incoming::Hello(i)) => {
                    let t = session
                        .liveliness()
                        .declare_token(sensor_alive_key(run.as_str(), i))
                        .wait()
                        .map_err(|e| {
                            BridgeError::Zenoh(format!("liveliness token of sensor {i}: {e}"))
                        })?;
                    tokens.insert(i, t);
                }
                // The agent host's probe ([`crate::session::probe_key`]): read
                // (that is its point), not a service.
                Ok(Incoming::Data { key, .. }) if crate::session::is_probe_key(&key) => {}
                Ok(Incoming::Data { key, bytes }) => {
                    for m in inbound.receive(admission, &key, &bytes) {
                        inbound.deliver(m, counters)?;
                    }
                }
                // Nobody queries a sensor host: it declares no queryable.
                Ok(
                    Incoming::Alive { alive: true, .. } | Incoming::Claim(_) | Incoming::Asked(..),
                ) => {}
                Ok(Incoming::Alive { alive: false, .. }) => {
                    tracing::warn!("the agent host is gone: the local sensors stop");
                    emit(&serde_json::json!({"event": "agent-host-gone"}));
                    *proxies = None;
                    return Ok(());
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => return Ok(()),
            }
        }
    }
}
