//! What a recording tool fails with, typed: a caller tells a recording it
//! cannot read from an output it may not write, a selection it cannot
//! carry out and a replay iceoryx2 refused. The text, with its causes
//! joined by `: `, is what `etp replay` prints after `error: `.

use etp_files::write::WriteError;
use etp_runtime::recording::RecordingError;
use etp_runtime::recording::observers::AttachError;
use etp_runtime::wire::WireError;
use etp_shared::scenario::ScenarioError;
use std::path::PathBuf;

/// A cause carried under an error's own words.
pub type Cause = Box<dyn std::error::Error + Send + Sync>;

/// A recording tool's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Why a recording tool failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file system refused to create, read, write, move or flush a
    /// file (`what`: the operation and its path).
    #[error("{what}")]
    Io {
        what: String,
        #[source]
        source: std::io::Error,
    },
    /// The stream the caller handed in for the lines (`cat`'s stdout)
    /// refused a write: a closed pipe, a full disk.
    #[error(transparent)]
    Stream(std::io::Error),
    /// The MCAP writer of a copy could not start or finish it (`what`:
    /// which step of which copy).
    #[error("{what}")]
    Mcap {
        what: String,
        #[source]
        source: mcap::McapError,
    },
    /// The MCAP writer of a copy refused one of its records (a metadata
    /// record, a schema, a channel, a message).
    #[error(transparent)]
    McapRecord(#[from] mcap::McapError),
    /// A message that does not decode, or whose decoding cannot be shown
    /// in another encoding (`at`: which message, by its log time).
    #[error("{at}")]
    Message {
        at: String,
        #[source]
        source: Cause,
    },
    /// A channel whose topic is none of etp's, where only etp's channels
    /// can be copied, tabled or published.
    #[error("unknown channel `{0}` in the recording")]
    UnknownChannel(String),
    /// A message on a channel the recording never declared.
    #[error("message on undeclared channel `{0}`")]
    UndeclaredChannel(String),
    /// A message on a channel the copy or the replay opened none for.
    #[error("message on unknown channel `{0}`")]
    UnopenedChannel(String),
    /// An etp channel in a message encoding no etp writes: a copy could
    /// not give it a schema.
    #[error("channel `{topic}`: message encoding `{encoding}` is not one etp writes")]
    Encoding { topic: String, encoding: String },
    /// An etp channel whose kind has no table at the scenario's dimension.
    #[error("the table of `{topic}`")]
    Table {
        topic: String,
        #[source]
        source: Words,
    },
    /// The recording itself: not an MCAP file, a payload that does not
    /// decode, metadata whose hashes disagree.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A finished file with a damaged record: only `repair` reads it.
    #[error(
        "{} is damaged: {why} (`etp replay repair {} OUT` salvages the records before the damage)",
        file.display(),
        file.display()
    )]
    Damaged { file: PathBuf, why: String },
    /// A file none of whose channels etp writes (a Foxglove copy, another
    /// program's file): its summary would be an empty run.
    #[error(
        "{} is not an etp recording: none of its {channels} channels is one etp records \
         (their encodings: {encodings}; a Foxglove copy, or another program's file); \
         `etp replay info {}` describes any MCAP file",
        file.display(),
        file.display()
    )]
    Foreign {
        file: PathBuf,
        channels: usize,
        /// The channels' message encodings, joined by `, `.
        encodings: String,
    },
    /// An output refused: it exists and `force` was not given, its folder
    /// is missing, a link or another user's, the file system refused.
    #[error(transparent)]
    Output(#[from] WriteError),
    /// An output that is the recording being read: writing it would
    /// destroy the input.
    #[error("{} is the recording being read: choose another output", .0.display())]
    OutputIsInput(PathBuf),
    /// A selection or option the recording cannot satisfy as asked (an
    /// empty time window, a topic pattern that matches no channel, a loop
    /// over nothing).
    #[error("{0}")]
    Request(String),
    /// A `--rate` so slow that a message's time offset is no duration.
    #[error("--rate {rate}: the replay would take forever")]
    Rate {
        rate: f64,
        #[source]
        source: std::time::TryFromFloatSecsError,
    },
    /// The recorded scenario does not read as a scenario (`what`: where it
    /// was read from).
    #[error("{what}")]
    Scenario {
        what: String,
        #[source]
        source: ScenarioError,
    },
    /// The replay needs the recorded scenario and the recording has none.
    #[error("the recording has no scenario (metadata `etp.scenario`)")]
    NoScenario,
    /// iceoryx2 refused the replay's node.
    #[error(transparent)]
    Wire(#[from] WireError),
    /// iceoryx2 refused a port of the replay (`what`: which).
    #[error("{what}")]
    Port {
        what: String,
        #[source]
        source: WireError,
    },
    /// A replayed sample could not be sent (`what`: on which channel).
    #[error("{what}")]
    Send {
        what: String,
        #[source]
        source: RecordingError,
    },
    /// iceoryx2 refused to wake the readers (`detail`: its error as it
    /// describes itself).
    #[error("{what}: {detail}")]
    Publish { what: String, detail: String },
    /// A recorder of the run id did not attach to the replay's publishers:
    /// its copy would miss messages.
    #[error(transparent)]
    Attach(#[from] AttachError),
    /// The metadata left for the run's recorder vanished before it was
    /// read back (another process removed the run's folder).
    #[error("{} vanished", .0.display())]
    HandoverVanished(PathBuf),
    /// SIGINT or SIGTERM stopped a replay before its end.
    #[error("interrupted after {messages} messages")]
    Interrupted { messages: u64 },
    /// A value could not be written as JSON (`what`: which).
    #[error("{what}")]
    Json {
        what: String,
        #[source]
        source: serde_json::Error,
    },
}

impl Error {
    /// The caller's stream was closed by its reader (`etp replay cat F |
    /// head -1`): the output ends quietly rather than as an error.
    pub fn is_broken_pipe(&self) -> bool {
        matches!(self, Error::Stream(e) if e.kind() == std::io::ErrorKind::BrokenPipe)
    }

    pub(crate) fn request(what: impl Into<String>) -> Self {
        Error::Request(what.into())
    }
}

/// A cause that is only words (a table builder's message).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Words(pub String);

/// Put the words of what failed over a cause, in the variant of what
/// failed (`anyhow`'s `with_context`, typed; the words are only made when
/// it failed).
pub(crate) trait Context<T> {
    /// A message that does not decode or show (`at`: which message).
    fn at_message(self, at: impl FnOnce() -> String) -> Result<T>;
}

impl<T, E: Into<Cause>> Context<T> for std::result::Result<T, E> {
    fn at_message(self, at: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|e| Error::Message {
            at: at(),
            source: e.into(),
        })
    }
}

/// A file operation's words over its I/O error.
pub(crate) trait IoContext<T> {
    /// `what`: the operation and its path (`writing out/a.csv`).
    fn doing(self, what: impl FnOnce() -> String) -> Result<T>;
}

impl<T> IoContext<T> for std::io::Result<T> {
    fn doing(self, what: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|source| Error::Io {
            what: what(),
            source,
        })
    }
}
