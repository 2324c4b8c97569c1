//! Service names, the per-run iceoryx2 configuration, the one function that
//! sets every service's limits, and node liveness.

use super::WireError;
use iceoryx2::config::Config;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{event, publish_subscribe};
use std::fmt::Debug;
use std::path::PathBuf;

/// Folder under which every run keeps its iceoryx2 root
/// (`<private base>/iox2/<run-id>/`, see [`super::private`]): per user, mode 0700.
pub fn root_base() -> PathBuf {
    super::private::base_path().join("iox2")
}

/// How long a process waits for the coordinator to subscribe to `hello`.
pub const HELLO_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(30);

/// Event id the iceoryx2 cleanup emits when a notifier's process died.
pub const DEAD_NOTIFIER_EVENT: usize = 200;

/// A run id: 1–40 characters of `[a-z0-9-]`. It names the services
/// (`etp/<run-id>/…`), the shared-memory prefix and the root folder, so two
/// runs never see each other.
///
/// A run spanning hosts has one id everywhere (it is in every header), and
/// each host its own iceoryx2 domain; two hosts' domains on one machine
/// (`etp sensor-host` beside `etp run`) are kept apart by [`IPC_DOMAIN_ENV`],
/// which suffixes the prefix and root folder, never the id or its tag.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct RunId {
    id: String,
    domain: Option<String>,
}

/// Environment variable naming the iceoryx2 domain of this host's part of a
/// run (`[a-z0-9-]`, set by `etp sensor-host` for itself and its sensors).
pub const IPC_DOMAIN_ENV: &str = "ETP_IPC_DOMAIN";

fn valid_id(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 40
        && s.bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
}

impl RunId {
    /// The id `s` in this process's domain ([`IPC_DOMAIN_ENV`], if set).
    pub fn new(s: &str) -> Result<Self, WireError> {
        let domain = std::env::var(IPC_DOMAIN_ENV).ok().filter(|d| !d.is_empty());
        Self::in_domain(s, domain.as_deref())
    }

    /// The id `s` in iceoryx2 domain `domain` (`None`: the default one).
    pub fn in_domain(s: &str, domain: Option<&str>) -> Result<Self, WireError> {
        if !valid_id(s) {
            return Err(WireError::RunId(s.to_string()));
        }
        if let Some(d) = domain
            && !valid_id(d)
        {
            return Err(WireError::RunId(format!("{s} (domain `{d}`)")));
        }
        Ok(Self {
            id: s.to_string(),
            domain: domain.map(str::to_string),
        })
    }

    /// The run of a root folder name (`<id>` or `<id>.<domain>`).
    pub fn from_folder(name: &str) -> Result<Self, WireError> {
        match name.split_once('.') {
            Some((id, d)) => Self::in_domain(id, Some(d)),
            None => Self::in_domain(name, None),
        }
    }

    /// A fresh id from the clock and the process id.
    pub fn generate() -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        let mixed = etp_shared::rng::mix64(nanos ^ (u64::from(std::process::id()) << 32));
        Self {
            id: format!("r{:012x}", mixed & 0xFFFF_FFFF_FFFF),
            domain: std::env::var(IPC_DOMAIN_ENV).ok().filter(|d| valid_id(d)),
        }
    }

    pub fn as_str(&self) -> &str {
        &self.id
    }

    /// The 64-bit tag carried in every [`super::Header`] (of the id only:
    /// the same on every host of the run).
    pub fn tag(&self) -> u64 {
        self.id.bytes().fold(0x45_54_50_u64, |h, b| {
            etp_shared::rng::mix64(h ^ u64::from(b))
        })
    }

    fn local_name(&self) -> String {
        match &self.domain {
            Some(d) => format!("{}.{d}", self.id),
            None => self.id.clone(),
        }
    }

    /// Shared-memory file prefix, with the user's id (two users' runs of
    /// one id never meet in /dev/shm; `_` and `.` cannot occur in an id, so
    /// no prefix of one run or domain is a prefix of another's).
    pub fn shm_prefix(&self) -> String {
        format!("etp_u{}_{}_", super::private::uid(), self.local_name())
    }

    /// The run's iceoryx2 root folder.
    pub fn root_dir(&self) -> PathBuf {
        root_base().join(self.local_name())
    }
}

impl std::fmt::Display for RunId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.id)
    }
}

