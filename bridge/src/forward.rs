//! The two directions of a bridge. Outbound: the iceoryx2 services a remote
//! reader needs, drained on their readers' wake-up events in causal order
//! and put on Zenoh in the link encoding (the sender's time, then the
//! payload in bincode, as format-4 recordings held payloads: fixed sizes for
//! the traffic counts; `wire::stamp::link_frame`). Inbound: Zenoh samples decoded
//! and published on the local iceoryx2 service with their sender's time, then its reader's wake-up
//! event notified, exactly as a local publisher would.
//!
//! Both count what they carry per sensor (`wire::traffic`): the link's
//! measured traffic, radio and plumbing, in each direction.

use crate::BridgeError;
use crate::admit::{Admission, Admitted, Refusal};
use crate::session::{PROBE_AFTER, PROBE_BYTES, down_key, parse_data_key, probe_key, up_key};
use etp_runtime::recording::{
    self,
    ports::{DecodedPublisher, EncodedSubscriber, decoded_publisher, encoded_subscriber},
};
use etp_runtime::wire::stamp::{link_frame, link_unframe};
use etp_runtime::wire::traffic::{Direction, LinkTraffic};
use etp_runtime::wire::{self, Header, Notifier, Ports, RunId, ServiceId, Waiter, Wake};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;

/// Per-sensor link traffic, shared by both directions.
pub type Counters = Arc<Mutex<BTreeMap<usize, LinkTraffic>>>;

/// The sensor a message of `s` belongs to: a per-sensor service's own, or
/// the sender of a shared one (sensors send with their index).
fn sensor_of(s: ServiceId, h: &Header) -> usize {
    s.sensor().unwrap_or(h.sender as usize)
}

fn count(counters: &Counters, s: ServiceId, h: &Header, bytes: usize) {
    if let Ok(mut c) = counters.lock() {
        c.entry(sensor_of(s, h))
            .or_default()
            .add(s, 1, bytes as u64);
    }
}

/// A put that took at least this long was held up by a peer that stopped
/// reading (its Zenoh queue full): counted per sensor as a stall.
pub const STALL: Duration = Duration::from_millis(250);

/// A put that took this long waited out Zenoh's wait for a full queue
/// ([`crate::session::STALLED_PEER_CLOSE`]): Zenoh closed the peer that
/// stopped reading.
pub const CLOSED: Duration = crate::session::STALLED_PEER_CLOSE;

/// Puts held up by a stalled peer, per sensor (the record `etp run` reads
/// from the `stalled` line).
pub use etp_runtime::report::Stall;

pub type Stalls = Arc<Mutex<BTreeMap<usize, Stall>>>;

/// Who a remote sensor's downlink goes to (agent host).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Grant {
    /// The host the sensor was granted to at join (its name: with TLS, its
    /// certificate's).
    Host(String),
    /// That host kept a put waiting until Zenoh closed it: it is refused for
    /// the rest of the run (the sensor's downlink goes nowhere, its token
    /// and claims are ignored), so it cannot hold the run up again.
    Refused(String),
    /// The sensor was cut as a dead link: a question of the run went
    /// unanswered, or a gap in its messages was held, past the bound
    /// ([`crate::answers`]). Nothing more goes down to it or comes up from it.
    Cut(String),
}

/// Per remote sensor, its [`Grant`] (none until a host claimed it), shared by
/// the agent host's loop and its outbound threads.
pub type Grants = Arc<Mutex<BTreeMap<usize, Grant>>>;

/// Per remote sensor, when the agent host last admitted a message from it
/// (agent host: its loop writes, the outbound threads read it to know
/// whether the sensor's host owes an answer).
pub type Heard = Arc<Mutex<BTreeMap<usize, Instant>>>;

/// Refusals logged per reason (all are counted).
const LOGGED_REFUSALS: u64 = 10;

/// How often the outbound loop looks at its stop flag without a wake-up.
const TICK: Duration = Duration::from_millis(100);

/// What the outbound direction carries.
pub struct Outbound {
    pub run: RunId,
    pub sensors: usize,
    /// Services in causal order (a message is put after those it depends on).
    pub services: Vec<ServiceId>,
    /// The wake-up events their publishers notify.
    pub events: Vec<ServiceId>,
    /// `true` on the agent host.
    pub down: bool,
    /// The remote sensors this link carries (up keys name their sender).
    pub remote: Vec<usize>,
    /// Down: who each sensor's downlink goes to ([`Outbound::to_grants`]).
    pub grants: Grants,
    /// Down: the host a stalled put waited for is known (TLS: only the
    /// granted host may subscribe to its keys), so it is refused after Zenoh
    /// closed it.
    pub attributed: bool,
    /// Down: when each sensor was last heard from ([`Outbound::probing`]).
    pub heard: Option<Heard>,
}

