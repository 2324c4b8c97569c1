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

class OutputError(EtpError):
    """An output refused: it exists and force was not given, its folder is a link or another
    user's, the file system refused, or its figure could not be drawn."""

class ComputeError(EtpError):
    """A computation failed: the abstraction, a linear program, a prediction from rebuilds,
    the executor."""

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