/// The iceoryx2 configuration of a run: its own prefix and root path, built in
/// code (no config file is read, whatever the working directory).
pub fn config(run: &RunId) -> Result<Config, WireError> {
    // The root lives in the user's private folder: checked before use.
    super::private::sub("iox2")?;
    let mut cfg = Config::default();
    cfg.global.prefix = FileName::new(run.shm_prefix().as_bytes())
        .map_err(|e| WireError::Config(format!("prefix: {e:?}")))?;
    let root = format!("{}/", run.root_dir().display());
    let path =
        Path::new(root.as_bytes()).map_err(|e| WireError::Config(format!("root {root}: {e:?}")))?;
    cfg.global.set_root_path(&path);
    Ok(cfg)
}

/// Every service of a run (DESIGN.md "Runtime"). Per-sensor services keep
/// idle sensors asleep: the agent wakes only the serving sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ServiceId {
    /// coordinator → agent: start episode / stop.
    Control,
    /// coordinator → sensor i (and the agent, which reads every sensor's):
    /// open / close a leg of sensor i with δ, stop. One service per sensor,
    /// so nothing is ever overwritten: an idle sensor's buffer only holds
    /// the few messages of legs it serves.
    Threshold(usize),
    /// agent → sensor i: true state.
    Truth(usize),
    /// agent → sensor i: its belief at the start of a leg i serves (radio).
    Handover(usize),
    /// sensors → agent: transmitted measurements (costed).
    Measurement,
    /// sensors → agent: slot closed.
    Slot,
    /// agent → coordinator: decision point reached.
    Waypoint,
    /// agent → coordinator: episode ended.
    Outcome,
    /// sensors → coordinator: per-leg energy ledger.
    Ledger,
    /// every process → coordinator: ready.
    Hello,
    /// event: wakes the agent.
    AgentWake,
    /// event: wakes the coordinator.
    CoordinatorWake,
    /// event: wakes sensor i.
    SensorWake(usize),
}

impl ServiceId {
    /// The service name `etp/<run-id>/<topic>`.
    pub fn name(&self, run: &RunId) -> String {
        format!("etp/{run}/{}", self.topic())
    }

    /// The service's name within its run (also its recording's channel
    /// topic): `control`, `sensor/3/truth`, …
    pub fn topic(&self) -> String {
        match self {
            Self::Control => "control".to_string(),
            Self::Threshold(i) => format!("sensor/{i}/threshold"),
            Self::Truth(i) => format!("sensor/{i}/truth"),
            Self::Handover(i) => format!("sensor/{i}/handover"),
            Self::Measurement => "measurement".to_string(),
            Self::Slot => "slot".to_string(),
            Self::Waypoint => "waypoint".to_string(),
            Self::Outcome => "outcome".to_string(),
            Self::Ledger => "ledger".to_string(),
            Self::Hello => "hello".to_string(),
            Self::AgentWake => "agent/wake".to_string(),
            Self::CoordinatorWake => "coordinator/wake".to_string(),
            Self::SensorWake(i) => format!("sensor/{i}/wake"),
        }
    }

    /// The wake-up event its reader is notified on after a publication
    /// (itself for an event). `replay --publish` notifies the same events as
    /// the live processes did, so observers (the recorder) wake alike.
    pub fn reader_wake(self) -> Self {
        match self {
            Self::Control | Self::Measurement | Self::Slot => Self::AgentWake,
            Self::Threshold(i) | Self::Truth(i) | Self::Handover(i) => Self::SensorWake(i),
            Self::Waypoint | Self::Outcome | Self::Ledger | Self::Hello => Self::CoordinatorWake,
            e @ (Self::AgentWake | Self::CoordinatorWake | Self::SensorWake(_)) => e,
        }
    }

    /// Every wake-up event of a run: every publication is followed by a
    /// notification on one of them, so an observer (the recorder) listening
    /// to all of them wakes whenever there is something to read.
    pub fn all_events(sensors: usize) -> Vec<Self> {
        let mut v = vec![Self::AgentWake, Self::CoordinatorWake];
        v.extend((0..sensors).map(Self::SensorWake));
        v
    }

    /// Every publish-subscribe service of a run with `sensors` sensors (what a
    /// recorder subscribes to).
    pub fn all_pubsub(sensors: usize) -> Vec<Self> {
        let mut v = vec![
            Self::Control,
            Self::Measurement,
            Self::Slot,
            Self::Waypoint,
            Self::Outcome,
            Self::Ledger,
            Self::Hello,
        ];
        for i in 0..sensors {
            v.push(Self::Threshold(i));
            v.push(Self::Truth(i));
            v.push(Self::Handover(i));
        }
        v
    }
}

