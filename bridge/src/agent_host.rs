//! The agent host's end: listens, tells joining sensor hosts the run
//! (queryable [`SESSION_KEY`]), grants each remote sensor to the first host
//! that claims it (queryable [`crate::session::join_key`]; a second claimant is refused and
//! counted, `duplicate-host`), waits (bounded) until every remote sensor
//! has joined, then carries the remote sensors' services both ways.
//!
//! Down, each remote sensor's messages go only to the host granted it at
//! join, on keys that name that host ([`crate::session::down_key`]; with
//! TLS, access control lets no other peer subscribe to them), so a peer
//! that stops reading holds up nothing it was not granted. Each remote
//! sensor has an outbound thread of its own: a put waits while the granted
//! host's queue is full, so a host that stops reading holds up only its own
//! sensors, and only until Zenoh closes it
//! ([`crate::session::STALLED_PEER_CLOSE`]); with TLS that host is then
//! refused for the rest of the run (its sensors are dead links). The run
//! itself sends a host little while the agent waits for its sensor (one
//! step's messages), so a host that owes an answer is probed
//! ([`crate::session::probe_key`]): a host that stopped reading fills its
//! queue with the probes and is closed all the same.
//!
//! A remote sensor is alive on this host as long as its host's liveliness
//! token is: the bridge keeps an iceoryx2 *proxy node* named like the sensor
//! (`etp-sensor-<i>`) for exactly that time, so the agent's and the
//! coordinator's existing dead-link detection (the node list) sees a
//! killed host or a cut link like a dead local sensor, within the link lease.

use crate::admit::{Admission, Admitted};
use crate::answers::{Question, Questions};
use crate::forward::{
    Counters, Grant, Grants, Heard, Inbound, Incoming, Outbound, Stalls, subscribe,
};
use crate::session::{
    End, SESSION_KEY, SessionInfo, agent_host_alive_key, config, data_keys, join_keys,
    other_protocol, parse_claim, parse_join_key,
};
use crate::{BridgeError, emit};
use etp_runtime::wire::stamp::LINK_PROTOCOL;
use etp_runtime::wire::to_coordinator::Hello;
use etp_runtime::wire::traffic::Direction;
use etp_runtime::wire::{
    self, COORDINATOR_NODE, Liveness, Ports, PubSub, RunId, ServiceId, open_pubsub,
    sensor_node_name,
};
use iceoryx2::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};
use zenoh::Wait;

/// `etp-bridge agent-host`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// The run's description (JSON `SessionInfo`, written by `etp run`).
    #[arg(long)]
    pub session: std::path::PathBuf,
    /// Zenoh endpoint to listen on, e.g. `tcp/10.0.0.1:7447`.
    #[arg(long)]
    pub listen: String,
    #[command(flatten)]
    pub host: crate::session::HostArgs,
}

/// The run's description as `etp run` wrote it, with this end's link
/// protocol.
fn read_session_info(a: &Args) -> Result<SessionInfo, BridgeError> {
    let text = std::fs::read_to_string(&a.session)
        .map_err(|e| BridgeError::Input(format!("reading {}: {e}", a.session.display())))?;
    let mut info: SessionInfo = serde_json::from_str(&text)
        .map_err(|e| BridgeError::Input(format!("{}: {e}", a.session.display())))?;
    // What this end puts on the link, whoever wrote the description.
    info.link_protocol = LINK_PROTOCOL;
    Ok(info)
}

/// The Zenoh session that listens for the sensor hosts, and its access
/// control (with identities: each sensor host only its sensors' keys).
fn open_session(
    a: &Args,
    info: &SessionInfo,
) -> Result<(zenoh::Session, Option<serde_json::Value>), BridgeError> {
    let identity = a.host.link.resolve(&a.listen, End::AgentHost)?;
    // With identities, access control by certificate: each sensor host only
    // its sensors' keys.
    let acl = match (&identity, &a.host.link.tls) {
        (Some(_), Some(dir)) => Some(crate::session::access_control_of(dir, info)?),
        _ => None,
    };
    crate::tls_check::watch_refusals();
    let session = zenoh::open(config(
        Some(&a.listen),
        None,
        a.host.lease(),
        identity.as_ref(),
        acl.as_ref(),
    )?)
    .wait()
    .map_err(|e| BridgeError::Zenoh(format!("listening on {}: {e}", a.listen)))?;
    Ok((session, acl))
}

