//! The exception classes of `etpareto` and the text they carry: the text
//! `etp` prints after `error: ` for the same failure (an error's chain of
//! causes joined by `: `, as `anyhow`'s `{:#}` does).

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    etpareto,
    EtpError,
    PyException,
    "Any etpareto error; its message is the text `etp` prints after `error: `."
);
create_exception!(
    etpareto,
    ScenarioError,
    EtpError,
    "A scenario argument that is neither a built-in name nor a valid scenario TOML file."
);
create_exception!(
    etpareto,
    SimulationError,
    EtpError,
    "A simulation request that cannot run (a bad delta, a trigger family unknown)."
);
create_exception!(
    etpareto,
    RecordingError,
    EtpError,
    "An unreadable, unfinished or damaged MCAP recording."
);
create_exception!(
    etpareto,
    FileFormatError,
    EtpError,
    "An unreadable front.json or strategy.json."
);
create_exception!(
    etpareto,
    RunError,
    EtpError,
    "A multi-process run that could not start or finish."
);
create_exception!(
    etpareto,
    SynthesisError,
    FileFormatError,
    "A synthesis folder that cannot be used: mdp.bin missing or not etp's, a front.json or \
     scenario.toml of another MDP."
);
create_exception!(
    etpareto,
    StrategyFileError,
    FileFormatError,
    "A strategy file a step was given that cannot be read or is not of the scenario."
);
create_exception!(
    etpareto,
    RequestError,
    EtpError,
    "A request a step cannot carry out as asked: an option out of range, two that exclude \
     each other."
);
create_exception!(
    etpareto,
    StudySpecError,
    RequestError,
    "A study's SPEC refused: unreadable, not TOML, an unknown key, a value of the wrong type \
     or out of range; the message names the key."
);
create_exception!(
    etpareto,
    OutputError,
    EtpError,
    "An output refused: it exists and force was not given, its folder is a link or another \
     user's, the file system refused, or its figure could not be drawn."
);
create_exception!(
    etpareto,
    ComputeError,
    EtpError,
    "A computation failed: the abstraction, a linear program, a prediction from rebuilds, \
     the executor."
);

// A run's failures, by what a caller does about them. Each is a `RunError`,
// so code that catches `RunError` catches them all.
create_exception!(
    etpareto,
    RunRequestError,
    RunError,
    "A run request refused as asked: an unknown key or a value of the wrong type, options \
     that exclude each other or go together, a number out of range, radio options the \
     channel refuses, a record path that is a folder or no file name, a run file that does \
     not read, an invalid run id."
);
create_exception!(
    etpareto,
    RunScenarioError,
    RunError,
    "A run's scenario that cannot run: a name that is no built-in and no readable, valid \
     file, or a scenario refused by its own checks, the trigger, the channel or \
     clone_sensors."
);
create_exception!(
    etpareto,
    RunStrategyError,
    RunError,
    "A strategy file the run cannot use: not etp's, edited since it was sealed, of another \
     scenario or channel."
);
create_exception!(
    etpareto,
    RunOutputError,
    RunError,
    "A file of the run refused: an output that exists without force, a folder that is \
     missing, a link or another user's, the unfinished recording of an earlier run of the \
     same id in the way, the user's folder of runs not private, the file system refusing \
     to read, write, create or lock a file."
);
create_exception!(
    etpareto,
    RunIdInUseError,
    RunError,
    "The run id is in use: another live run holds it, or processes of that run are alive \
     (choose another run_id)."
);
create_exception!(
    etpareto,
    RunLinkError,
    RunError,
    "The link across hosts refused its protection: the key folder (tls) missing, not \
     private or of another host, an endpoint that does not fit tls or insecure."
);
create_exception!(
    etpareto,
    RunLiveError,
    RunError,
    "The live view could not serve: an address that is not loopback without insecure, one \
     it cannot listen on, or no client subscribed within the deadline (live_wait)."
);
create_exception!(
    etpareto,
    RunBinaryError,
    RunError,
    "A process binary of the run is not where it is looked for (bin_dir, ETP_PROCESS_DIR, \
     or next to etp on PATH)."
);
create_exception!(
    etpareto,
    RunProcessError,
    RunError,
    "The run's machinery failed: a process that could not be spawned, did not start or \
     ended without what the run needs, iceoryx2 refusing the run's services, the runtime \
     not set up, the predicting simulation failing, a value not written as JSON."
);
create_exception!(
    etpareto,
    RunExit,
    RunError,
    "A run that ended with an exit code of its own (its `code` attribute), the one `etp \
     run` exits with: 130 for SIGINT or SIGTERM before any episode; its message is the \
     line `etp run` prints."
);