impl Outbound {
    /// What a bridge carries in `direction` for the remote sensors `remote`:
    /// the catalogue's forwarded rows in causal rank
    /// ([`ServiceId::forwarded`]) and their readers' wake-up events.
    pub fn new(run: &RunId, sensors: usize, direction: Direction, remote: &[usize]) -> Self {
        let services = ServiceId::forwarded(direction, remote);
        Self {
            run: run.clone(),
            sensors,
            events: ServiceId::wakes_of(&services),
            services,
            down: direction == Direction::Down,
            remote: remote.to_vec(),
            grants: Grants::default(),
            attributed: false,
            heard: None,
        }
    }

    /// Down: put each sensor's messages on the keys of the host `grants`
    /// names for it ([`crate::session::down_key`]); none yet or refused: the
    /// message goes nowhere. `attributed`: only that host can subscribe to
    /// its keys (TLS access control), so a put that outlasted Zenoh's wait
    /// ([`CLOSED`]) was held up by it, and it is refused from then on.
    pub fn to_grants(mut self, grants: &Grants, attributed: bool) -> Self {
        self.grants = grants.clone();
        self.attributed = attributed;
        self
    }

    /// Down: probe a granted host that owes an answer
    /// ([`crate::session::probe_key`]): when a sensor's last downlink
    /// message is [`PROBE_AFTER`] old and nothing came from the sensor
    /// since it was put, the host is sent a probe every wake-up (at most
    /// every 100 ms) until the sensor answers. A host that stopped reading
    /// then fills its queue even though the run sends it nothing more, so
    /// Zenoh closes it and (attributed) it is refused, instead of the agent
    /// waiting for its sensor for as long as its token lives.
    pub fn probing(mut self, heard: &Heard) -> Self {
        self.heard = Some(heard.clone());
        self
    }

    /// Whether `sensor`'s host owes an answer to the message put at `put`.
    fn owes(&self, sensor: usize, put: Instant) -> bool {
        let Some(heard) = &self.heard else {
            return false;
        };
        put.elapsed() >= PROBE_AFTER
            && heard
                .lock()
                .map(|h| h.get(&sensor).is_none_or(|&t| t < put))
                .unwrap_or(false)
    }

    fn grant(&self, sensor: usize) -> Option<Grant> {
        self.grants.lock().ok()?.get(&sensor).cloned()
    }

    fn refuse(&self, sensor: usize, host: String) {
        if let Ok(mut g) = self.grants.lock() {
            g.insert(sensor, Grant::Refused(host));
        }
    }

    /// [`Outbound::run`] on a thread of its own (iceoryx2 node `node_name`).
    #[allow(clippy::too_many_arguments)]
    pub fn spawn(
        self,
        node_name: String,
        session: &zenoh::Session,
        counters: &Counters,
        stalls: &Stalls,
        stop: &Arc<AtomicBool>,
        on_ready: impl FnOnce() + Send + 'static,
        on_put: impl FnMut(ServiceId, &Header, &[u8]) + Send + 'static,
    ) -> std::thread::JoinHandle<Result<(), BridgeError>> {
        let (session, counters, stalls, stop) = (
            session.clone(),
            counters.clone(),
            stalls.clone(),
            stop.clone(),
        );
        std::thread::spawn(move || {
            self.run(
                &node_name, &session, &counters, &stalls, &stop, on_ready, on_put,
            )
        })
    }

