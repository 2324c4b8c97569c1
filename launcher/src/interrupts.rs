//! Ctrl-C (SIGINT) and SIGTERM, listened to from the moment `etp run` has
//! its runtime, before it claims a folder or starts a process: a signal that
//! comes while the run prepares, waits for a Foxglove client or for remote
//! hosts to join is kept, and ends the command with exit 130 and nothing
//! left behind (the processes started so far stopped and reaped, the run's
//! folder and iceoryx2 files removed, no recording claimed). Once the
//! episodes run, the supervisor stops them after the complete ones.

use crate::error::{Error, IoContext, Result};
use etp_runtime::shell::ExitWith;
use std::time::Duration;
use tokio::signal::unix::{Signal, SignalKind, signal};

/// The run's two listeners, made once: a signal that arrives between two
/// polls is kept for the next one.
pub struct Interrupts {
    int: Signal,
    term: Signal,
}

impl Interrupts {
    /// Listen from now on (inside the runtime `rt`).
    pub fn listen(rt: &tokio::runtime::Runtime) -> Result<Self> {
        let _in_rt = rt.enter();
        Ok(Self {
            int: signal(SignalKind::interrupt()).setting_up("listening for Ctrl-C")?,
            term: signal(SignalKind::terminate()).setting_up("listening for SIGTERM")?,
        })
    }

    /// The name of the next interrupt (waits for it).
    pub async fn next(&mut self) -> &'static str {
        tokio::select! {
            _ = self.int.recv() => "SIGINT",
            _ = self.term.recv() => "SIGTERM",
        }
    }

    /// The name of an interrupt that came already, without waiting.
    pub fn pending(&mut self, rt: &tokio::runtime::Runtime) -> Option<&'static str> {
        // `timeout` polls the listeners once before it looks at the clock.
        rt.block_on(async { tokio::time::timeout(Duration::ZERO, self.next()).await })
            .ok()
    }
}

/// The error that ends the command (exit 130) when an interrupt came
/// `during` a wait before the first episode.
pub fn before_any_episode(name: &str, during: &str) -> Error {
    Error::Exit(ExitWith {
        code: super::EXIT_INTERRUPTED,
        message: format!("etp run: interrupted ({name}) {during}, before any episode: nothing ran"),
    })
}
