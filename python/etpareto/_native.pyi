"""Type stubs of ``etpareto._native``, the compiled half of ``etpareto``.

Tables cross as lists of columns ``(name, dtype, data, mask)``: see
``etpareto._frames``. JSON objects cross as the CLI's JSON text.
"""

from typing import Any, Callable, Dict, List, Optional, Tuple, Union

_Column = Tuple[str, str, Union[bytes, List[Optional[str]]], Optional[bytes]]

__version__: str

class EtpError(Exception):
    """Any etpareto error; its message is the text ``etp`` prints after ``error:``."""

class ScenarioError(EtpError):
    """A scenario argument that is neither a built-in name nor a valid scenario TOML."""

class SimulationError(EtpError):
    """A simulation request that cannot run (a bad delta, an unknown trigger family)."""

class RecordingError(EtpError):
    """An unreadable, unfinished or damaged MCAP recording."""

class FileFormatError(EtpError):
    """An unreadable front.json or strategy.json."""

class RunError(EtpError):
    """A multi-process run that could not start or finish."""

class SynthesisError(FileFormatError):
    """A synthesis folder that cannot be used: mdp.bin missing or not etp's, a front.json or
    scenario.toml of another MDP."""

class StrategyFileError(FileFormatError):
    """A strategy file a step was given that cannot be read or is not of the scenario."""

class RequestError(EtpError):
    """A request a step cannot carry out as asked: an option out of range, two that exclude
    each other."""

class StudySpecError(RequestError):
    """A study's SPEC refused: unreadable, not TOML, an unknown key, a value of the wrong type
    or out of range; the message names the key."""

class OutputError(EtpError):
    """An output refused: it exists and force was not given, its folder is a link or another
    user's, the file system refused, or its figure could not be drawn."""

class ComputeError(EtpError):
    """A computation failed: the abstraction, a linear program, a prediction from rebuilds,
    the executor."""

class RunRequestError(RunError):
    """A run request refused as asked: an unknown key or a value of the wrong type, options
    that exclude each other or go together, a number out of range, radio options the
    channel refuses, a record path that is a folder or no file name, a run file that does
    not read, an invalid run id."""

class RunScenarioError(RunError):
    """A run's scenario that cannot run: a name that is no built-in and no readable, valid
    file, or a scenario refused by its own checks, the trigger, the channel or
    clone_sensors."""

class RunStrategyError(RunError):
    """A strategy file the run cannot use: not etp's, edited since it was sealed, of another
    scenario or channel."""

class RunOutputError(RunError):
    """A file of the run refused: an output that exists without force, a folder that is
    missing, a link or another user's, the unfinished recording of an earlier run of the
    same id in the way, the user's folder of runs not private, the file system refusing
    to read, write, create or lock a file."""

class RunIdInUseError(RunError):
    """The run id is in use: another live run holds it, or processes of that run are alive
    (choose another run_id)."""

class RunLinkError(RunError):
    """The link across hosts refused its protection: the key folder (tls) missing, not
    private or of another host, an endpoint that does not fit tls or insecure."""

class RunLiveError(RunError):
    """The live view could not serve: an address that is not loopback without insecure, one
    it cannot listen on, or no client subscribed within the deadline (live_wait)."""

class RunBinaryError(RunError):
    """A process binary of the run is not where it is looked for (bin_dir, ETP_PROCESS_DIR,
    or next to etp on PATH)."""

class RunProcessError(RunError):
    """The run's machinery failed: a process that could not be spawned, did not start or
    ended without what the run needs, iceoryx2 refusing the run's services, the runtime
    not set up, the predicting simulation failing, a value not written as JSON."""

class RunExit(RunError):
    """A run that ended with an exit code of its own (``code``), the one ``etp run`` exits
    with: 130 for SIGINT or SIGTERM before any episode; its message is the line ``etp
    run`` prints."""

    code: int

class RecordingUnreadableError(RecordingError):
    """A recording that cannot be read: the file system refused it, a message that does not
    decode, a channel never declared or in an encoding etp does not write, metadata whose
    hashes disagree, a recorded scenario that does not read."""