/// The agent host's end: serves the run's description, grants each remote
/// sensor to one host, forwards both ways until the run is over, then
/// reports what it refused, its bound and its traffic.
pub fn run(a: &Args) -> Result<(), BridgeError> {
    let info = read_session_info(a)?;
    let run = RunId::new(&info.run_id)?;
    let sensors = info.sensors.len();
    let (session, acl) = open_session(a, &info)?;
    let _alive = session
        .liveliness()
        .declare_token(agent_host_alive_key(run.as_str()))
        .wait()
        .map_err(|e| BridgeError::Zenoh(format!("liveliness token: {e}")))?;
    let reply = serde_json::to_string(&info).map_err(|e| BridgeError::Input(e.to_string()))?;
    let _queryable = session
        .declare_queryable(SESSION_KEY)
        .callback(move |q| {
            let _ = q.reply(SESSION_KEY, reply.clone()).wait();
        })
        .wait()
        .map_err(|e| BridgeError::Zenoh(format!("queryable: {e}")))?;
    let (tx, rx) = std::sync::mpsc::channel();
    let (answers, answerers) = answerers();
    let claims = tx.clone();
    let _claims = session
        .declare_queryable(join_keys(run.as_str()))
        .callback(move |q| {
            let _ = claims.send(Incoming::Claim(q));
        })
        .wait()
        .map_err(|e| BridgeError::Zenoh(format!("queryable of claims: {e}")))?;
    let _subs = subscribe(
        &session,
        &[data_keys(run.as_str(), false)],
        &format!("etp/{run}/alive/sensor/*"),
        tx.clone(),
    )?;
    let counters = Counters::default();
    let stalls = Stalls::default();
    let stop = Arc::new(AtomicBool::new(false));
    let grants = Grants::default();
    let heard = Heard::default();
    let outbound: Vec<_> = info
        .remote
        .iter()
        .map(|&i| {
            let asked = tx.clone();
            Outbound::new(&run, sensors, Direction::Down, &[i])
                .to_grants(&grants, acl.is_some())
                .probing(&heard)
                .spawn(
                    format!("etp-bridge-out-{i}"),
                    &session,
                    &counters,
                    &stalls,
                    &stop,
                    || {},
                    move |s, h, bytes| {
                        if let Some(q) = question_of(s, h, bytes) {
                            let _ = asked.send(Incoming::Asked(i, q, Instant::now()));
                        }
                    },
                )
        })
        .collect();
    let node = wire::create_node(&run, "etp-bridge-in")?;
    let ports = Ports {
        node: &node,
        run: &run,
        sensors,
    };
    let inbound = Inbound::new(&ports, &ServiceId::forwarded(Direction::Up, &info.remote))?;
    let hello = open_pubsub::<Hello>(&node, &run, ServiceId::Hello, sensors)?;
    let remote: BTreeSet<usize> = info.remote.iter().copied().collect();
    let mut serving = Serving {
        cut: BTreeSet::new(),
        // Every wait of the run on a remote sensor is bounded: its open
        // questions and the gaps in its messages (crate::answers).
        questions: Questions::new(a.host.lease()),
        said_hello: BTreeSet::new(),
        admission: Admission::towards_agent(run.tag(), &info.remote),
        hellos: Vec::new(),
        proxies: BTreeMap::new(),
        ready: false,
        started: Instant::now(),
        timeout: a.host.join_wait(),
        info: &info,
        run: &run,
        node: &node,
        inbound: &inbound,
        hello: &hello,
        remote: &remote,
        grants: &grants,
        heard: &heard,
        counters: &counters,
    };
    let result = serving.until_over(&rx, &answers)?;
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    drop(answers);
    for t in answerers {
        let _ = t.join();
    }
    let mut out = Ok(());
    for t in outbound {
        let r = t
            .join()
            .map_err(|_| BridgeError::Wire("an outbound thread panicked".into()))?;
        out = out.and(r);
    }
    crate::emit_refused(&serving.admission, &info.sensors);
    emit(&serde_json::json!({"event": "bound",
        "wait_ms": serving.questions.bound().wait().as_millis() as u64,
        "slowest_answer_ms": serving.questions.bound().slowest().as_millis() as u64}));
    crate::emit_handshakes();
    crate::emit_traffic(&counters, &stalls, &info.sensors);
    drop(serving.proxies);
    result.and(out)
}

