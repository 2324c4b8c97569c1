//! What a run fails with, typed: a caller tells a refused request from a
//! scenario or strategy it cannot run, a recording target it may not
//! claim, a run id in use, a process that did not start or report, and an
//! outcome with an exit code of its own (an interrupt before any episode, a
//! finished run that is not clean). The text, with its causes joined by
//! `: `, is what `etp run` prints after `error: `; an outcome with its own
//! exit code prints its message alone ([`Error::exit_with`]).

use etp_files::folders::FolderError;
use etp_files::write::WriteError;
use etp_live::LiveError;
use etp_runtime::link_keys::KeyFolderError;
use etp_runtime::scenario_arg::ScenarioArgError;
use etp_runtime::shell::ExitWith;
use etp_runtime::wire::WireError;
use etp_shared::radio::RadioError;
use etp_synthesis::exec::ExecError;
use std::path::PathBuf;

/// A cause carried under an error's own words.
pub type Cause = Box<dyn std::error::Error + Send + Sync>;

/// A run's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Why a run failed, or ended with an exit code of its own.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An outcome with its own exit code: SIGINT or SIGTERM before any
    /// episode (130), or a finished run that is not clean
    /// ([`crate::exit_for`]: 4, 5, 130). Its message is printed alone.
    #[error(transparent)]
    Exit(ExitWith),
    /// A request the run cannot carry out as asked: options that exclude
    /// each other or go together, a number out of range, a threshold or a
    /// sensor the scenario does not have, a strategy with an option it was
    /// not made for.
    #[error("{0}")]
    Request(String),
    /// The radio options (`--loss`, `--retries`, `--burst`) refused for the
    /// run's channel.
    #[error("radio options")]
    Radio(#[source] RadioError),
    /// `--record` names a folder.
    #[error(
        "--record {}: is a folder; name the recording file (e.g. {})",
        .0.display(),
        .0.join("run.mcap").display()
    )]
    RecordIsFolder(PathBuf),
    /// `--record` names no file (`..`, `/`).
    #[error("--record {}: not a file name", .0.display())]
    RecordNotAFile(PathBuf),
    /// The partial file of an earlier run of the same id is in the way:
    /// its recording, never this run's to remove.
    #[error(
        "{} exists: the recording of an earlier run with id {run_id} that never finished \
         (see etp replay repair); move it away or use another run id",
        partial.display()
    )]
    PartialExists { partial: PathBuf, run_id: String },
    /// An output refused: it exists and `force` was not given, its folder
    /// is missing, a link or another user's.
    #[error(transparent)]
    Output(#[from] WriteError),
    /// A run file (`--config`) that does not read as one, or the run's
    /// configuration that cannot be written as one (`what`: which).
    #[error("{what}")]
    RunFile {
        what: String,
        #[source]
        source: Cause,
    },
    /// A `SCENARIO` argument that names no built-in and no readable, valid
    /// file.
    #[error(transparent)]
    ScenarioArg(#[from] ScenarioArgError),
    /// The run's scenario text refused by its own checks, by `--trigger`,
    /// by the run's channel or by `--clone-sensors` (`what`: which step).
    #[error("{what}")]
    Scenario {
        what: String,
        #[source]
        source: Option<Cause>,
    },
    /// A strategy file the run cannot use: not etp's, edited since it was
    /// sealed, of another scenario or channel (`what`: which check).
    #[error("{what}")]
    Strategy {
        what: String,
        #[source]
        source: Cause,
    },
    /// The in-process simulation that predicts the run failed.
    #[error(transparent)]
    Simulation(#[from] ExecError),
    /// The file system refused to read, write, create or lock a file
    /// (`what`: the operation and its path).
    #[error("{what}")]
    Io {
        what: String,
        #[source]
        source: std::io::Error,
    },
    /// The runtime the run is supervised in, or a signal listener, could
    /// not be set up (`what`: which).
    #[error("{what}")]
    Runtime {
        what: String,
        #[source]
        source: std::io::Error,
    },
    /// The user's private folder of runs cannot be used.
    #[error(transparent)]
    Folder(#[from] FolderError),
    /// Another live `etp run` holds the run id's folder.
    #[error("run id `{0}` is in use by another `etp run` (choose another --run-id)")]
    RunIdLocked(String),
    /// iceoryx2 processes of the run id are alive (a recorder or a replay
    /// started by hand on it).
    #[error(
        "run id `{0}` is in use: iceoryx2 processes of that run are alive (choose another --run-id)"
    )]
    RunIdAlive(String),
    /// A run id that names no services, or iceoryx2 refused the run's
    /// configuration.
    #[error(transparent)]
    Wire(#[from] WireError),
    /// The link's protection refused (`--tls`, `--insecure`, the endpoint).
    #[error(transparent)]
    Link(#[from] KeyFolderError),
    /// The live view refused its address or could not start.
    #[error(transparent)]
    Live(#[from] LiveError),
    /// `--live-wait`: no client subscribed within `--deadline`.
    #[error(
        "--live-wait: no Foxglove client subscribed at ws://{ip}:{port} within --deadline \
         ({deadline} s)"
    )]
    NoLiveClient {
        ip: std::net::IpAddr,
        port: u16,
        deadline: f64,
    },
    /// A process binary of the run that is not where it is looked for
    /// (`what`: which, and where).
    #[error("{what}")]
    Binary {
        what: String,
        #[source]
        source: Option<std::io::Error>,
    },
    /// A process of the run that could not be spawned, waited for or read,
    /// that did not start, or that ended without what the run needs from
    /// it: the recorder, the bridge, the coordinator's report (`what`: which
    /// and how).
    #[error("{what}")]
    Process {
        what: String,
        #[source]
        source: Option<Cause>,
    },
    /// A value that could not be written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

impl Error {
    /// The exit code and message of an outcome with its own exit code
    /// (`None` for a failure: exit 1 with `error: ` and the text).
    pub fn exit_with(&self) -> Option<&ExitWith> {
        match self {
            Error::Exit(x) => Some(x),
            _ => None,
        }
    }

    pub(crate) fn request(what: impl Into<String>) -> Self {
        Error::Request(what.into())
    }

    pub(crate) fn scenario(what: impl Into<String>) -> Self {
        Error::Scenario {
            what: what.into(),
            source: None,
        }
    }

    pub(crate) fn process(what: impl Into<String>) -> Self {
        Error::Process {
            what: what.into(),
            source: None,
        }
    }

    pub(crate) fn binary(what: impl Into<String>) -> Self {
        Error::Binary {
            what: what.into(),
            source: None,
        }
    }
}

/// Put the words of what failed over a cause, in the variant of what
/// failed (`anyhow`'s `with_context`, typed; the words are only made when
/// it failed).
pub(crate) trait Context<T> {
    /// A step of the run's scenario text.
    fn in_scenario<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T>;
    /// A check of the strategy file.
    fn in_strategy<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T>;
    /// A run file read or written.
    fn in_run_file<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T>;
    /// A process of the run spawned, waited for or read.
    fn in_process<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T>;
}

impl<T, E: Into<Cause>> Context<T> for std::result::Result<T, E> {
    fn in_scenario<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| Error::Scenario {
            what: what().into(),
            source: Some(e.into()),
        })
    }
    fn in_strategy<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| Error::Strategy {
            what: what().into(),
            source: e.into(),
        })
    }
    fn in_run_file<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| Error::RunFile {
            what: what().into(),
            source: e.into(),
        })
    }
    fn in_process<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| Error::Process {
            what: what().into(),
            source: Some(e.into()),
        })
    }
}

