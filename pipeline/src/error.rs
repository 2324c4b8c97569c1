//! What a pipeline step fails with, typed: a caller tells a refused
//! scenario from a synthesis folder it cannot use, a request it cannot
//! carry out, an output it may not write and a computation that failed
//! (Python raises a class per variant). A study adds its own: a SPEC
//! refused by key ([`SpecError`]) and what a study fails with
//! ([`StudyError`]). The text, with its causes joined by `: `, is what
//! `etp` prints after `error: `.

use etp_figures::FigureError;
use etp_files::write::WriteError;
use etp_runtime::scenario_arg::ScenarioArgError;
use etp_shared::scenario::ScenarioError;
use etp_synthesis::exec::ExecError;
use etp_synthesis::predict::PredictError;
use std::path::PathBuf;

/// A cause carried under an error's own words.
pub type Cause = Box<dyn std::error::Error + Send + Sync>;

/// A pipeline step's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Why a pipeline step failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scenario: a `SCENARIO` argument, a synthesis folder's
    /// `scenario.toml`, a scenario under a trigger family or channel.
    #[error("{what}")]
    Scenario {
        what: String,
        #[source]
        source: Option<Cause>,
    },
    /// A `SCENARIO` argument that names no built-in and no readable,
    /// valid file.
    #[error(transparent)]
    ScenarioArg(#[from] ScenarioArgError),
    /// A scenario text refused by its own checks.
    #[error(transparent)]
    InvalidScenario(#[from] ScenarioError),
    /// A synthesis folder that cannot be used: `mdp.bin` missing or not
    /// etp's, a `front.json` or `scenario.toml` of another MDP.
    #[error("{what}")]
    Synthesis {
        what: String,
        #[source]
        source: Option<Cause>,
    },
    /// A strategy file the step was given: unreadable, or not of the
    /// scenario.
    #[error("{what}")]
    Strategy {
        what: String,
        #[source]
        source: Option<Cause>,
    },
    /// A request the step cannot carry out as asked: an option out of
    /// range, two options that exclude each other.
    #[error("{0}")]
    Request(String),
    /// An output refused: it exists and `force` was not given, its folder
    /// is a link or another user's, the file system refused.
    #[error(transparent)]
    Output(#[from] WriteError),
    /// A figure that could not be drawn or written.
    #[error(transparent)]
    Figure(#[from] FigureError),
    /// A strategy's prediction from rebuilds, or the request loop, failed.
    #[error(transparent)]
    Prediction(#[from] PredictError),
    /// The executor the Monte Carlo runs on failed (an MPI rank lost).
    #[error(transparent)]
    Executor(#[from] ExecError),
    /// A computation failed: the abstraction, a linear program, a
    /// prediction, an MDP's own consistency check.
    #[error("{what}")]
    Compute {
        what: String,
        #[source]
        source: Option<Cause>,
    },
}

impl Error {
    pub(crate) fn scenario(what: impl Into<String>) -> Self {
        Error::Scenario {
            what: what.into(),
            source: None,
        }
    }
    pub(crate) fn synthesis(what: impl Into<String>) -> Self {
        Error::Synthesis {
            what: what.into(),
            source: None,
        }
    }
    pub(crate) fn request(what: impl Into<String>) -> Self {
        Error::Request(what.into())
    }
}

/// Put a step's own words over a cause, in the variant of what failed
/// (`anyhow`'s `context`, typed).
pub(crate) trait Context<T> {
    fn in_scenario(self, what: impl Into<String>) -> Result<T>;
    fn in_synthesis(self, what: impl Into<String>) -> Result<T>;
    fn in_strategy(self, what: impl Into<String>) -> Result<T>;
    fn computing(self, what: impl Into<String>) -> Result<T>;
}

impl<T, E: std::error::Error + Send + Sync + 'static> Context<T> for std::result::Result<T, E> {
    fn in_scenario(self, what: impl Into<String>) -> Result<T> {
        self.map_err(|e| Error::Scenario {
            what: what.into(),
            source: Some(Box::new(e)),
        })
    }
    fn in_synthesis(self, what: impl Into<String>) -> Result<T> {
        self.map_err(|e| Error::Synthesis {
            what: what.into(),
            source: Some(Box::new(e)),
        })
    }
    fn in_strategy(self, what: impl Into<String>) -> Result<T> {
        self.map_err(|e| Error::Strategy {
            what: what.into(),
            source: Some(Box::new(e)),
        })
    }
    fn computing(self, what: impl Into<String>) -> Result<T> {
        self.map_err(|e| Error::Compute {
            what: what.into(),
            source: Some(Box::new(e)),
        })
    }
}

/// Why a study's SPEC is refused: each error names the SPEC's key
/// (`samples`, `requests[1].min_target`, `scenarios[0]`, …).
#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    /// Not TOML, an unknown key or a value of the wrong type (the parser's
    /// message names the key and its line).
    #[error(transparent)]
    Toml(#[from] toml::de::Error),
    /// The same for a SPEC given as JSON (the Python package's dict).
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A value out of its range or not of its form: `key: what`.
    #[error("{key}: {what}")]
    Value { key: String, what: String },
    /// A scenario of `scenarios` that cannot be read, drawn or put under a
    /// family: `scenarios[i]` (`… under FAMILY`) over the scenario's error.
    #[error("{key}")]
    Scenario {
        key: String,
        #[source]
        source: Cause,
    },
}

impl SpecError {
    pub(crate) fn value(key: impl Into<String>, what: impl Into<String>) -> Self {
        SpecError::Value {
            key: key.into(),
            what: what.into(),
        }
    }
}

/// Why a study failed. Finished cases stay on disk whatever the error: the
/// same study started again resumes from them.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// The SPEC file could not be read.
    #[error("reading study spec {}", path.display())]
    ReadSpec {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The SPEC file refused, under its path.
    #[error("study spec {}", path.display())]
    SpecFile {
        path: PathBuf,
        #[source]
        source: SpecError,
    },
    /// A SPEC given as a value refused.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// The study's folder holds the study of another SPEC (each key that
    /// differs named with both values).
    #[error("{0}")]
    AnotherSpec(String),
    /// A file of the study's folder that cannot be read: its `spec.json`,
    /// a finished case's row file (written whole, so edited since).
    #[error("{what}")]
    Folder {
        what: String,
        #[source]
        source: Cause,
    },
    /// A case's step failed: `study case JOB: the synthesis`, `study case
    /// JOB request K` over the step's error.
    #[error("{what}")]
    Case {
        what: String,
        #[source]
        source: Error,
    },
    /// A step of the study itself failed: a file written, the executor.
    #[error(transparent)]
    Step(#[from] Error),
    /// A folder of the study refused (a link, another user's, the file
    /// system refused).
    #[error(transparent)]
    Output(#[from] WriteError),
    /// The ranks of the job could not share the plan or gather the rows.
    #[error("{what}")]
    Ranks {
        what: String,
        #[source]
        source: Cause,
    },
    /// A value of the study not written or read as JSON, with what it is.
    #[error("{what}")]
    Serde {
        what: String,
        #[source]
        source: serde_json::Error,
    },
    /// A value of the study not written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A table not written as CSV.
    #[error("{what}")]
    Table {
        what: String,
        #[source]
        source: Cause,
    },
    /// The study's own bookkeeping disagrees with itself (a bug).
    #[error("{0}")]
    Bug(String),
}

impl StudyError {
    pub(crate) fn serde(what: impl Into<String>) -> impl FnOnce(serde_json::Error) -> Self {
        let what = what.into();
        move |source| StudyError::Serde { what, source }
    }
    pub(crate) fn ranks<E: std::error::Error + Send + Sync + 'static>(
        what: impl Into<String>,
    ) -> impl FnOnce(E) -> Self {
        let what = what.into();
        move |e| StudyError::Ranks {
            what,
            source: Box::new(e),
        }
    }
}

/// A cause that is only words (a parser's message).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Words(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_s_words_stand_over_their_cause() {
        let io: std::result::Result<(), _> = Err(std::io::Error::other("disk on fire"));
        let e = io
            .in_synthesis("reading out/mdp.bin")
            .expect_err("an error");
        assert!(matches!(e, Error::Synthesis { .. }));
        // `etp` prints the words, then each cause after `: `.
        assert_eq!(e.to_string(), "reading out/mdp.bin");
        let cause = std::error::Error::source(&e).map(ToString::to_string);
        assert_eq!(cause.as_deref(), Some("disk on fire"));
        let e = Error::request("--merge: the level α must lie in (0, 1) (got 2)");
        assert_eq!(
            e.to_string(),
            "--merge: the level α must lie in (0, 1) (got 2)"
        );
        assert!(std::error::Error::source(&e).is_none());
        // A refused output is the writer's own error, its text unchanged.
        let w = Error::from(WriteError::Exists("a.json".into()));
        assert!(matches!(w, Error::Output(WriteError::Exists(_))));
        assert_eq!(
            w.to_string(),
            "a.json already exists (use --force to overwrite)"
        );
    }
}