/// The limits of one service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    pub max_publishers: usize,
    pub max_subscribers: usize,
    pub max_nodes: usize,
    /// Buffer of the run's own subscribers.
    pub buffer: usize,
    /// Buffer of an observer's (the recorder's) subscriber; the service's
    /// maximum is the larger of the two.
    pub observer_buffer: usize,
    pub history: usize,
    /// Off for every service that carries data, control or accounting: a
    /// full buffer (a slow, paused or lagging reader, the recorder included)
    /// makes the publisher wait instead of overwriting an unread sample. On
    /// only for the wake-up events, which carry nothing.
    pub safe_overflow: bool,
}

/// Buffer of the recorder's subscribers (it drains whenever a wake-up event fires).
const OBSERVER_BUFFER: usize = 512;

/// Extra ports and nodes every service allows beyond the run's own processes:
/// a recorder and a replayer.
const OBSERVERS: usize = 2;

/// THE limits table: every process opens every service through [`open_pubsub`]
/// / [`open_event`], which take their limits from here, so whichever process
/// creates a service first, it has the same QoS (the iceoryx2 defaults —
/// 2 publishers, 20 nodes, 16 notifiers — fail at 32 sensors).
pub fn limits(service: ServiceId, sensors: usize) -> Limits {
    let nodes = sensors + 2 + OBSERVERS;
    let one_to_one = |buffer| Limits {
        max_publishers: 1 + OBSERVERS,
        max_subscribers: 1 + OBSERVERS,
        max_nodes: nodes,
        buffer,
        observer_buffer: OBSERVER_BUFFER,
        history: 0,
        safe_overflow: false,
    };
    let many_to_one = |buffer| Limits {
        max_publishers: sensors + OBSERVERS,
        max_subscribers: 1 + OBSERVERS,
        max_nodes: nodes,
        buffer,
        observer_buffer: OBSERVER_BUFFER,
        history: 0,
        safe_overflow: false,
    };
    match service {
        ServiceId::Control => one_to_one(8),
        ServiceId::Truth(_) | ServiceId::Handover(_) => one_to_one(8),
        ServiceId::Waypoint | ServiceId::Outcome => one_to_one(16),
        ServiceId::Measurement | ServiceId::Slot => many_to_one(16),
        // Ledgers are drained at leg boundaries; a generous buffer per sensor.
        ServiceId::Ledger => many_to_one(256),
        // Read by its sensor and by the agent; at most an OPEN and a CLOSE
        // per leg the sensor serves are ever outstanding.
        ServiceId::Threshold(_) => Limits {
            max_subscribers: 2 + OBSERVERS,
            ..one_to_one(16)
        },
        // Late subscribers (the coordinator starts in parallel) get the history.
        ServiceId::Hello => Limits {
            max_publishers: sensors + 2 + OBSERVERS,
            max_subscribers: 1 + OBSERVERS,
            max_nodes: nodes,
            buffer: sensors + 4,
            observer_buffer: sensors + 4,
            history: 1,
            safe_overflow: false,
        },
        ServiceId::AgentWake | ServiceId::CoordinatorWake => Limits {
            max_publishers: sensors + 2 + OBSERVERS,
            max_subscribers: 1 + OBSERVERS,
            max_nodes: nodes,
            buffer: 0,
            observer_buffer: 0,
            history: 0,
            safe_overflow: true,
        },
        ServiceId::SensorWake(_) => Limits {
            max_publishers: 2 + OBSERVERS,
            max_subscribers: 1 + OBSERVERS,
            max_nodes: nodes,
            buffer: 0,
            observer_buffer: 0,
            history: 0,
            safe_overflow: true,
        },
    }
}

/// A publish-subscribe service's factory.
pub type PubSub<T> = publish_subscribe::PortFactory<ipc::Service, T, ()>;
/// An event service's factory.
pub type Event = event::PortFactory<ipc::Service>;

/// Open (or create) a publish-subscribe service with the limits of [`limits`].
pub fn open_pubsub<T: Debug + ZeroCopySend>(
    node: &Node<ipc::Service>,
    run: &RunId,
    service: ServiceId,
    sensors: usize,
) -> Result<PubSub<T>, WireError> {
    let l = limits(service, sensors);
    let name = service.name(run);
    let sname =
        ServiceName::new(&name).map_err(|e| WireError::Service(name.clone(), format!("{e:?}")))?;
    node.service_builder(&sname)
        .publish_subscribe::<T>()
        .max_publishers(l.max_publishers)
        .max_subscribers(l.max_subscribers)
        .max_nodes(l.max_nodes)
        .subscriber_max_buffer_size(l.buffer.max(l.observer_buffer))
        .history_size(l.history)
        .enable_safe_overflow(l.safe_overflow)
        .open_or_create()
        .map_err(|e| WireError::Service(name, format!("{e:?}")))
}

