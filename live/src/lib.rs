//! `etp-live`: the live view of `etp run --live`, a Foxglove WebSocket
//! server (the `foxglove` crate; it negotiates the subprotocol `foxglove.sdk.v1`).
//!
//! The run never waits for the view. The agent writes frames to a Unix
//! datagram socket non-blocking (`etp_runtime::live::LiveTap`: at most one
//! slot frame per 20 ms and one per episode end, dropped when the socket's
//! queue is full); this crate's thread reads them and logs them to the
//! Foxglove channels, whose per-client queues drop the oldest message when
//! a client is slow (the SDK's behaviour). No service of the run is opened
//! here: the iceoryx2 traffic, the counts and the report are those of a run
//! without a view.
//!
//! Topics (see [`topics`] and `docs/foxglove-live-layout.json`): `/scene`
//! (`foxglove.SceneUpdate`: obstacles, target, route with waypoints,
//! sensors; sent again every second and when a client subscribes),
//! `/agent` (`foxglove.SceneUpdate`: true position, prior mean and 3σ
//! ellipse, the serving sensor's transmission), `/outcome` (`foxglove.Log`,
//! one line per finished episode, and a warning line per flag of the
//! channel monitor), and JSON for the Plot panel: `/status`, `/outcomes`,
//! `/energy`, `/rates`, `/sensor/<name>`, and `/drift` (each flag of the
//! channel monitor once: the fields of `run --json`'s `drift[]`).

pub mod draw;
mod publish;

use etp_runtime::live::{LiveMsg, MAX_DATAGRAM};
use etp_shared::scenario::Scenario;
use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{WebSocketServer, WebSocketServerHandle};
use std::net::SocketAddr;
use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub use publish::topics;

/// The default address of `--live`.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";
/// The scene is sent again this often (a client that subscribes late gets it).
const SCENE_EVERY: Duration = Duration::from_secs(1);
/// How long the view's thread waits for a frame before looking at the clock.
const POLL: Duration = Duration::from_millis(100);

/// Why the view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    #[error(
        "--live {addr}: not a loopback address; the live view is plain WebSocket (neither \
         authenticated nor encrypted): give --insecure to serve it on {addr} anyway"
    )]
    NotLoopback { addr: SocketAddr },
    #[error("--live {addr}: cannot listen there")]
    Bind {
        addr: SocketAddr,
        source: foxglove::FoxgloveError,
    },
    #[error("--live: the view's feed socket {}", path.display())]
    Feed {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("--live: starting the view's threads")]
    Thread(#[source] std::io::Error),
}

/// The project's rule: a link is authenticated and encrypted unless the
/// user says `--insecure`. The Foxglove WebSocket is neither, so only a
/// loopback address is served without it.
pub fn check_address(addr: SocketAddr, insecure: bool) -> Result<(), LiveError> {
    if addr.ip().is_loopback() || insecure {
        Ok(())
    } else {
        Err(LiveError::NotLoopback { addr })
    }
}

/// What the view did (for the log).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ViewStats {
    /// Frames read from the feed, and datagrams that did not decode.
    pub frames: u64,
    pub undecodable: u64,
}

/// Flags a subscription for [`LiveView::wait_for_subscriber`] and asks the
/// view's thread for the scene at once.
#[derive(Default)]
struct Subscribed {
    any: Mutex<bool>,
    changed: Condvar,
    scene_due: AtomicBool,
}

impl ServerListener for Subscribed {
    fn on_subscribe(&self, _client: Client, _channel: ChannelView<'_>) {
        self.scene_due.store(true, Ordering::Relaxed);
        if let Ok(mut any) = self.any.lock() {
            *any = true;
            self.changed.notify_all();
        }
    }
}

/// A running view: the WebSocket server and the thread that feeds it.
pub struct LiveView {
    server: Option<WebSocketServerHandle>,
    runtime: Option<foxglove_runtime::Runtime>,
    stop: Arc<AtomicBool>,
    subscribed: Arc<Subscribed>,
    thread: Option<JoinHandle<ViewStats>>,
    addr: SocketAddr,
    port: u16,
}

/// The view's own tokio runtime (one worker: the server is light).
mod foxglove_runtime {
    pub type Runtime = tokio::runtime::Runtime;
    pub fn new() -> std::io::Result<Runtime> {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("etp-live")
            .enable_all()
            .build()
    }
}