// A recording's failures, by what a caller does about them; each is a
// `RecordingError`.
create_exception!(
    etpareto,
    RecordingUnreadableError,
    RecordingError,
    "A recording that cannot be read: the file system refused it, a message that does not \
     decode, a channel never declared or in an encoding etp does not write, metadata whose \
     hashes disagree, a recorded scenario that does not read."
);
create_exception!(
    etpareto,
    RecordingDamagedError,
    RecordingError,
    "A finished recording with a damaged record (`etp replay repair` salvages the records \
     before the damage)."
);
create_exception!(
    etpareto,
    RecordingUnfinishedError,
    RecordingError,
    "A recording whose recorder stopped before finishing it (`etp replay repair` writes a \
     finished copy)."
);
create_exception!(
    etpareto,
    RecordingNotEtpError,
    RecordingError,
    "A file that is not an etp recording: not MCAP at all, or none of its channels etp's."
);
create_exception!(
    etpareto,
    RecordingOutputError,
    RecordingError,
    "An output of a recording tool refused: it exists without force, it is the recording \
     being read, its folder is missing, a link or another user's, or writing it failed."
);
create_exception!(
    etpareto,
    RecordingRequestError,
    RecordingError,
    "A selection or option the recording cannot satisfy as asked (an empty time window, a \
     topic pattern that matches no channel, a rate too slow)."
);
create_exception!(
    etpareto,
    RecordingReplayError,
    RecordingError,
    "A replay that iceoryx2 refused, whose recorder did not attach, or that was \
     interrupted."
);

/// `m.add("Class", <Class>)` for each class named.
macro_rules! add_classes {
    ($m:expr, $($class:ident),+ $(,)?) => {
        $( $m.add(stringify!($class), $m.py().get_type::<$class>())?; )+
    };
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    add_classes!(
        m,
        EtpError,
        ScenarioError,
        SimulationError,
        RecordingError,
        FileFormatError,
        RunError,
        SynthesisError,
        StrategyFileError,
        RequestError,
        StudySpecError,
        OutputError,
        ComputeError,
        RunRequestError,
        RunScenarioError,
        RunStrategyError,
        RunOutputError,
        RunIdInUseError,
        RunLinkError,
        RunLiveError,
        RunBinaryError,
        RunProcessError,
        RunExit,
        RecordingUnreadableError,
        RecordingDamagedError,
        RecordingUnfinishedError,
        RecordingNotEtpError,
        RecordingOutputError,
        RecordingRequestError,
        RecordingReplayError,
    );
    Ok(())
}

/// `e` and its causes joined by `: ` (what `etp` prints for it: the CLI
/// wraps library errors in `anyhow` and prints `{:#}`).
pub fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text.push_str(": ");
        text.push_str(&c.to_string());
        cause = c.source();
    }
    text
}

/// A pipeline step's error as the exception of its kind, with the text
/// `etp` prints for it. The match is exhaustive: a new kind of failure in
/// the pipeline gets its class here before it compiles.
pub fn pipeline_error(e: etp_pipeline::error::Error) -> PyErr {
    let text = chain(&e);
    pipeline_exception(&e, text)
}

/// The class of a pipeline step's error `e`, carrying `text`.
fn pipeline_exception(e: &etp_pipeline::error::Error, text: String) -> PyErr {
    use etp_pipeline::error::Error as E;
    match e {
        E::Scenario { .. } | E::ScenarioArg(_) | E::InvalidScenario(_) => {
            ScenarioError::new_err(text)
        }
        E::Synthesis { .. } => SynthesisError::new_err(text),
        E::Strategy { .. } => StrategyFileError::new_err(text),
        E::Request(_) => RequestError::new_err(text),
        E::Output(_) | E::Figure(_) => OutputError::new_err(text),
        E::Prediction(_) | E::Executor(_) | E::Compute { .. } => ComputeError::new_err(text),
    }
}

/// A study's error as the exception of its kind, with the text `etp
/// study` prints for it: a SPEC refused is a `StudySpecError` (a scenario
/// of it that cannot be used a `ScenarioError`), a case's step raises its
/// step's class, a study folder of another SPEC an `OutputError`. The
/// match is exhaustive: a new kind of failure of a study gets its class
/// here before it compiles.
pub fn study_error(e: etp_pipeline::error::StudyError) -> PyErr {
    use etp_pipeline::error::{SpecError as S, StudyError as E};
    let text = chain(&e);
    match &e {
        E::Spec(S::Scenario { .. })
        | E::SpecFile {
            source: S::Scenario { .. },
            ..
        } => ScenarioError::new_err(text),
        E::ReadSpec { .. } | E::Spec(_) | E::SpecFile { .. } => StudySpecError::new_err(text),
        E::AnotherSpec(_) | E::Output(_) | E::Folder { .. } => OutputError::new_err(text),
        E::Case { source, .. } | E::Step(source) => pipeline_exception(source, text),
        E::Ranks { .. } | E::Serde { .. } | E::Json(_) | E::Table { .. } | E::Bug(_) => {
            ComputeError::new_err(text)
        }
    }
}