/// Open (or create) an event service with the limits of [`limits`].
pub fn open_event(
    node: &Node<ipc::Service>,
    run: &RunId,
    service: ServiceId,
    sensors: usize,
) -> Result<Event, WireError> {
    let l = limits(service, sensors);
    let name = service.name(run);
    let sname =
        ServiceName::new(&name).map_err(|e| WireError::Service(name.clone(), format!("{e:?}")))?;
    node.service_builder(&sname)
        .event()
        .max_notifiers(l.max_publishers)
        .max_listeners(l.max_subscribers)
        .max_nodes(l.max_nodes)
        .notifier_dead_event(EventId::new(DEAD_NOTIFIER_EVENT))
        .open_or_create()
        .map_err(|e| WireError::Service(name, format!("{e:?}")))
}

/// Node names of the run's processes (used for liveness checks).
pub const COORDINATOR_NODE: &str = "etp-coordinator";
pub const AGENT_NODE: &str = "etp-agent";
/// Node name of the recorder (`etp run --record`), started before the others.
pub const RECORDER_NODE: &str = "etp-recorder";
/// Node name of sensor `i`.
pub fn sensor_node_name(i: usize) -> String {
    format!("etp-sensor-{i}")
}

/// Create a node of a run. iceoryx2 signal handling is off: the processes poll
/// their own termination flag (see the binaries), and tokio owns signals in `etp`.
pub fn create_node(run: &RunId, name: &str) -> Result<Node<ipc::Service>, WireError> {
    let cfg = config(run)?;
    let nname = NodeName::new(name).map_err(|e| WireError::Node(format!("name {name}: {e:?}")))?;
    let node = NodeBuilder::new()
        .name(&nname)
        .config(&cfg)
        .create::<ipc::Service>()
        .map_err(|e| WireError::Node(format!("{e:?}")))?;
    // Installs iceoryx2's SIGINT/SIGTERM handler now (it is lazy): until a
    // process's first wait, a SIGTERM would otherwise kill it outright.
    super::termination_requested(&node);
    Ok(node)
}

/// What the node list says about a named node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Liveness {
    Alive,
    /// Its process died (its stale resources were removed just now).
    Dead,
    /// No such node (never started, or already cleaned up).
    Missing,
}

/// Look a node up by name in the run's node list; a dead node's stale
/// resources are removed on the way (so the peers' counts drop and listeners
/// get [`DEAD_NOTIFIER_EVENT`]).
pub fn liveness(cfg: &Config, name: &str) -> Liveness {
    node_state(cfg, name, true)
}

/// [`liveness`] without the cleanup: the verdict only, as fast as the node
/// list can give it (the cleanup of a dead node's ports can take tens of
/// milliseconds; call [`remove_dead_nodes`] afterwards).
pub fn peek_liveness(cfg: &Config, name: &str) -> Liveness {
    node_state(cfg, name, false)
}

fn node_state(cfg: &Config, name: &str, cleanup: bool) -> Liveness {
    let named = |d: &Option<iceoryx2::node::NodeDetails>| {
        d.as_ref().is_some_and(|d| d.name().as_str() == name)
    };
    let mut found = Liveness::Missing;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        match state {
            NodeState::Alive(view) if named(view.details()) => found = Liveness::Alive,
            NodeState::Dead(view) if named(view.details()) => {
                found = Liveness::Dead;
                if cleanup {
                    let _ = view.try_remove_stale_resources();
                }
            }
            _ => return CallbackProgression::Continue,
        }
        CallbackProgression::Stop
    });
    found
}

/// Remove what dead nodes of a run left behind; returns how many were removed.
pub fn remove_dead_nodes(cfg: &Config) -> usize {
    let mut removed = 0;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        if let NodeState::Dead(view) = state
            && view.try_remove_stale_resources().is_ok()
        {
            removed += 1;
        }
        CallbackProgression::Continue
    });
    removed
}

/// Number of live nodes of a run.
pub fn alive_nodes(cfg: &Config) -> usize {
    let mut alive = 0;
    let _ = Node::<ipc::Service>::list(cfg, |state| {
        if let NodeState::Alive(_) = state {
            alive += 1;
        }
        CallbackProgression::Continue
    });
    alive
}