impl LiveView {
    /// Listen on `addr` and on the feed socket `feed` (created here, in the
    /// run's private folder). `predicted` is each sensor's predicted energy
    /// per episode (`/energy`). Fails before anything of the run started.
    pub fn start(
        addr: SocketAddr,
        scenario: &Scenario,
        predicted: Vec<f64>,
        feed: &Path,
    ) -> Result<Self, LiveError> {
        let feed_err = |source| LiveError::Feed {
            path: feed.to_path_buf(),
            source,
        };
        let socket = UnixDatagram::bind(feed).map_err(feed_err)?;
        socket.set_read_timeout(Some(POLL)).map_err(feed_err)?;
        let runtime = foxglove_runtime::new().map_err(LiveError::Thread)?;
        let ctx = foxglove::Context::new();
        let channels = publish::Channels::new(&ctx, scenario, predicted);
        let subscribed = Arc::new(Subscribed::default());
        let server = WebSocketServer::new()
            .name(format!("etp {}", env!("CARGO_PKG_VERSION")))
            .context(&ctx)
            .tokio_runtime(runtime.handle())
            .listener(subscribed.clone())
            .bind(addr.ip().to_string(), addr.port())
            .start_blocking()
            .map_err(|source| LiveError::Bind { addr, source })?;
        let port = server.port();
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (stop, subscribed) = (stop.clone(), subscribed.clone());
            std::thread::Builder::new()
                .name("etp-live-feed".into())
                .spawn(move || feed_loop(&socket, &channels, &stop, &subscribed))
                .map_err(LiveError::Thread)?
        };
        tracing::info!(%addr, port, "live view: Foxglove WebSocket server listening");
        Ok(Self {
            server: Some(server),
            runtime: Some(runtime),
            stop,
            subscribed,
            thread: Some(thread),
            addr,
            port,
        })
    }

    /// The port listened on (the given one, or the one chosen for port 0).
    pub fn port(&self) -> u16 {
        self.port
    }

    /// The address as given.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Wait until a client subscribed to any channel (at most `timeout`);
    /// `true` if one did.
    pub fn wait_for_subscriber(&self, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        let Ok(mut any) = self.subscribed.any.lock() else {
            return false;
        };
        while !*any {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            match self.subscribed.changed.wait_timeout(any, left) {
                Ok((g, _)) => any = g,
                Err(_) => return false,
            }
        }
        true
    }

    /// Log what is left in the feed, then stop the server.
    pub fn finish(mut self) -> ViewStats {
        self.shut()
    }

    fn shut(&mut self) -> ViewStats {
        self.stop.store(true, Ordering::Relaxed);
        let stats = self
            .thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        if let Some(server) = self.server.take() {
            let done = server.stop();
            if let Some(rt) = &self.runtime {
                rt.block_on(done.wait());
            }
        }
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_timeout(Duration::from_secs(1));
        }
        stats
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        if self.thread.is_some() || self.server.is_some() {
            self.shut();
        }
    }
}

/// The view's thread: read frames, log them; the scene every second and
/// when a client subscribes. After `stop`, what is queued is still logged.
fn feed_loop(
    socket: &UnixDatagram,
    channels: &publish::Channels,
    stop: &AtomicBool,
    subscribed: &Subscribed,
) -> ViewStats {
    let mut stats = ViewStats::default();
    let mut buf = vec![0u8; MAX_DATAGRAM];
    let mut last_scene: Option<Instant> = None;
    let mut stopping = false;
    loop {
        if subscribed.scene_due.swap(false, Ordering::Relaxed)
            || last_scene.is_none_or(|t| t.elapsed() >= SCENE_EVERY)
        {
            channels.scene();
            last_scene = Some(Instant::now());
        }
        match socket.recv(&mut buf) {
            Ok(n) => match buf.get(..n).map(LiveMsg::decode) {
                Some(Ok(m)) => {
                    stats.frames += 1;
                    channels.publish(&m);
                }
                _ => stats.undecodable += 1,
            },
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::Interrupted
                ) =>
            {
                if stopping {
                    break;
                }
            }
            Err(e) => {
                tracing::warn!("live view: reading the feed: {e}; the view stops");
                break;
            }
        }
        if !stopping && stop.load(Ordering::Relaxed) {
            // Drain what the agent sent before the end, without waiting.
            stopping = true;
            if socket.set_nonblocking(true).is_err() {
                break;
            }
        }
    }
    stats
}
