//! `etp`: parse the command line, hand over to the library.

fn main() -> std::process::ExitCode {
    restore_default_sigpipe();
    etp::run(etp::cli::parse())
}

/// The Rust runtime ignores SIGPIPE, so `etp replay FILE | head` would panic
/// on the first write after `head` exits. Like every Unix filter, `etp` should
/// just stop: restore the default action (terminate quietly).
#[allow(unsafe_code)]
fn restore_default_sigpipe() {
    // SAFETY: called once at start, before any thread exists; `signal` with
    // SIG_DFL installs no handler code.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
