//! Progress bars of the pipeline's steps: `etp_runtime::progress` (an
//! indicatif bar on a terminal, plain lines otherwise, nothing when quiet),
//! drawn by rank 0 alone in an MPI job, and — for a caller that shows
//! progress its own way (the Python package's callback) — the bar of the
//! step under way, readable from another thread through the [`Progress`]
//! value the step was handed ([`Progress::watched`], [`Progress::current`]).
//!
//! The watched bar belongs to the value and its clones, never to the
//! process: two steps on two threads, each with its own [`Progress`], each
//! see their own step's bar. A bar tracks its position whether it is drawn
//! or not, so a watcher sees the same counts a terminal would; watching
//! changes no result.

pub use etp_runtime::progress::*;

use etp_synthesis::exec::Executor;
use indicatif::ProgressBar;
use std::sync::{Arc, Mutex};

/// The newest bar of a watched step, shared with its watcher.
type Slot = Arc<Mutex<Option<ProgressBar>>>;

/// Where a step's progress goes: drawn on stderr by rank 0 unless quiet,
/// and, when watched, the newest bar kept for [`Progress::current`]. A
/// step hands a clone (or [`Progress::silenced`]) to the steps it runs, so
/// their bars reach the same watcher.
#[derive(Clone, Default)]
pub struct Progress {
    quiet: bool,
    watcher: Option<Slot>,
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Progress")
            .field("quiet", &self.quiet)
            .field("watched", &self.watcher.is_some())
            .finish()
    }
}

impl Progress {
    /// Bars drawn on stderr, none when `quiet` (`--json`); no watcher.
    pub fn new(quiet: bool) -> Self {
        Progress {
            quiet,
            watcher: None,
        }
    }

    /// Nothing drawn; each bar kept for [`Self::current`] (a caller that
    /// shows progress its own way, on another thread).
    pub fn watched() -> Self {
        Progress {
            quiet: true,
            watcher: Some(Slot::default()),
        }
    }

    /// The same watcher, nothing drawn (the inner steps of a step that
    /// draws its own bar).
    pub fn silenced(&self) -> Self {
        Progress {
            quiet: true,
            watcher: self.watcher.clone(),
        }
    }

    /// No bar is drawn.
    pub fn is_quiet(&self) -> bool {
        self.quiet
    }

    /// [`etp_runtime::progress::bar`], quiet on every rank of `exec` but 0;
    /// the step under way for [`Self::current`] when watched.
    pub fn bar(&self, exec: &Executor, len: u64, message: &str) -> ProgressBar {
        let pb = etp_runtime::progress::bar(len, message, self.quiet || !exec.is_root());
        if let Some(slot) = &self.watcher
            && let Ok(mut c) = slot.lock()
        {
            *c = Some(pb.clone());
        }
        pb
    }

    /// The newest bar's (message, position, length), when watched.
    pub fn current(&self) -> Option<(String, u64, u64)> {
        let c = self.watcher.as_ref()?.lock().ok()?;
        let pb = c.as_ref()?;
        Some((pb.message(), pb.position(), pb.length().unwrap_or(0)))
    }
}

/// A bar no watcher sees (a step of `etp` alone): [`Progress::new`]`(quiet)`'s.
pub fn bar(exec: &Executor, len: u64, message: &str, quiet: bool) -> ProgressBar {
    Progress::new(quiet).bar(exec, len, message)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two watched steps on two threads each see their own bar; a silenced
    /// clone reaches the same watcher; an unwatched one reports nothing.
    #[test]
    fn each_watcher_sees_its_own_steps_bar() {
        let exec = Executor::LOCAL;
        let (a, b) = (Progress::watched(), Progress::watched());
        std::thread::scope(|s| {
            s.spawn(|| a.bar(&exec, 10, "first").inc(3));
            s.spawn(|| b.bar(&exec, 20, "second").inc(7));
        });
        assert_eq!(a.current(), Some(("first".into(), 3, 10)));
        assert_eq!(b.current(), Some(("second".into(), 7, 20)));
        a.silenced().bar(&exec, 5, "inner");
        assert_eq!(a.current(), Some(("inner".into(), 0, 5)));
        assert!(a.silenced().is_quiet() && a.is_quiet());
        assert_eq!(b.current(), Some(("second".into(), 7, 20)));
        let drawn = Progress::new(true);
        drawn.bar(&exec, 4, "unwatched");
        assert_eq!(drawn.current(), None);
    }
}