/// A file operation's, or the runtime's, words over its I/O error.
pub(crate) trait IoContext<T> {
    /// `what`: the operation and its path (`writing run/scenario.toml`).
    fn doing<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T>;
    /// `what`: the runtime or listener being set up.
    fn setting_up(self, what: &str) -> Result<T>;
}

impl<T> IoContext<T> for std::io::Result<T> {
    fn doing<S: Into<String>>(self, what: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|source| Error::Io {
            what: what().into(),
            source,
        })
    }
    fn setting_up(self, what: &str) -> Result<T> {
        self.map_err(|source| Error::Runtime {
            what: what.into(),
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::RunConfig;
    use crate::request::RunRequest;

    /// The chain as `etp` prints it after `error: ` (anyhow's `{:#}`).
    fn printed(e: Error) -> String {
        format!("{:#}", anyhow::Error::from(e))
    }

    #[test]
    fn a_refused_request_is_its_own_variant_with_its_words() {
        let c = RunConfig {
            scenario: Some("open-2d".into()),
            delta: Some(1.0518),
            episodes: Some(0),
            ..RunConfig::default()
        };
        let e = RunRequest::from_config(c).expect_err("no episode");
        assert!(matches!(e, Error::Request(_)), "{e:?}");
        assert!(e.exit_with().is_none());
        assert_eq!(printed(e), "--episodes must be at least 1");
        // Words over a cause print as `words: cause`, as anyhow's context did.
        let io: std::io::Result<()> = Err(std::io::Error::other("disk on fire"));
        let e = io
            .doing(|| "writing run/scenario.toml")
            .expect_err("an error");
        assert!(matches!(e, Error::Io { .. }));
        assert_eq!(printed(e), "writing run/scenario.toml: disk on fire");
    }

    #[test]
    fn an_outcome_with_its_own_exit_code_gives_back_its_code_and_message() {
        let problems = vec![
            (crate::EXIT_DEGRADED, "1 episode(s) degraded".to_string()),
            (
                crate::EXIT_ACCOUNTING,
                "the recording did not finish".into(),
            ),
        ];
        let e = crate::exit_for(&problems).expect_err("not clean");
        let (code, message) = e
            .exit_with()
            .map(|x| (x.code, x.message.clone()))
            .expect("an exit code of its own");
        assert_eq!(code, crate::EXIT_DEGRADED);
        assert_eq!(
            message,
            "etp run: 1 episode(s) degraded\netp run: the recording did not finish"
        );
        // Printed as a failure it would be its message alone.
        assert_eq!(printed(e), message);
        assert!(crate::exit_for(&[]).is_ok());
        let e = crate::interrupts::before_any_episode("SIGINT", "during --live-wait");
        assert_eq!(
            e.exit_with().map(|x| (x.code, x.message.as_str())),
            Some((
                crate::EXIT_INTERRUPTED,
                "etp run: interrupted (SIGINT) during --live-wait, before any episode: nothing ran"
            ))
        );
    }
}
