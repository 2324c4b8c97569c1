//! The one place a runtime process blocks: its wake-up listener, with signals
//! and interrupted waits handled once for every process.
//!
//! Every process of a run owns exactly one wake-up event (`agent/wake`,
//! `coordinator/wake`, `sensor/<i>/wake`); peers publish, then notify it. A
//! process therefore waits in one place, [`Waiter::wait`] (its listener
//! attached to an iceoryx2 `WaitSet`; an observer of the whole run — the
//! recorder, a bridge — attaches every event it needs to one `Waiter`), and
//! gets one of the closed set of [`Wake`] events:
//!
//! * a SIGSTOP/SIGCONT (or a debugger, or Ctrl-Z + `fg`) interrupts the
//!   kernel wait with EINTR: that is *not* an event — the wait resumes for
//!   the time that is left, so a paused process never fails or degrades;
//! * SIGINT/SIGTERM (iceoryx2 records them) end the wait with
//!   [`Wake::Terminate`];
//! * silence for the whole timeout is [`Wake::Silence`]: the caller's
//!   watchdog decides whether a peer is dead (node list), never the clock
//!   alone (a live but slow process is waited for).

use super::WireError;
use super::ports::{DEAD_NOTIFIER_EVENT, Listener};
use iceoryx2::prelude::*;
use iceoryx2::waitset::{WaitSetAttachmentId, WaitSetRunResult};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// What ended one wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// The listener was notified: look at the subscribers. `dead_peer` is set
    /// when iceoryx2's dead-notifier event was among the notifications (the
    /// cleanup of a dead node's ports emits it).
    Notified { dead_peer: bool },
    /// Nothing for the whole timeout.
    Silence,
    /// SIGINT or SIGTERM was received.
    Terminate,
}

/// The one wait of a process: its wake-up listener — or, for an observer
/// of a whole run (the recorder, a bridge's outbound direction), several —
/// attached to an iceoryx2 [`WaitSet`] for the process's whole life.
///
/// Why the attachment guards are forgotten: they borrow both the wait set
/// and the listeners, which live side by side here (a process stores its
/// `Waiter` beside its ports), and re-attaching for every wait costs two
/// `epoll_ctl` calls per wake-up — measured 40 % fewer steps/s over IPC.
/// Forgetting a guard leaves its listener's descriptor registered until the
/// wait set (its epoll instance) is dropped with the `Waiter`; the wait set
/// holds these attachments only, and each one's id is kept to tell which
/// listener fired.
pub struct Waiter {
    /// Boxed: an attachment's id holds the wait set's address, which must
    /// not move after the ids are taken.
    waitset: Box<WaitSet<ipc::Service>>,
    listeners: Vec<(WaitSetAttachmentId<ipc::Service>, Listener)>,
}

impl Waiter {
    /// The wait of a process on its own wake-up event.
    pub fn new(listener: Listener) -> Result<Self, WireError> {
        Self::over(vec![listener])
    }

    /// One wait over several wake-up events (e.g. every event of a run:
    /// [`super::ServiceId::all_events`]): notified when any fires.
    pub fn over(listeners: Vec<Listener>) -> Result<Self, WireError> {
        let waitset = Box::new(
            WaitSetBuilder::new()
                .create::<ipc::Service>()
                .map_err(|e| WireError::Wait(format!("creating the wait set: {e:?}")))?,
        );
        let mut ids = Vec::with_capacity(listeners.len());
        for l in &listeners {
            let guard = waitset
                .attach_notification(l)
                .map_err(|e| WireError::Wait(format!("attaching a wake-up listener: {e:?}")))?;
            ids.push(WaitSetAttachmentId::from_guard(&guard));
            std::mem::forget(guard);
        }
        Ok(Self {
            waitset,
            listeners: ids.into_iter().zip(listeners).collect(),
        })
    }

    /// Block until notified, `timeout` passes, or a termination signal.
    /// Interrupted waits (EINTR after SIGCONT) resume with the time left.
    /// The termination flag is read only when the wait ends without a
    /// notification (a signal interrupts the wait), so the hot path — a
    /// notified wait — costs no extra system call.
    pub fn wait(&self, node: &Node<ipc::Service>, timeout: Duration) -> Result<Wake, WireError> {
        let dead = EventId::new(DEAD_NOTIFIER_EVENT);
        let until = Instant::now() + timeout;
        loop {
            let left = until.saturating_duration_since(Instant::now());
            let mut notified = false;
            let mut dead_peer = false;
            let mut drain_error = None;
            let run = self.waitset.wait_and_process_once_with_timeout(
                |fired| {
                    // Consume every pending notification of the listener
                    // that fired: an unconsumed one would wake the wait set
                    // again at once.
                    for (id, listener) in &self.listeners {
                        if *id != fired {
                            continue;
                        }
                        if let Err(e) = listener.try_wait(|ev| {
                            notified = true;
                            dead_peer |= ev.id == dead;
                        }) {
                            drain_error = Some(format!("{e:?}"));
                        }
                    }
                    CallbackProgression::Continue
                },
                left,
            );
            if let Some(e) = drain_error {
                return Err(WireError::Wait(e));
            }
            match run {
                Ok(_) if notified => return Ok(Wake::Notified { dead_peer }),
                Ok(WaitSetRunResult::TerminationRequest) => {
                    note_termination();
                    return Ok(Wake::Terminate);
                }
                // SIGINT/SIGTERM and SIGCONT all interrupt the wait; only the
                // first two end it.
                Ok(_) if termination_requested(node) => return Ok(Wake::Terminate),
                Ok(WaitSetRunResult::Interrupt) => {}
                Ok(_) if Instant::now() >= until => return self.after_silence(),
                // A spurious early return: wait for the rest.
                Ok(_) => {}
                Err(e) => return Err(WireError::Wait(format!("{e:?}"))),
            }
        }
    }
}