class RecordingDamagedError(RecordingError):
    """A finished recording with a damaged record (``etp replay repair`` salvages the records
    before the damage)."""

class RecordingUnfinishedError(RecordingError):
    """A recording whose recorder stopped before finishing it (``etp replay repair`` writes a
    finished copy)."""

class RecordingNotEtpError(RecordingError):
    """A file that is not an etp recording: not MCAP at all, or none of its channels etp's."""

class RecordingOutputError(RecordingError):
    """An output of a recording tool refused: it exists without force, it is the recording
    being read, its folder is missing, a link or another user's, or writing it failed."""

class RecordingRequestError(RecordingError):
    """A selection or option the recording cannot satisfy as asked (an empty time window, a
    topic pattern that matches no channel, a rate too slow)."""

class RecordingReplayError(RecordingError):
    """A replay that iceoryx2 refused, whose recorder did not attach, or that was
    interrupted."""

class Scenario:
    """A validated scenario (``etpareto.load_scenario``)."""

    @property
    def name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def source(self) -> str:
        """The built-in name or path it was loaded from."""
    @property
    def dim(self) -> int: ...
    @property
    def content_hash(self) -> str: ...
    @property
    def sensors(self) -> List[str]: ...
    @property
    def legs(self) -> List[str]:
        """The sensor serving each leg, by name."""
    @property
    def deltas(self) -> List[float]: ...
    @property
    def trigger(self) -> str: ...
    @property
    def warnings(self) -> List[str]: ...

def load_scenario(name_or_path: str) -> Scenario: ...
def builtin_scenarios() -> List[str]: ...
def simulate(
    scenario: Union[Scenario, str],
    delta: float,
    episodes: int = 3000,
    seed: int = 0,
    trigger: Optional[str] = None,
    records: bool = True,
) -> Tuple[str, Optional[List[_Column]], Optional[List[_Column]]]: ...
def read_recording(path: str) -> Tuple[Dict[str, List[_Column]], Dict[str, Dict[str, str]]]: ...
def read_front(path: str) -> str: ...
def read_strategy(path: str) -> Tuple[str, List[_Column]]: ...
def mdp_drn(dir: str) -> str: ...
def run(keys: str, config: Optional[str] = None, force: bool = False) -> Tuple[str, List[Tuple[int, str]]]: ...
def synthesize(
    scenario: Union[Scenario, str],
    out: str,
    samples: int = 6000,
    seed: int = 0,
    trigger: Optional[str] = None,
    holdout_samples: int = 0,
    kf_baseline: bool = True,
    aggregation_episodes: int = 50000,
    force: bool = False,
    progress: Optional[Callable[[str, int, int], None]] = None,
) -> str:
    """``etp synthesize … --json``'s text; the files written into ``out``."""
def select_strategy(
    dir: str,
    min_target: Optional[float] = None,
    max_collision: Optional[float] = None,
    max_energy: Optional[float] = None,
    replicates: int = 4,
    rounds: int = 8,
    confidence: Optional[float] = None,
    aggregation_check: int = 4000,
    output: Optional[str] = None,
    force: bool = False,
    progress: Optional[Callable[[str, int, int], None]] = None,
) -> Tuple[str, str, int]:
    """(strategy.json's text, the loop's verdict, its rounds); the file written."""
def validate(
    strategy: str,
    episodes: int = 3000,
    seed: int = 0,
    plot_episodes: Optional[int] = None,
    force: bool = False,
    progress: Optional[Callable[[str, int, int], None]] = None,
) -> Tuple[str, List[str], List[str]]:
    """(``etp validate … --json``'s text, the failing checks' names, the map figures written)."""
def study(
    spec_file: Optional[str] = None,
    spec_json: Optional[str] = None,
    out: Optional[str] = None,
    progress: Optional[Callable[[str, int, int], None]] = None,
) -> str:
    """``etp study SPEC -o OUT --json``'s text (study.json); the study's files written into ``out``."""
