//! THE process shell: what every process of a run (agent, coordinator,
//! sensor node, recorder, bridge) does around its own work, written once.
//!
//! Each process is a [`Process`] (its name, arguments and body); [`main_with`]
//! — the one entry point of every process: `main` of its binary, and for
//! the agent, coordinator, sensor node and recorder also `etp process
//! <name>` (the bridge has only its binary: `etp` does not link Zenoh) —
//! parses the arguments with the process's own parser (help and usage
//! errors exit 0 / 2, as clap does), sets up logging ([`init_logging`]:
//! `tracing` on stderr, `RUST_LOG`, default `warn`), runs the process's
//! body, and turns the result into the
//! exit code: a [`Done`] is 0 (its stdout line for the parent printed first),
//! an error is 1 with one line `<name>: error: <cause: cause …>` on stderr.
//! A closed stdout or stderr (the parent died) never panics.
//!
//! Signals and the wait loop live beside the ports: [`crate::wire::create_node`]
//! installs iceoryx2's SIGINT/SIGTERM handler before the first wait, and
//! [`crate::wire::Waiter`] is the one place a process blocks — over its own
//! wake-up event, or over several (the recorder, the bridge) — returning
//! the closed set of [`crate::wire::Wake`]s.

use std::ffi::OsString;
use std::io::Write;
use std::process::ExitCode;

/// How the body of a process ended well.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Done {
    /// Nothing for the parent.
    Quiet,
    /// One line on stdout for the parent (a report, a summary).
    Line {
        text: String,
        /// An undelivered line (stdout closed) fails the process: the
        /// parent needed it (the coordinator's report). Otherwise it is
        /// logged and dropped (the recorder's summary: the file is done).
        required: bool,
    },
}

/// One process of a run as the shell runs it: what differs between agent,
/// coordinator, sensor node, recorder and bridge, and nothing else.
pub trait Process {
    /// The binary's name: the logs' and the error line's prefix.
    const NAME: &'static str;
    /// Its command line, typed.
    type Args;
    /// Parse the command line `argv` (the first is the program name): the
    /// process crate's own clap parser, which prints help or the usage
    /// error and exits (0 or 2), as `main` would.
    fn parse(argv: Vec<OsString>) -> Self::Args;
    /// Why the body failed: shown with `{:#}`, which for an `anyhow` error
    /// (the process crates') is the error and its causes after colons.
    type Error: std::fmt::Display;
    /// The process's own work; its error (with its causes) is the process's
    /// last line on stderr.
    fn body(args: &Self::Args) -> Result<Done, Self::Error>;
}

/// An outcome with its own exit code (documented by the command that uses
/// it), e.g. `etp replay` on an unfinished recording exits with 3.
#[derive(Debug)]
pub struct ExitWith {
    pub code: u8,
    pub message: String,
}

impl std::fmt::Display for ExitWith {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for ExitWith {}

/// THE entry point of every process (`main` of its binary, and `etp process
/// <name>` for all but the bridge): parse `args` (the first is the program name) as `P::Args`, set
/// up logging, run `P::body`, and map its result to the exit code.
pub fn main_with<P, I, T>(args: I) -> ExitCode
where
    P: Process,
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let args = P::parse(args.into_iter().map(Into::into).collect());
    let name = P::NAME;
    init_logging(name);
    match P::body(&args) {
        Ok(Done::Quiet) => ExitCode::SUCCESS,
        Ok(Done::Line { text, required }) => {
            let mut out = std::io::stdout().lock();
            match writeln!(out, "{text}").and_then(|()| out.flush()) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) if required => {
                    tracing::warn!("stdout closed ({e}): the line for the parent is lost");
                    ExitCode::FAILURE
                }
                Err(e) => {
                    tracing::info!("stdout closed ({e}); the line is dropped");
                    ExitCode::SUCCESS
                }
            }
        }
        Err(e) => {
            // The error and its causes; stderr may be closed too: never
            // panic on it.
            let _ = writeln!(std::io::stderr(), "{name}: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// iceoryx2 reports errors only: its warnings (no config file, the global
/// config used while cleaning a dead node whose details are gone) are noise
/// here, where every configuration is built in code. `IOX2_LOG_LEVEL`
/// (iceoryx2's own variable: `debug`, `warn`, …) overrides it for a diagnosis.
pub fn quiet_iceoryx2() {
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
}

/// Logging of a process: a `tracing` subscriber on stderr filtered by
/// `RUST_LOG` (default `warn`; Zenoh's own warnings at `error`). The process
/// enters a span named after itself so every line says who wrote it.
pub fn init_logging(process: &str) {
    quiet_iceoryx2();
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        // Zenoh's own warnings (e.g. that gossip, which we turn off, cannot
        // de-duplicate across region gateways) are noise by default.
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,zenoh=error"));
    // Colour only on a terminal: logs redirected to a file or a pipe stay
    // plain text (no ANSI escape codes).
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr)
        .with_target(false)
        .try_init();
    tracing::debug!(process, pid = std::process::id(), "logging ready");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug)]
    struct Args {
        fail: bool,
    }

    /// A process that fails when asked to.
    struct Probe;

    impl Process for Probe {
        const NAME: &'static str = "t";
        type Args = Args;
        fn parse(argv: Vec<OsString>) -> Args {
            Args {
                fail: argv.iter().any(|a| a == "--fail"),
            }
        }
        type Error = &'static str;
        fn body(a: &Args) -> Result<Done, &'static str> {
            if a.fail {
                Err("asked to")
            } else {
                Ok(Done::Quiet)
            }
        }
    }

    #[test]
    fn the_result_becomes_the_exit_code() {
        assert_eq!(main_with::<Probe, _, _>(["t"]), ExitCode::SUCCESS);
        assert_eq!(main_with::<Probe, _, _>(["t", "--fail"]), ExitCode::FAILURE);
    }
}