/// The agent host's side of a run while it lasts. Its owned fields are
/// dropped in this order (the open questions before the sensors' proxies),
/// as when each was a variable of [`run`].
struct Serving<'a> {
    /// Sensors cut as dead links.
    cut: BTreeSet<usize>,
    /// Every wait of the run on a remote sensor is bounded: its open
    /// questions and the gaps in its messages (crate::answers).
    questions: Questions,
    said_hello: BTreeSet<usize>,
    admission: Admission,
    /// Remote hellos, held until the coordinator (and a recorder) subscribe.
    hellos: Vec<Admitted>,
    /// A proxy node per remote sensor whose token is alive.
    proxies: BTreeMap<usize, Node<ipc::Service>>,
    /// Every remote sensor has joined.
    ready: bool,
    started: Instant,
    /// How long the remote sensors have to join.
    timeout: Duration,
    info: &'a SessionInfo,
    run: &'a RunId,
    node: &'a Node<ipc::Service>,
    inbound: &'a Inbound,
    hello: &'a PubSub<Hello>,
    remote: &'a BTreeSet<usize>,
    grants: &'a Grants,
    heard: &'a Heard,
    counters: &'a Counters,
}

impl Serving<'_> {
    /// A sensor's name (`#i` for an index the run does not name).
    fn name(&self, i: usize) -> String {
        self.info
            .sensors
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("#{i}"))
    }

    /// Forward until termination, the parent's death or the end of the
    /// Zenoh side. The outer error ends the end at once; the inner one (the
    /// remote sensors did not join in time) comes after the shutdown.
    fn until_over(
        &mut self,
        rx: &std::sync::mpsc::Receiver<Incoming>,
        answers: &std::sync::mpsc::Sender<Answer>,
    ) -> Result<Result<(), BridgeError>, BridgeError> {
        let parent = std::os::unix::process::parent_id();
        loop {
            if wire::termination_requested(self.node)
                || std::os::unix::process::parent_id() != parent
            {
                return Ok(Ok(()));
            }
            if !self.ready
                && let Some(late) = self.check_joined()
            {
                return Ok(Err(late));
            }
            // Remote hellos wait until the coordinator (and a recorder) subscribe.
            if !self.hellos.is_empty()
                && wire::liveness(self.node.config(), COORDINATOR_NODE) == Liveness::Alive
                && self.hello.dynamic_config().number_of_subscribers()
                    >= wire::hello_readers(self.node.config())
            {
                for m in self.hellos.drain(..) {
                    self.inbound.deliver(m, self.counters)?;
                }
            }
            self.close_refused_hosts();
            self.cut_overdue();
            let wait = if self.hellos.is_empty() { 100 } else { 5 };
            match rx.recv_timeout(Duration::from_millis(wait)) {
                Ok(Incoming::Data { key, bytes }) => self.on_data(&key, &bytes)?,
                Ok(Incoming::Alive { key, alive }) => self.on_alive(&key, alive)?,
                Ok(Incoming::Claim(q)) => self.on_claim(q, answers),
                // A sensor without a proxy is a dead link already (lost, cut or
                // refused): nobody waits for its answer.
                Ok(Incoming::Asked(i, q, at)) => {
                    if self.proxies.contains_key(&i) {
                        self.questions.asked(i, q, at);
                    }
                }
                Ok(Incoming::Hello(_)) | Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => return Ok(Ok(())),
            }
        }
    }

    /// Before every remote sensor has joined: `ready` once each has a proxy
    /// and said hello; the error naming the missing ones once the time to
    /// join is over.
    fn check_joined(&mut self) -> Option<BridgeError> {
        let joined: BTreeSet<usize> = self
            .proxies
            .keys()
            .copied()
            .filter(|i| self.said_hello.contains(i))
            .collect();
        if joined == *self.remote {
            self.ready = true;
            emit(
                &serde_json::json!({"event": "ready", "joined": self.info.remote.iter().map(|&i| self.name(i)).collect::<Vec<_>>()}),
            );
            tracing::info!(remote = ?self.info.remote, "every remote sensor joined");
        } else if self.started.elapsed() >= self.timeout {
            let missing: Vec<String> = self
                .remote
                .difference(&joined)
                .map(|&i| self.name(i))
                .collect();
            let tls = crate::tls_check::refusals();
            let seen = if tls.named.is_empty() {
                String::new()
            } else {
                format!("; refused TLS connections: {}", tls.named.join("; "))
            };
            return Some(BridgeError::Join(format!(
                "sensor(s) {} did not join within {:.0} s (is `etp sensor-host --connect …` running on their host?){seen}",
                missing.join(", "),
                self.timeout.as_secs_f64()
            )));
        }
        None
    }

    /// A host refused for not reading (an outbound thread's verdict): its
    /// sensors are dead links from now on, whether or not its token went.
    fn close_refused_hosts(&mut self) {
        for i in refused_sensors(self.grants) {
            self.questions.forget(i);
            if self.proxies.remove(&i).is_some() {
                tracing::warn!(sensor = %self.name(i), "remote sensor lost: its host was closed for not reading");
                emit(&serde_json::json!({"event": "lost", "sensor": self.name(i),
                    "unix_ns": wire_now_ns()}));
            }
        }
    }

    /// A sensor whose answer or message is overdue is cut as a dead link.
    fn cut_overdue(&mut self) {
        if let Some(dead) = overdue(&mut self.questions, &mut self.admission, &self.cut) {
            let i = dead.sensor;
            self.cut.insert(i);
            self.admission.cut(i);
            self.questions.forget(i);
            if let Ok(mut g) = self.grants.lock() {
                let host = match g.get(&i) {
                    Some(Grant::Host(h) | Grant::Refused(h) | Grant::Cut(h)) => h.clone(),
                    None => String::new(),
                };
                g.insert(i, Grant::Cut(host));
            }
            self.proxies.remove(&i);
            tracing::warn!(sensor = %self.name(i), "dead link: {}", dead.why);
            let mut event = serde_json::json!({"event": "dead-link", "sensor": self.name(i),
                "message": dead.message, "why": dead.why, "late_ms": dead.late.as_millis() as u64,
                "bound_ms": dead.bound.as_millis() as u64, "unix_ns": wire_now_ns()});
            if let Some(seq) = dead.missing {
                event["missing_seq"] = serde_json::json!(seq);
            }
            emit(&event);
            emit(
                &serde_json::json!({"event": "lost", "sensor": self.name(i), "unix_ns": wire_now_ns()}),
            );
        }
    }

    /// Messages of remote sensors: admitted ones answer questions and are
    /// delivered (hellos held until they may be).
    fn on_data(&mut self, key: &str, bytes: &[u8]) -> Result<(), BridgeError> {
        let admitted = self.inbound.receive(&mut self.admission, key, bytes);
        let now = Instant::now();
        for m in &admitted {
            self.questions
                .delivered(m.message.header().sender as usize, &m.message, now);
        }
        if !admitted.is_empty()
            && let Ok(mut h) = self.heard.lock()
        {
            for m in &admitted {
                h.insert(m.message.header().sender as usize, now);
            }
        }
        for m in admitted {
            if m.service == ServiceId::Hello {
                self.said_hello.insert(m.message.header().sender as usize);
                self.hellos.push(m);
            } else {
                self.inbound.deliver(m, self.counters)?;
            }
        }
        Ok(())
    }

    /// A remote sensor's token came or went: its proxy follows, unless the
    /// sensor is closed for the rest of the run.
    fn on_alive(&mut self, key: &str, alive: bool) -> Result<(), BridgeError> {
        let Some(i) = key.rsplit('/').next().and_then(|x| x.parse::<usize>().ok()) else {
            return Ok(());
        };
        if !self.remote.contains(&i) {
            return Ok(());
        }
        if !alive {
            self.questions.forget(i);
        }
        // A sensor closed for the rest of the run (its host refused
        // for not reading, or cut as a dead link, whichever came
        // first) stays closed: a token back after Zenoh reconnected
        // its host is named and ignored.
        match grant_of(self.grants, i) {
            Some(Grant::Refused(host)) => {
                if self.proxies.remove(&i).is_some() {
                    tracing::warn!(sensor = %self.name(i), host, "remote sensor lost: its host was closed for not reading");
                    emit(&serde_json::json!({"event": "lost", "sensor": self.name(i),
                        "unix_ns": wire_now_ns()}));
                } else if alive {
                    tracing::warn!(sensor = %self.name(i), host, "a host refused for not reading is back: ignored");
                }
                return Ok(());
            }
            Some(Grant::Cut(host)) => {
                if alive {
                    tracing::warn!(sensor = %self.name(i), host, "a sensor cut as a dead link is back: ignored");
                }
                return Ok(());
            }
            _ if self.cut.contains(&i) => return Ok(()),
            _ => {}
        }
        if alive && !self.proxies.contains_key(&i) {
            self.proxies
                .insert(i, wire::create_node(self.run, &sensor_node_name(i))?);
            tracing::info!(sensor = %self.name(i), "remote sensor alive");
        } else if !alive && self.proxies.remove(&i).is_some() {
            tracing::info!(sensor = %self.name(i), "remote sensor lost (host gone, link cut, or run over)");
            emit(&serde_json::json!({"event": "lost", "sensor": self.name(i),
                "unix_ns": wire_now_ns()}));
        }
        Ok(())
    }

    /// A sensor host claims a sensor: granted to the first host that claims
    /// it, refused otherwise; the answer goes through the answerers.
    fn on_claim(&mut self, q: zenoh::query::Query, answers: &std::sync::mpsc::Sender<Answer>) {
        let payload = q
            .payload()
            .map(|p| String::from_utf8_lossy(&p.to_bytes()).into_owned())
            .unwrap_or_default();
        let (zid, protocol) = parse_claim(&payload);
        let zid = zid.to_string();
        if let Some(why) = other_protocol(Some(LINK_PROTOCOL), protocol) {
            // Its messages would not be read as it sent them.
            tracing::warn!(key = %q.key_expr(), zid, "refused a claim: {why}");
            let _ = answers.send((q, Err(why)));
            return;
        }
        let verdict = match parse_join_key(self.run.as_str(), q.key_expr().as_str()) {
            Some((i, host)) => match grant_of(self.grants, i) {
                Some(Grant::Refused(_) | Grant::Cut(_)) => Err(None),
                Some(Grant::Host(h)) if h != host => Err(Some(
                    self.admission.refuse(crate::admit::Refusal::DuplicateHost),
                )),
                _ => self
                    .admission
                    .claim(i, &zid)
                    .map(|()| (i, host.to_string()))
                    .map_err(Some),
            },
            None => Err(Some(
                self.admission.refuse(crate::admit::Refusal::UnknownKey),
            )),
        };
        let key = q.key_expr().clone();
        let answer = match verdict {
            Ok((i, host)) => {
                tracing::info!(sensor = %self.name(i), host, zid, "sensor granted");
                if let Ok(mut g) = self.grants.lock() {
                    g.entry(i).or_insert(Grant::Host(host));
                }
                Ok(())
            }
            Err(None) => {
                tracing::warn!(key = %key, zid, "refused a claim of a sensor closed for the rest of the run");
                Err("this sensor is closed for the rest of the run (its host stopped reading, or its link was cut as dead)".to_string())
            }
            Err(Some(r)) => {
                tracing::warn!(key = %key, zid, reason = r.name(), "refused a claim");
                Err(format!(
                    "{} ({})",
                    match r {
                        crate::admit::Refusal::DuplicateHost =>
                            "another host serves this sensor in this run",
                        _ => "this host may not serve this sensor in this run",
                    },
                    r.name()
                ))
            }
        };
        // Answered by the answerers: a reply waits while the
        // querier's queue is full (a reply takes the query's
        // congestion control, the querier's choice), and this loop
        // carries every remote sensor's uplink.
        let _ = answers.send((q, answer));
    }
}