    /// Forward until `stop` (or a termination request); `on_ready` is
    /// called once every port exists, `on_put` sees every message put
    /// (service, header, payload bytes). Runs on its own thread: iceoryx2 ports stay on the
    /// thread that made them.
    ///
    /// A put blocks while a subscribed peer's queue is full (congestion
    /// control `Block`: nothing is dropped), and Zenoh closes a peer that
    /// stays full for [`crate::session::STALLED_PEER_CLOSE`]: the wait is
    /// bounded, and a put that waited [`STALL`] or more is counted in
    /// `stalls` for its sensor.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        self,
        node_name: &str,
        session: &zenoh::Session,
        counters: &Counters,
        stalls: &Stalls,
        stop: &AtomicBool,
        on_ready: impl FnOnce(),
        mut on_put: impl FnMut(ServiceId, &Header, &[u8]),
    ) -> Result<(), BridgeError> {
        let node = wire::create_node(&self.run, node_name)?;
        let ports = Ports {
            node: &node,
            run: &self.run,
            sensors: self.sensors,
        };
        let run = self.run.as_str().to_string();
        // Per service its subscriber and its Zenoh publishers: down, one
        // towards the host granted the service's sensor (declared once it is
        // granted; the key names the host and the sensor); up, one per
        // remote sensor (the key names the sender).
        type Publishers = BTreeMap<Option<usize>, zenoh::pubsub::Publisher<'static>>;
        let mut links: Vec<(ServiceId, Box<dyn EncodedSubscriber>, Publishers)> = Vec::new();
        let declare = |key: String| declare_publisher(session, key);
        for &s in &self.services {
            let sub = encoded_subscriber(&ports, s, false)?;
            let mut publishers = Publishers::new();
            if !self.down {
                for &i in &self.remote {
                    publishers.insert(Some(i), declare(up_key(&run, i, s))?);
                }
            }
            links.push((s, sub, publishers));
        }
        // Down: the host each publisher of a service puts towards.
        let mut towards: BTreeMap<ServiceId, String> = BTreeMap::new();
        // Down: per sensor, when its last message was put, and the probe
        // publisher towards its host ([`Outbound::probing`]).
        let mut last_put: BTreeMap<usize, Instant> = BTreeMap::new();
        let mut probes = Probes::new();
        let probe = zenoh::bytes::ZBytes::from(vec![0u8; PROBE_BYTES]);
        let waiter = Waiter::over(
            self.events
                .iter()
                .map(|&e| ports.listener(e))
                .collect::<Result<Vec<_>, _>>()?,
        )?;
        on_ready();
        let mut batch = Vec::new();
        loop {
            for (s, sub, publishers) in &mut links {
                let s: ServiceId = *s;
                batch.clear();
                sub.drain(recording::Encoding::Bincode, &mut batch)?;
                for (h, time, payload) in &batch {
                    let sensor = sensor_of(s, h);
                    let target = if self.down {
                        match self.grant(sensor) {
                            Some(Grant::Host(host)) => {
                                if towards.get(&s) != Some(&host) {
                                    publishers.insert(None, declare(down_key(&run, &host, s))?);
                                    towards.insert(s, host);
                                }
                                None
                            }
                            Some(Grant::Refused(_)) => {
                                publishers.clear();
                                towards.remove(&s);
                                note_dropped(stalls, sensor);
                                continue;
                            }
                            Some(Grant::Cut(_)) => {
                                publishers.clear();
                                towards.remove(&s);
                                continue;
                            }
                            // Not granted yet: nobody may read it (as a put
                            // with no subscriber).
                            None => continue,
                        }
                    } else {
                        Some(sensor)
                    };
                    let Some(publisher) = publishers.get(&target) else {
                        // Only the served sensors publish in a sensor
                        // host's own iceoryx2 domain.
                        tracing::warn!(
                            ?s,
                            sender = h.sender,
                            "a message of a sensor this link does not carry"
                        );
                        continue;
                    };
                    let bytes = link_frame(*time, payload);
                    let len = bytes.len();
                    let started = Instant::now();
                    publisher
                        .put(bytes)
                        .wait()
                        .map_err(|e| BridgeError::Zenoh(format!("put {s:?}: {e}")))?;
                    if self.down {
                        last_put.insert(sensor, started);
                    }
                    self.waited(stalls, sensor, started, towards.get(&s).cloned());
                    count(counters, s, h, len);
                    on_put(s, h, payload);
                }
            }
            self.probe_owing(session, &run, &last_put, &mut probes, &probe, stalls)?;
            self.forget_closed(&mut last_put, &mut probes);
            if stop.load(Ordering::Relaxed) {
                return Ok(());
            }
            match waiter.wait(&node, TICK)? {
                Wake::Notified { .. } | Wake::Silence => {}
                Wake::Terminate => stop.store(true, Ordering::Relaxed),
            }
        }
    }
}

/// Down: a probe publisher, and the host it puts towards, per sensor.
type Probes = BTreeMap<usize, (String, zenoh::pubsub::Publisher<'static>)>;

/// A Zenoh publisher on `key` that blocks while a peer's queue is full.
fn declare_publisher(
    session: &zenoh::Session,
    key: String,
) -> Result<zenoh::pubsub::Publisher<'static>, BridgeError> {
    session
        .declare_publisher(key.clone())
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(|e| BridgeError::Zenoh(format!("publisher {key}: {e}")))
}