/// A publisher on a run's service.
pub type Pub<T> = iceoryx2::port::publisher::Publisher<ipc::Service, T, ()>;
/// A subscriber on a run's service.
pub type Sub<T> = iceoryx2::port::subscriber::Subscriber<ipc::Service, T, ()>;
/// A listener (wake-ups) on a run's event service.
pub type Listener = iceoryx2::port::listener::Listener<ipc::Service>;
/// A notifier on a run's event service.
pub type Notifier = iceoryx2::port::notifier::Notifier<ipc::Service>;

/// The run's ports are opened through these, all with the limits of [`limits`].
pub struct Ports<'a> {
    pub node: &'a Node<ipc::Service>,
    pub run: &'a RunId,
    pub sensors: usize,
}

impl Ports<'_> {
    pub fn publisher<T: Debug + ZeroCopySend>(&self, s: ServiceId) -> Result<Pub<T>, WireError> {
        open_pubsub::<T>(self.node, self.run, s, self.sensors)?
            .publisher_builder()
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
    }

    pub fn subscriber<T: Debug + ZeroCopySend>(&self, s: ServiceId) -> Result<Sub<T>, WireError> {
        self.subscriber_with_buffer(s, limits(s, self.sensors).buffer)
    }

    /// A subscriber with the observer's (recorder's) buffer.
    pub fn observer<T: Debug + ZeroCopySend>(&self, s: ServiceId) -> Result<Sub<T>, WireError> {
        self.subscriber_with_buffer(s, limits(s, self.sensors).observer_buffer)
    }

    fn subscriber_with_buffer<T: Debug + ZeroCopySend>(
        &self,
        s: ServiceId,
        buffer: usize,
    ) -> Result<Sub<T>, WireError> {
        open_pubsub::<T>(self.node, self.run, s, self.sensors)?
            .subscriber_builder()
            .buffer_size(buffer)
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
    }

    pub fn listener(&self, s: ServiceId) -> Result<Listener, WireError> {
        open_event(self.node, self.run, s, self.sensors)?
            .listener_builder()
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
    }

    pub fn notifier(&self, s: ServiceId) -> Result<Notifier, WireError> {
        open_event(self.node, self.run, s, self.sensors)?
            .notifier_builder()
            .create()
            .map_err(|e| WireError::Port(s.name(self.run), format!("{e:?}")))
    }
}

/// Announce a process to the coordinator: wait (bounded, sleeping) until the
/// coordinator's `hello` subscriber exists, then send `hello` and wake it.
/// Samples sent before a subscriber exists would be lost, and the processes
/// start in parallel. Returns the publisher (keep it alive).
///
/// `coordinator_wake` is the caller's own notifier on `coordinator/wake`: a
/// second, temporary one per process would exceed the service's notifier
/// limit when several processes say hello at once (seen under load:
/// `ExceedsMaxSupportedNotifiers` on a fresh run).
pub fn say_hello(
    ports: &Ports<'_>,
    coordinator_wake: &Notifier,
    hello: super::messages::to_coordinator::Hello,
    timeout: std::time::Duration,
) -> Result<Pub<super::messages::to_coordinator::Hello>, WireError> {
    let factory = open_pubsub::<super::messages::to_coordinator::Hello>(
        ports.node,
        ports.run,
        ServiceId::Hello,
        ports.sensors,
    )?;
    let publisher = factory
        .publisher_builder()
        .create()
        .map_err(|e| WireError::Port(ServiceId::Hello.name(ports.run), format!("{e:?}")))?;
    // A recorder (started before everyone) subscribes too: wait for one more.
    let cfg = config(ports.run)?;
    let needed = 1 + usize::from(liveness(&cfg, RECORDER_NODE) == Liveness::Alive);
    let start = std::time::Instant::now();
    while factory.dynamic_config().number_of_subscribers() < needed {
        if start.elapsed() >= timeout {
            return Err(WireError::Port(
                ServiceId::Hello.name(ports.run),
                format!("no coordinator subscribed within {timeout:?}"),
            ));
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    publisher
        .send_copy(hello)
        .map_err(|e| WireError::Port(ServiceId::Hello.name(ports.run), format!("{e:?}")))?;
    // A subscriber can be counted above before the publisher's connection to
    // it exists; the hello then waits in the history (size 1) until the next
    // connection update, which a process that sends nothing more never does
    // (seen under load: a coordinator missing three sensors' hellos). Update
    // the connections for a moment: a new connection gets the history, an
    // existing one gets nothing twice.
    {
        use iceoryx2::port::update_connections::UpdateConnections;
        for _ in 0..30 {
            let _ = publisher.update_connections();
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
    }
    coordinator_wake.notify().map_err(|e| {
        WireError::Port(ServiceId::CoordinatorWake.name(ports.run), format!("{e:?}"))
    })?;
    Ok(publisher)
}