/// A claim's answer: granted, or refused with why.
type Answer = (zenoh::query::Query, Result<(), String>);

/// How many claims may be answered at once. A reply (and the final response
/// a dropped query sends) waits while its querier's queue is full, at most
/// until Zenoh closes that querier ([`crate::session::STALLED_PEER_CLOSE`]):
/// a host that stopped reading holds one answerer per claim it sent in
/// those seconds, and the others answer everyone else.
const ANSWERERS: usize = 8;

/// The threads that answer claims, off the agent host's loop (which carries
/// every remote sensor's uplink): [`ANSWERERS`] of them take answers from
/// one queue, so one reply to a stalled querier never holds up the rest.
fn answerers() -> (
    std::sync::mpsc::Sender<Answer>,
    Vec<std::thread::JoinHandle<()>>,
) {
    let (tx, rx) = std::sync::mpsc::channel::<Answer>();
    let rx = std::sync::Arc::new(std::sync::Mutex::new(rx));
    let threads = (0..ANSWERERS)
        .map(|_| {
            let rx = std::sync::Arc::clone(&rx);
            std::thread::spawn(move || {
                loop {
                    // The lock is held only to take the next answer.
                    let next = match rx.lock() {
                        Ok(rx) => rx.recv(),
                        Err(_) => return,
                    };
                    let Ok((q, answer)) = next else { return };
                    let key = q.key_expr().clone();
                    let r = match answer {
                        Ok(()) => q.reply(key, "granted").wait(),
                        Err(why) => q.reply_err(why).wait(),
                    };
                    if let Err(e) = r {
                        tracing::debug!("a claim's answer was not sent: {e}");
                    }
                }
            })
        })
        .collect();
    (tx, threads)
}

