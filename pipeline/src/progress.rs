//! Progress bars of the pipeline's steps: `etp_runtime::progress` (an
//! indicatif bar on a terminal, plain lines otherwise, nothing when quiet),
//! drawn by rank 0 alone in an MPI job, and — for a caller that shows
//! progress its own way (the Python package's callback) — the bar of the
//! step under way, readable from another thread ([`watch`], [`current`]).
//!
//! A bar tracks its position whether it is drawn or not, so a watcher sees
//! the same counts a terminal would; watching changes no result.

pub use etp_runtime::progress::*;

use etp_synthesis::exec::Executor;
use indicatif::ProgressBar;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How many callers watch (each [`watch`]`(true)` counts until its `false`).
static WATCHERS: AtomicUsize = AtomicUsize::new(0);
static CURRENT: Mutex<Option<ProgressBar>> = Mutex::new(None);

/// [`etp_runtime::progress::bar`], quiet on every rank of `exec` but 0;
/// the step under way for [`current`] while someone [`watch`]es.
pub fn bar(exec: &Executor, len: u64, message: &str, quiet: bool) -> ProgressBar {
    let pb = etp_runtime::progress::bar(len, message, quiet || !exec.is_root());
    if WATCHERS.load(Ordering::SeqCst) > 0
        && let Ok(mut c) = CURRENT.lock()
    {
        *c = Some(pb.clone());
    }
    pb
}

/// Start (`true`) or stop (`false`, once per start) keeping the newest bar
/// for [`current`]; the bar is dropped when the last watcher stops. Two
/// watchers at once (two threads of one Python process) see the newest
/// bar of either.
pub fn watch(on: bool) {
    if on {
        WATCHERS.fetch_add(1, Ordering::SeqCst);
        return;
    }
    let before = WATCHERS
        .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
        .unwrap_or(0);
    if before <= 1
        && let Ok(mut c) = CURRENT.lock()
    {
        *c = None;
    }
}

/// The newest bar's (message, position, length), while [`watch`]ed.
pub fn current() -> Option<(String, u64, u64)> {
    let c = CURRENT.lock().ok()?;
    let pb = c.as_ref()?;
    Some((pb.message(), pb.position(), pb.length().unwrap_or(0)))
}