impl Outbound {
    /// Down: probe the hosts that owe an answer, each through a publisher
    /// towards the host its sensor is granted to.
    fn probe_owing(
        &self,
        session: &zenoh::Session,
        run: &str,
        last_put: &BTreeMap<usize, Instant>,
        probes: &mut Probes,
        probe: &zenoh::bytes::ZBytes,
        stalls: &Stalls,
    ) -> Result<(), BridgeError> {
        for (&sensor, &put) in last_put {
            if !self.owes(sensor, put) {
                continue;
            }
            let Some(Grant::Host(host)) = self.grant(sensor) else {
                continue;
            };
            if probes.get(&sensor).is_none_or(|(h, _)| *h != host) {
                let p = declare_publisher(session, probe_key(run, &host, sensor))?;
                probes.insert(sensor, (host.clone(), p));
            }
            let Some((_, p)) = probes.get(&sensor) else {
                continue;
            };
            let started = Instant::now();
            p.put(probe.clone())
                .wait()
                .map_err(|e| BridgeError::Zenoh(format!("probe of sensor {sensor}: {e}")))?;
            self.waited(stalls, sensor, started, Some(host));
        }
        Ok(())
    }

    /// Down: a sensor refused or cut is neither timed nor probed any more.
    fn forget_closed(&self, last_put: &mut BTreeMap<usize, Instant>, probes: &mut Probes) {
        if let Some(refused) = self.grants.lock().ok().map(|g| {
            g.iter()
                .filter(|(_, g)| matches!(g, Grant::Refused(_) | Grant::Cut(_)))
                .map(|(&i, _)| i)
                .collect::<Vec<_>>()
        }) {
            for i in refused {
                last_put.remove(&i);
                probes.remove(&i);
            }
        }
    }

    /// A put (or probe) for `sensor` towards `host` that started at
    /// `started` is over: if it waited [`STALL`] or more, a stall is noted;
    /// if it waited out Zenoh's close and the wait is attributed, the host
    /// is refused.
    fn waited(&self, stalls: &Stalls, sensor: usize, started: Instant, host: Option<String>) {
        let took = started.elapsed();
        if took >= STALL {
            let refuse = self.down && self.attributed && took >= CLOSED;
            note_stall(stalls, sensor, took, host.clone(), refuse);
            if refuse && let Some(host) = host {
                self.refuse(sensor, host);
            }
        }
    }
}

fn note_stall(stalls: &Stalls, sensor: usize, took: Duration, host: Option<String>, refused: bool) {
    tracing::warn!(
        sensor,
        host = host.as_deref().unwrap_or("?"),
        ms = took.as_millis() as u64,
        "a put waited for a peer that stopped reading"
    );
    if refused {
        tracing::warn!(
            sensor,
            host = host.as_deref().unwrap_or("?"),
            "closed for not reading: the host is refused for the rest of the run"
        );
    }
    if let Ok(mut m) = stalls.lock() {
        let e = m.entry(sensor).or_default();
        e.puts += 1;
        e.longest_ms = e.longest_ms.max(took.as_millis() as u64);
        e.refused |= refused;
        if host.is_some() {
            e.host = host;
        }
    }
}

/// A message of a sensor whose host was refused: not sent, counted.
fn note_dropped(stalls: &Stalls, sensor: usize) {
    if let Ok(mut m) = stalls.lock() {
        m.entry(sensor).or_default().dropped += 1;
    }
}

/// What arrives from Zenoh (through the subscribers' callbacks).
#[derive(Debug)]
pub enum Incoming {
    Data {
        key: String,
        bytes: Vec<u8>,
    },
    /// A liveliness token appeared (`true`) or vanished.
    Alive {
        key: String,
        alive: bool,
    },
    /// A local sensor said hello (it went up the link).
    Hello(usize),
    /// A sensor host's claim of a remote sensor at join (query
    /// [`crate::session::join_key`]; its payload is the host's Zenoh id),
    /// answered by the agent host's loop.
    Claim(zenoh::query::Query),
    /// The agent host put a question to remote sensor `.0` at `.2`
    /// ([`crate::answers`]).
    Asked(usize, crate::answers::Question, Instant),
}

/// The inbound direction's local ports: one publisher and one wake-up
/// notifier per service it delivers.
pub struct Inbound {
    publishers: BTreeMap<ServiceId, Box<dyn DecodedPublisher>>,
    wakes: BTreeMap<ServiceId, Notifier>,
}