/// The question a downlink message asks its sensor (a closing threshold's
/// kind is read from its bytes).
fn question_of(s: ServiceId, h: &etp_runtime::wire::Header, bytes: &[u8]) -> Option<Question> {
    let kind = match s {
        ServiceId::Threshold(_) => {
            match etp_runtime::recording::Encoding::Bincode.decode(&s.topic(), bytes) {
                Ok(etp_runtime::recording::Recorded::Threshold(t)) => Some(t.kind),
                _ => None,
            }
        }
        _ => None,
    };
    Question::of_downlink(s, h, kind)
}

/// A remote sensor found a dead link by the bound on waits.
struct DeadLink {
    sensor: usize,
    /// The message that never came, in words.
    message: String,
    why: String,
    late: Duration,
    bound: Duration,
    /// A gap's missing sequence number.
    missing: Option<u32>,
}

/// The oldest wait on a sensor (not cut yet) that passed the bound: an
/// unanswered question, or a gap holding the sensor's later messages.
fn overdue(
    questions: &mut Questions,
    admission: &mut Admission,
    cut: &BTreeSet<usize>,
) -> Option<DeadLink> {
    let now = Instant::now();
    let bound = questions.bound().wait();
    if let Some(g) = admission
        .gaps(now, bound)
        .filter(|g| !cut.contains(&g.sensor))
    {
        let (s, h) = g.first_held;
        return Some(DeadLink {
            sensor: g.sensor,
            message: format!("message {} (sequence number)", g.missing),
            why: format!(
                "its message with sequence number {} never came; {} later message(s) waited {} ms for it (the first: {} of episode {} leg {} step {})",
                g.missing,
                g.held,
                g.waited.as_millis(),
                s.topic(),
                h.episode,
                h.leg,
                h.step
            ),
            late: g.waited,
            bound,
            missing: Some(g.missing),
        });
    }
    let o = questions
        .overdue(now)
        .filter(|o| !cut.contains(&o.sensor))?;
    Some(DeadLink {
        sensor: o.sensor,
        message: o.question.to_string(),
        why: format!(
            "its {} never came: waited {} ms (bound {} ms)",
            o.question,
            o.waited.as_millis(),
            bound.as_millis()
        ),
        late: o.waited,
        bound,
        missing: None,
    })
}

fn refused_sensors(grants: &Grants) -> Vec<usize> {
    grants
        .lock()
        .map(|g| {
            g.iter()
                .filter(|(_, g)| matches!(g, Grant::Refused(_)))
                .map(|(&i, _)| i)
                .collect()
        })
        .unwrap_or_default()
}

fn grant_of(grants: &Grants, sensor: usize) -> Option<Grant> {
    grants.lock().ok()?.get(&sensor).cloned()
}

fn wire_now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}
