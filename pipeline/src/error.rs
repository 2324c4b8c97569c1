//! What a pipeline step fails with, typed: a caller tells a refused
//! scenario from a synthesis folder it cannot use, a request it cannot
//! carry out, an output it may not write and a computation that failed
//! (Python raises a class per variant). The text, with its causes joined by
//! `: `, is what `etp` prints after `error: `.

use etp_figures::FigureError;
use etp_files::write::WriteError;
use etp_runtime::scenario_arg::ScenarioArgError;
use etp_shared::scenario::ScenarioError;
use etp_synthesis::exec::ExecError;
use etp_synthesis::predict::PredictError;

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