impl Waiter {
    /// A wait that timed out: drain every listener before calling it
    /// silence. A listener can be left deaf by iceoryx2's event state
    /// (0.10, `iceoryx2-cal` `event::common`): a drain that swaps the
    /// state from NOTIFIED to IDLE and then empties the socket can eat the
    /// datagram of a notifier that set the state to PENDING in between; that
    /// notifier then sets NOTIFIED with the socket empty, every later notify
    /// sees NOTIFIED and sends nothing, and the wait set (which only watches
    /// the socket) never fires again. Draining here resets the state, so a
    /// lost wake-up costs one timeout instead of every wait that follows
    /// (docs/MODEL.md §3.3).
    fn after_silence(&self) -> Result<Wake, WireError> {
        let dead = EventId::new(DEAD_NOTIFIER_EVENT);
        let mut notified = false;
        let mut dead_peer = false;
        for (_, listener) in &self.listeners {
            listener
                .try_wait(|ev| {
                    notified = true;
                    dead_peer |= ev.id == dead;
                })
                .map_err(|e| WireError::Wait(format!("{e:?}")))?;
        }
        Ok(if notified {
            tracing::debug!(
                "notified, yet the wait timed out: a lost wake-up (or one that came as the wait ended)"
            );
            Wake::Notified { dead_peer }
        } else {
            Wake::Silence
        })
    }
}

/// A termination request, once seen, stays seen: iceoryx2's signal handler
/// hands the last signal out only once (a read swaps it out).
static TERMINATING: AtomicBool = AtomicBool::new(false);

/// Was SIGINT/SIGTERM received? (iceoryx2's default signal handling records
/// termination requests; `Node::wait` reports them. An interrupted sleep —
/// SIGCONT — is not a termination request.) The first call installs the
/// handler: [`super::create_node`] makes it, so a SIGTERM arriving before a
/// process first waits is recorded instead of killing it.
pub fn termination_requested(node: &Node<ipc::Service>) -> bool {
    if TERMINATING.load(Ordering::Relaxed) {
        return true;
    }
    let requested = matches!(
        node.wait(Duration::ZERO),
        Err(iceoryx2::node::NodeWaitFailure::TerminationRequest)
    );
    if requested {
        note_termination();
    }
    requested
}

/// Remember a termination request reported by a wait set.
pub fn note_termination() {
    TERMINATING.store(true, Ordering::Relaxed);
}

/// The one liveness watchdog of a process: is its supervisor (parent
/// process) or its peer node gone? Consulted only after a silent wait (or
/// iceoryx2's dead-notifier event), never on the hot path. Listing the nodes
/// costs milliseconds, so a silent wait lists them only every `list_every`
/// silences; a dead-notifier event lists them at once.
#[derive(Debug, Clone)]
pub struct Watchdog {
    parent: u32,
    peer: String,
    /// The peer was seen alive once: from then on "missing" means gone.
    seen: bool,
    list_every: u32,
    silences: u32,
}

impl Watchdog {
    /// Watch `peer` (a node name of the run) and this process's parent. `seen`:
    /// the peer is known to have been alive already (e.g. it answered hello).
    pub fn new(peer: &str, seen: bool, list_every: u32) -> Self {
        Self {
            parent: std::os::unix::process::parent_id(),
            peer: peer.to_string(),
            seen,
            list_every: list_every.max(1),
            silences: 0,
        }
    }

    /// After a wait that brought no message (`dead_event`: iceoryx2 said a
    /// peer died): `true` when the supervisor or the peer is gone.
    pub fn gone(&mut self, cfg: &iceoryx2::config::Config, dead_event: bool) -> bool {
        if std::os::unix::process::parent_id() != self.parent {
            return true;
        }
        self.silences = self.silences.wrapping_add(1);
        if !dead_event && !self.silences.is_multiple_of(self.list_every) {
            return false;
        }
        match super::liveness(cfg, &self.peer) {
            super::Liveness::Alive => {
                self.seen = true;
                false
            }
            super::Liveness::Missing => self.seen,
            super::Liveness::Dead => true,
        }
    }

    /// The supervisor only (cheap: one system call).
    pub fn parent_gone(&self) -> bool {
        std::os::unix::process::parent_id() != self.parent
    }
}

/// The one header stamper: every message a process publishes carries the
/// run's tag, its sender id and a per-sender sequence number.
#[derive(Debug, Clone)]
pub struct Stamper {
    tag: u64,
    sender: u32,
    seq: u32,
}

impl Stamper {
    pub fn new(run: &super::RunId, sender: u32) -> Self {
        Self {
            tag: run.tag(),
            sender,
            seq: 0,
        }
    }

    /// The run tag messages of this run carry.
    pub fn tag(&self) -> u64 {
        self.tag
    }

    /// The header of the next message.
    pub fn header(&mut self, episode: u64, leg: u32, step: u32) -> super::Header {
        self.seq = self.seq.wrapping_add(1);
        super::Header {
            run: self.tag,
            episode,
            step,
            leg,
            sender: self.sender,
            seq: self.seq,
        }
    }
}
