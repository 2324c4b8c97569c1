//! etp patch (see third_party/README.md): the accept loop tells its user
//! about every connection it refused before it became a link (a failed or
//! timed-out TLS handshake), so that refusals can be counted and their cause
//! named. Without a hook, nothing changes but the log.

use std::{net::SocketAddr, sync::OnceLock};

/// Why a connection was refused before it became a link.
#[derive(Debug)]
pub enum Refused<'a> {
    /// The TLS handshake failed; `get_ref()` of the error downcasts to the
    /// `rustls::Error` when rustls refused it (a certificate, an alert, not TLS).
    Handshake(&'a std::io::Error),
    /// The TLS handshake did not finish within the handshake timeout.
    Timeout,
    /// Its source address had `PER_SOURCE_HANDSHAKES` handshakes under way:
    /// closed before any byte was read.
    TooManyFromSource,
}

/// Called by the accept loop for each refused connection, with its peer.
pub type RefusalHook = fn(SocketAddr, Refused<'_>);

static HOOK: OnceLock<RefusalHook> = OnceLock::new();

/// Install the process's refusal hook (the first call wins).
pub fn on_refused(hook: RefusalHook) {
    let _ = HOOK.set(hook);
}

pub(crate) fn refused(peer: SocketAddr, why: Refused<'_>) {
    if let Some(hook) = HOOK.get() {
        hook(peer, why);
    }
}