/// A run's error as the exception of its kind, with the text `etp run`
/// prints for it. The match is exhaustive: a new kind of failure of a run
/// gets its class here before it compiles.
pub fn launcher_error(e: etp_launcher::Error) -> PyErr {
    let text = chain(&e);
    run_exception(e, text)
}

/// [`launcher_error`] under the words `what` (`run file PATH`), as `etp run`
/// prints an error it put context over: `what: ` and the error's text.
pub fn launcher_error_under(what: &str, e: etp_launcher::Error) -> PyErr {
    let text = format!("{what}: {}", chain(&e));
    run_exception(e, text)
}

fn run_exception(e: etp_launcher::Error, text: String) -> PyErr {
    use etp_launcher::Error as E;
    use etp_runtime::wire::WireError as W;
    match e {
        // `etp run` prints such an outcome's message alone, whatever the
        // context over it, and exits with its code.
        E::Exit(x) => run_exit(x.code, x.message),
        E::Request(_)
        | E::Radio(_)
        | E::RecordIsFolder(_)
        | E::RecordNotAFile(_)
        | E::RunFile { .. }
        | E::Wire(W::RunId(_)) => RunRequestError::new_err(text),
        E::ScenarioArg(_) | E::Scenario { .. } => RunScenarioError::new_err(text),
        E::Strategy { .. } => RunStrategyError::new_err(text),
        E::Output(_) | E::PartialExists { .. } | E::Io { .. } | E::Folder(_) => {
            RunOutputError::new_err(text)
        }
        E::RunIdLocked(_) | E::RunIdAlive(_) => RunIdInUseError::new_err(text),
        E::Link(_) => RunLinkError::new_err(text),
        E::Live(_) | E::NoLiveClient { .. } => RunLiveError::new_err(text),
        E::Binary { .. } => RunBinaryError::new_err(text),
        E::Process { .. }
        | E::Runtime { .. }
        | E::Wire(W::Config(_) | W::Node(_) | W::Service(..) | W::Port(..) | W::Wait(_))
        | E::Simulation(_)
        | E::Json(_) => RunProcessError::new_err(text),
    }
}

/// `RunExit` with `message`, its exit code in its `code` attribute.
fn run_exit(code: u8, message: String) -> PyErr {
    Python::attach(|py| {
        let err = RunExit::new_err(message);
        match err.value(py).setattr("code", code) {
            Ok(()) => err,
            Err(failed) => failed,
        }
    })
}

/// A recording tool's error as the exception of its kind, with the text
/// `etp replay` prints for it. The match is exhaustive: a new kind of
/// failure of the recording tools gets its class here before it compiles.
pub fn recording_error(e: etp_recording_tools::Error) -> PyErr {
    use etp_recording_tools::Error as E;
    use etp_runtime::recording::RecordingError as R;
    let text = chain(&e);
    match e {
        E::Io { .. }
        | E::Message { .. }
        | E::UndeclaredChannel(_)
        | E::UnopenedChannel(_)
        | E::Encoding { .. }
        | E::Table { .. }
        | E::Scenario { .. }
        | E::NoScenario
        | E::Recording(R::UnknownTopic(_) | R::Decode { .. } | R::Metadata(_)) => {
            RecordingUnreadableError::new_err(text)
        }
        E::Damaged { .. } => RecordingDamagedError::new_err(text),
        E::Foreign { .. } | E::UnknownChannel(_) | E::Recording(R::NotMcap(..)) => {
            RecordingNotEtpError::new_err(text)
        }
        E::Output(_)
        | E::OutputIsInput(_)
        | E::Stream(_)
        | E::Mcap { .. }
        | E::McapRecord(_)
        | E::Json { .. }
        | E::Recording(R::Encode(_)) => RecordingOutputError::new_err(text),
        E::Request(_) | E::Rate { .. } => RecordingRequestError::new_err(text),
        E::Wire(_)
        | E::Port { .. }
        | E::Send { .. }
        | E::Publish { .. }
        | E::Attach(_)
        | E::HandoverVanished(_)
        | E::Interrupted { .. }
        | E::Recording(R::Port(_)) => RecordingReplayError::new_err(text),
    }
}