impl Inbound {
    pub fn new(ports: &Ports<'_>, services: &[ServiceId]) -> Result<Self, BridgeError> {
        let mut publishers = BTreeMap::new();
        let mut wakes = BTreeMap::new();
        for &s in services {
            publishers.insert(s, decoded_publisher(ports, s)?);
            let w = s.reader_wake();
            if let std::collections::btree_map::Entry::Vacant(e) = wakes.entry(w) {
                e.insert(ports.notifier(w)?);
            }
        }
        Ok(Self { publishers, wakes })
    }

    /// Decode a sample of `key` (not delivered yet); garbage (too short for
    /// the sender's time, or a payload that does not decode), a key of no
    /// service this end delivers, or an up key naming another sensor than
    /// the message's sender, is refused. The sender's time is any number.
    pub fn decode(&self, key: &str, bytes: &[u8]) -> Result<Admitted, Refusal> {
        let (key_sensor, topic) = parse_data_key(key).ok_or(Refusal::UnknownKey)?;
        let s = recording::service_of_topic(topic)
            .filter(|s| self.publishers.contains_key(s))
            .ok_or(Refusal::UnknownKey)?;
        let (publish_time, payload) = link_unframe(bytes).ok_or(Refusal::Malformed)?;
        let message = recording::Encoding::Bincode
            .decode(topic, payload)
            .map_err(|_| Refusal::Malformed)?;
        if let Some(i) = key_sensor
            && sensor_of(s, message.header()) != i
        {
            return Err(Refusal::WrongSender);
        }
        Ok(Admitted {
            service: s,
            message,
            publish_time,
            bytes: bytes.len(),
        })
    }

    /// Decode and check a sample: the messages now deliverable, in order.
    /// A refused one is counted in `admission`, logged (the first few of
    /// each reason, with its key) and dropped: never an error.
    pub fn receive(&self, admission: &mut Admission, key: &str, bytes: &[u8]) -> Vec<Admitted> {
        let r = match self.decode(key, bytes) {
            Ok(m) => admission.admit(m),
            Err(r) => Err(admission.refuse(r)),
        };
        r.unwrap_or_else(|r| {
            let n = admission.refused().get(&r).copied().unwrap_or(0);
            if n <= LOGGED_REFUSALS {
                tracing::warn!(
                    key,
                    bytes = bytes.len(),
                    reason = r.name(),
                    "refused a message from the link"
                );
            }
            Vec::new()
        })
    }

    /// Publish a decoded payload on its service, with its sender's time,
    /// and wake its reader; counted.
    pub fn deliver(&self, m: Admitted, counters: &Counters) -> Result<(), BridgeError> {
        let Admitted {
            service: s,
            message: r,
            publish_time,
            bytes,
        } = m;
        let h = *r.header();
        let publisher = self
            .publishers
            .get(&s)
            .ok_or_else(|| BridgeError::Protocol(format!("no publisher for {s:?}")))?;
        publisher.send_at(r, publish_time)?;
        if let Some(w) = self.wakes.get(&s.reader_wake()) {
            w.notify()
                .map_err(|e| BridgeError::Wire(format!("notify {:?}: {e:?}", s.reader_wake())))?;
        }
        count(counters, s, &h, bytes);
        Ok(())
    }
}

/// Subscribers of `data` keys and of liveliness tokens under `alive` (with
/// the tokens already there); all feed `tx`.
pub type Subscriptions = (
    Vec<zenoh::pubsub::Subscriber<()>>,
    zenoh::pubsub::Subscriber<()>,
);

/// Subscribe to the data keys `data` (one direction: only what this end
/// delivers) and to liveliness tokens under `alive`.
pub fn subscribe(
    session: &zenoh::Session,
    data: &[String],
    alive: &str,
    tx: std::sync::mpsc::Sender<Incoming>,
) -> Result<Subscriptions, BridgeError> {
    let mut data_subs = Vec::new();
    for key in data {
        let t = tx.clone();
        data_subs.push(
            session
                .declare_subscriber(key.as_str())
                .callback(move |s| {
                    let _ = t.send(Incoming::Data {
                        key: s.key_expr().to_string(),
                        bytes: s.payload().to_bytes().into_owned(),
                    });
                })
                .wait()
                .map_err(|e| BridgeError::Zenoh(format!("subscriber {key}: {e}")))?,
        );
    }
    let alive_sub = session
        .liveliness()
        .declare_subscriber(alive)
        .history(true)
        .callback(move |s| {
            let _ = tx.send(Incoming::Alive {
                key: s.key_expr().to_string(),
                alive: s.kind() == zenoh::sample::SampleKind::Put,
            });
        })
        .wait()
        .map_err(|e| BridgeError::Zenoh(format!("liveliness subscriber {alive}: {e}")))?;
    Ok((data_subs, alive_sub))
}
