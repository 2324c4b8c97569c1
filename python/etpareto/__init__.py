"""etpareto from Python: Pareto-optimal event-triggered estimation strategies.

The package calls etpareto's library crates (the code behind the ``etp``
command, not the command itself) and returns Python values:

* :func:`load_scenario` — a built-in scenario or a scenario TOML, validated.
* :func:`simulate` — in-process episodes with a constant threshold δ; its
  ``.summary`` is the dict ``etp simulate … --json`` prints for the same
  arguments, ``.episodes`` and ``.legs`` one row per episode and per leg.
* :func:`read_recording` — an MCAP recording of ``etp run --record`` as one
  DataFrame per channel (the decoding of ``etp replay export``), streamed
  from disk.
* :func:`synthesize` — ``etp synthesize``: the MDP, its Pareto front and
  their files in a folder, with a progress callback.
* :func:`select_strategy` — ``etp strategy DIR --min-target P``: the request
  loop and the strategy it stands by, with its prediction.
* :func:`validate` — ``etp validate STRATEGY``: the strategy simulated
  against its prediction, the checks.
* :func:`study` — ``etp study SPEC``: every scenario × trigger family ×
  request of a SPEC (a file or a dict) synthesized, selected and validated;
  its table, resumable on the same folder.
* :func:`read_front`, :func:`read_strategy` — ``front.json`` and
  ``strategy.json`` as dicts and DataFrames.
* :func:`run` — a multi-process run (``etp run``), its report as a dict.
* :func:`to_stormpy` — a synthesis's MDP as a stormpy model (labels
  ``init``, ``coll``, ``tar``, ``free``; reward ``energy``), for Storm's
  model checking, stormvogel and the like (needs ``pip install stormpy``).

Errors are :class:`EtpError` subclasses whose message is the text ``etp``
prints after ``error:`` for the same failure, one class per kind of failure
of the pipeline's steps: :class:`ScenarioError` (the scenario),
:class:`SynthesisError` (a synthesis folder that cannot be used) and
:class:`StrategyFileError` (both :class:`FileFormatError`),
:class:`RequestError` (an option out of range; a study's SPEC refused:
:class:`StudySpecError`, naming the key), :class:`OutputError` (an
output refused or its figure not drawn), :class:`ComputeError` (the
abstraction, a linear program, a prediction).

A run (:func:`run`) raises a :class:`RunError` subclass, by what a caller
does about it: :class:`RunRequestError` (a key, a value or a run file
refused), :class:`RunScenarioError` (the scenario),
:class:`RunStrategyError` (the strategy file), :class:`RunOutputError` (a
file or folder of the run refused), :class:`RunIdInUseError` (choose
another ``run_id``), :class:`RunLinkError` (the key folder of a link across
hosts), :class:`RunLiveError` (the live view), :class:`RunBinaryError` (the
run's process binaries not found: ``bin_dir``), :class:`RunProcessError` (a
process or iceoryx2 failed), :class:`RunExit` (an interrupt before any
episode; its exit code in ``.code``). A recording (:func:`read_recording`)
raises a :class:`RecordingError` subclass: :class:`RecordingUnreadableError`,
:class:`RecordingDamagedError` and :class:`RecordingUnfinishedError` (both
salvaged by ``etp replay repair``), :class:`RecordingNotEtpError` (not an
etp recording), :class:`RecordingOutputError`, :class:`RecordingRequestError`,
:class:`RecordingReplayError`.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import pandas as pd

from . import _native
from ._frames import frame
from ._native import (
    ComputeError,
    EtpError,
    FileFormatError,
    OutputError,
    RecordingDamagedError,
    RecordingError,
    RecordingNotEtpError,
    RecordingOutputError,
    RecordingReplayError,
    RecordingRequestError,
    RecordingUnfinishedError,
    RecordingUnreadableError,
    RequestError,
    RunBinaryError,
    RunError,
    RunExit,
    RunIdInUseError,
    RunLinkError,
    RunLiveError,
    RunOutputError,
    RunProcessError,
    RunRequestError,
    RunScenarioError,
    RunStrategyError,
    Scenario,
    ScenarioError,
    SimulationError,
    StrategyFileError,
    StudySpecError,
    SynthesisError,
    builtin_scenarios,
)

__version__: str = _native.__version__

__all__ = [
    "ComputeError",
    "EtpError",
    "FileFormatError",
    "Front",
    "OutputError",
    "RecordingDamagedError",
    "RecordingError",
    "RecordingNotEtpError",
    "RecordingOutputError",
    "RecordingReplayError",
    "RecordingRequestError",
    "RecordingUnfinishedError",
    "RecordingUnreadableError",
    "RequestError",
    "RunBinaryError",
    "RunError",
    "RunExit",
    "RunIdInUseError",
    "RunLinkError",
    "RunLiveError",
    "RunOutputError",
    "RunProcessError",
    "RunReport",
    "RunRequestError",
    "RunScenarioError",
    "RunStrategyError",
    "Scenario",
    "ScenarioError",
    "Simulation",
    "SimulationError",
    "Strategy",
    "StrategyFileError",
    "StudySpecError",
    "Synthesis",
    "SynthesisError",
    "Validation",
    "builtin_scenarios",
    "load_scenario",
    "read_front",
    "read_recording",
    "read_strategy",
    "run",
    "select_strategy",
    "simulate",
    "study",
    "synthesize",
    "to_stormpy",
    "validate",
]

#: ``progress(stage, done, total)``: the step under way (``"synthesize"``,
#: ``"aggregation check"``, ``"rebuilds"``, ``"validate"``, …) and its
#: units done of ``total`` (0 while unknown), at most every 0.2 s.
ProgressCallback = Callable[[str, int, int], None]

PathLike = Union[str, "os.PathLike[str]"]


def load_scenario(name_or_path: PathLike) -> Scenario:
    """Load and validate a scenario, like ``etp check NAME_OR_PATH``.

    ``name_or_path`` is a built-in name (see :func:`builtin_scenarios`) or the
    path of a scenario TOML. Raises :class:`ScenarioError` carrying ``etp
    check``'s message when it is neither or does not validate.
    """
    return _native.load_scenario(os.fspath(name_or_path))


class Simulation:
    """The result of :func:`simulate`.

    Attributes:
        summary: the dict ``etp simulate SCENARIO --delta D --episodes N
            --seed S [--trigger F] --json`` prints (same keys, same values).
        episodes: one row per episode (``episode``, ``outcome``, ``steps``,
            ``slots``, ``transmissions``, ``triggers``, ``delivered``,
            ``energy``, ``expected_transmissions``, ``nees_sum``,
            ``squared_error_sum``), or ``None`` with ``records=False``.
        legs: one row per leg run (``episode``, ``leg``, ``sensor``,
            ``collision`` — the obstacle hit or ``<NA>`` —, ``steps``,
            ``slots``, ``transmissions``, ``triggers``, ``delivered``,
            ``kf_slots``, ``expected_transmissions``, ``energy``), or ``None``.
    """

    def __init__(
        self,
        summary: Dict[str, Any],
        episodes: Optional[pd.DataFrame],
        legs: Optional[pd.DataFrame],
    ) -> None:
        self.summary = summary
        self.episodes = episodes
        self.legs = legs

    def __repr__(self) -> str:
        s = self.summary
        return (
            f"Simulation({s['scenario']}, delta={s['delta']}, episodes={s['episodes']}, "
            f"p_target={s['p_target']:.4f}, energy_mean={s['energy_mean']:.4f})"
        )


def simulate(
    scenario: Union[Scenario, PathLike],
    delta: float,
    episodes: int = 3000,
    seed: int = 0,
    trigger: Optional[str] = None,
    records: bool = True,
) -> Simulation:
    """In-process episodes with the constant threshold ``delta`` on every leg.

    The same computation as ``etp simulate SCENARIO --delta DELTA --episodes
    EPISODES --seed SEED [--trigger TRIGGER] --json`` (same defaults): the
    result's ``.summary`` equals that command's JSON object. With ``records``
    (default) the same episodes are also returned one row each
    (``.episodes``) and per leg (``.legs``); ``records=False`` skips them
    (half the work).

    ``scenario`` is a :class:`Scenario` or what :func:`load_scenario` takes;
    ``trigger`` a family name (``box``, ``stochastic``, ``send-on-delta``,
    ``variance``, ``periodic``) over the scenario's own.

    Raises :class:`ScenarioError` or :class:`SimulationError` with the CLI's
    message (e.g. ``--delta must be a finite number ≥ 0, got -1``).
    """
    if not isinstance(scenario, Scenario):
        scenario = os.fspath(scenario)
    text, eps, legs = _native.simulate(
        scenario, float(delta), int(episodes), int(seed), trigger, bool(records)
    )
    return Simulation(
        json.loads(text),
        None if eps is None else frame(eps),
        None if legs is None else frame(legs),
    )


def read_recording(
    path: PathLike, *, with_metadata: bool = False
) -> Union[Dict[str, pd.DataFrame], Tuple[Dict[str, pd.DataFrame], Dict[str, Dict[str, str]]]]:
    """A finished MCAP recording of ``etp run --record`` as DataFrames.

    Returns a dict channel topic → DataFrame, one row per message in file
    order and the columns of ``etp replay export`` (``log_time_ns`` first,
    the header's fields unprefixed, arrays one column per entry, codes by
    name; ``run``, the run's 64-bit id, as a string). The file is read twice
    chunk by chunk (as ``etp replay export`` reads it): memory holds the
    tables being built, never the file. ``with_metadata=True`` also returns
    the recording's metadata records (name → dict).

    Raises the :class:`RecordingError` subclass of the failure with ``etp
    replay``'s message: :class:`RecordingNotEtpError` for a file that is not
    MCAP, :class:`RecordingDamagedError` for a damaged one,
    :class:`RecordingUnfinishedError` for an unfinished one (``etp replay
    repair`` writes a finished copy of either), :class:`RecordingUnreadableError`
    for one the file system refuses or whose messages do not decode.
    """
    tables, metadata = _native.read_recording(os.fspath(path))
    frames = {topic: frame(cols) for topic, cols in tables.items()}
    if with_metadata:
        return frames, metadata
    return frames


class Front:
    """A ``front.json``: ``.data`` the whole file as a dict; ``.vertices``
    (one row per vertex of the ε-front, its objectives as columns),
    ``.baselines`` (one row per constant δ) and ``.certified`` (the
    certified front's points, empty without one) as DataFrames."""

    def __init__(self, data: Dict[str, Any]) -> None:
        self.data = data
        self.vertices = pd.json_normalize(data.get("vertices") or [], sep="_")
        self.baselines = pd.json_normalize(data.get("baselines") or [], sep="_")
        certified = data.get("certified") or {}
        points = certified.get("points") if isinstance(certified, dict) else None
        self.certified = pd.json_normalize(points or [], sep="_")

    @property
    def epsilon(self) -> float:
        """The certified gap ε (scaled units)."""
        return float(self.data["epsilon"])

    def __repr__(self) -> str:
        return (
            f"Front({self.data.get('scenario_name')}, vertices={len(self.vertices)}, "
            f"epsilon={self.data.get('epsilon')})"
        )


def read_front(path: PathLike) -> Front:
    """``front.json`` (a path to it, or to the synthesis folder holding it),
    checked by the parser of ``etp strategy``; :class:`FileFormatError` with
    its message otherwise."""
    return Front(json.loads(_native.read_front(os.fspath(path))))


def to_stormpy(synthesis: Union["Synthesis", PathLike]) -> Any:
    """The MDP of a synthesis (a :class:`Synthesis` or its folder) as a
    stormpy sparse MDP: the model of ``etp export --format drn`` — states
    ``0..S`` of ``mdp.bin`` then the terminals ``coll``, ``tar``, ``free``
    (labels of the same names, and ``init``), choices labelled ``d<k>``
    (threshold ``k``), reward model ``energy`` (each choice's expected
    energy, so ``R{"energy"}min=? [ C ]`` is a strategy's energy).

    stormpy is imported here only: without it, :class:`ImportError` says
    how to install it (``pip install stormpy``). Raises
    :class:`SynthesisError` (a :class:`FileFormatError`) for a folder
    without a valid ``mdp.bin``.
    """
    try:
        import stormpy
        import stormpy.io
    except ImportError as e:
        raise ImportError(
            "etpareto.to_stormpy needs stormpy, Storm's Python API: "
            "pip install stormpy (wheels for CPython 3.11 on Linux)"
        ) from e
    folder = synthesis.dir if isinstance(synthesis, Synthesis) else Path(synthesis)
    text = _native.mdp_drn(os.fspath(folder))
    options = stormpy.io.DirectEncodingParserOptions()
    options.build_choice_labeling = True
    # Storm's DRN parser reads files only: the text goes through a private
    # temporary folder, removed on return.
    with tempfile.TemporaryDirectory(prefix="etpareto-drn-") as tmp:
        path = os.path.join(tmp, "model.drn")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        return stormpy.build_model_from_drn(path, options=options)


class Strategy:
    """A sealed ``strategy.json``: ``.data`` the file as a dict,
    ``.predicted`` its prediction (dict or ``None``), ``.omega`` the policy
    as a DataFrame — one row per (state, threshold): ``state``,
    ``decision_point``, ``region``, ``delta``, ``omega`` (the probability of
    that δ in that state)."""

    def __init__(self, data: Dict[str, Any], omega: pd.DataFrame) -> None:
        self.data = data
        self.omega = omega
        #: Set by :func:`select_strategy`: the loop's verdict and rounds, the file.
        self.verdict: Optional[str] = None
        self.rounds: Optional[int] = None
        self.path: Optional[Path] = None

    @property
    def predicted(self) -> Optional[Dict[str, float]]:
        return self.data.get("predicted")

    def __repr__(self) -> str:
        return f"Strategy({self.data.get('scenario_name')}, {self.data.get('label')!r})"


def read_strategy(path: PathLike) -> Strategy:
    """``strategy.json`` (a path to it or to its folder), loaded like ``etp
    validate`` loads it (seal and scenario hash checked); raises
    :class:`FileFormatError` with its message otherwise."""
    text, omega = _native.read_strategy(os.fspath(path))
    s = Strategy(json.loads(text), frame(omega))
    p = Path(path)
    s.path = p / "strategy.json" if p.is_dir() else p
    return s


class Synthesis:
    """The result of :func:`synthesize`: ``.dir`` the folder written
    (``mdp.bin``, ``front.json``, ``front.png``/``.svg``, ``scenario.toml``),
    ``.report`` the dict ``etp synthesize … --json`` prints, ``.front`` the
    :class:`Front` read back from ``dir``."""

    def __init__(self, dir: Path, report: Dict[str, Any]) -> None:
        self.dir = dir
        self.report = report
        self.front = read_front(dir)

    def __repr__(self) -> str:
        m = self.report["mdp"]
        return (
            f"Synthesis({str(self.dir)!r}, states={m['states']}, "
            f"vertices={self.report['front']['vertices']})"
        )


def synthesize(
    scenario: Union[Scenario, PathLike],
    out: PathLike,
    *,
    samples: int = 6000,
    seed: int = 0,
    trigger: Optional[str] = None,
    holdout_samples: int = 0,
    kf_baseline: bool = True,
    aggregation_episodes: int = 50_000,
    force: bool = False,
    progress: Optional[ProgressCallback] = None,
) -> Synthesis:
    """Synthesize like ``etp synthesize SCENARIO -o OUT`` (same defaults,
    same files, the same bytes for the same seed on any thread count).

    The keywords are the command's flags: ``samples`` (``--samples``),
    ``seed``, ``trigger`` (``--trigger``: a family over the scenario's own,
    written into ``OUT/scenario.toml``), ``holdout_samples``,
    ``kf_baseline=False`` (``--no-kf-baseline``), ``aggregation_episodes``
    (0: no check), ``force`` (replace an existing synthesis; what was
    derived from it is moved to ``OUT/stale-…/``). ``progress`` is called
    as ``progress(stage, done, total)`` while it works.

    Raises :class:`ScenarioError`, :class:`RequestError`, or
    :class:`OutputError` (e.g. an existing ``front.json`` without
    ``force``) with ``etp synthesize``'s message, touching nothing;
    :class:`ComputeError` when the abstraction fails.
    """
    if not isinstance(scenario, Scenario):
        scenario = os.fspath(scenario)
    text = _native.synthesize(
        scenario,
        os.fspath(out),
        samples=int(samples),
        seed=int(seed),
        trigger=trigger,
        holdout_samples=int(holdout_samples),
        kf_baseline=bool(kf_baseline),
        aggregation_episodes=int(aggregation_episodes),
        force=bool(force),
        progress=progress,
    )
    return Synthesis(Path(out), json.loads(text))


def select_strategy(
    dir: Union[Synthesis, PathLike],
    *,
    min_target: Optional[float] = None,
    max_collision: Optional[float] = None,
    max_energy: Optional[float] = None,
    replicates: int = 4,
    rounds: int = 8,
    confidence: Optional[float] = None,
    aggregation_check: int = 4000,
    output: Optional[PathLike] = None,
    force: bool = False,
    progress: Optional[ProgressCallback] = None,
) -> Strategy:
    """Select like ``etp strategy DIR --min-target P [--max-collision C]``
    (or ``--max-energy E``): the request loop — select on the MDP, predict
    on the strategy's own rebuilds, tighten while the prediction misses —
    and the strategy it stands by, written to ``output`` (default
    ``DIR/strategy.json``; the same bytes as the command's). The default,
    honest path of the CLI; its ``predicted`` is the prediction etp stands
    by.

    The returned :class:`Strategy` has ``.verdict`` (``"met"``, or why the
    request is out of reach — the CLI's exit 7: the closest strategy found
    is written and returned, its label says OUT OF REACH) and ``.rounds``.
    Raises :class:`SynthesisError` (a folder without a usable synthesis),
    :class:`OutputError` (an existing strategy file without ``force``) or
    :class:`ComputeError` with the command's message, ``ValueError`` for an
    argument out of range.
    """
    if isinstance(dir, Synthesis):
        dir = dir.dir
    text, verdict, n_rounds = _native.select_strategy(
        os.fspath(dir),
        min_target=None if min_target is None else float(min_target),
        max_collision=None if max_collision is None else float(max_collision),
        max_energy=None if max_energy is None else float(max_energy),
        replicates=int(replicates),
        rounds=int(rounds),
        confidence=None if confidence is None else float(confidence),
        aggregation_check=int(aggregation_check),
        output=None if output is None else os.fspath(output),
        force=bool(force),
        progress=progress,
    )
    path = Path(output) if output is not None else Path(dir) / "strategy.json"
    s = read_strategy(path)
    if s.data != json.loads(text):
        raise EtpError(f"{path} changed while it was being written and read back")
    s.verdict = verdict
    s.rounds = n_rounds
    s.path = path
    return s


class Validation:
    """The result of :func:`validate`: ``.report`` the dict ``etp validate
    … --json`` prints (predicted vs simulated, the checks), ``.failed`` the
    names of the checks that fail (``etp validate`` exits 6 when any does),
    ``.holds`` whether none does."""

    def __init__(self, report: Dict[str, Any], failed: List[str], plots: List[Path]) -> None:
        self.report = report
        self.failed = failed
        #: The map figures written (``plot_episodes``): PNG, SVG.
        self.plots = plots

    @property
    def holds(self) -> bool:
        return not self.failed

    def table(self) -> pd.DataFrame:
        """Predicted vs simulated (with the simulation's 95 % half-width),
        one row per quantity: ``p_target``, ``p_collision``, ``energy_mean``;
        ``predicted_minus_simulated`` with the sign of every error etp prints.
        The numbers are the CLI's (``etp_shared::stats``: Wilson intervals for
        the probabilities), never recomputed here."""
        r = self.report
        pred = r.get("predicted") or {}
        pred_ci = r.get("predicted_ci95") or {}
        rows = []
        for key in ("p_target", "p_collision", "energy_mean"):
            rows.append({
                "quantity": key,
                "predicted": pred.get(key),
                "predicted_ci95": pred_ci.get(key),
                "simulated": r.get(key),
                "simulated_ci95": r.get(f"{key}_ci95"),
                "predicted_minus_simulated": (
                    None if pred.get(key) is None or r.get(key) is None
                    else pred[key] - r[key]
                ),
            })
        return pd.DataFrame(rows).set_index("quantity")

    def __repr__(self) -> str:
        return f"Validation(episodes={self.report.get('episodes')}, holds={self.holds}, failed={self.failed})"


def validate(
    strategy: Union[Strategy, PathLike],
    *,
    episodes: int = 3000,
    seed: int = 0,
    plot_episodes: Optional[int] = None,
    force: bool = False,
    progress: Optional[ProgressCallback] = None,
) -> Validation:
    """Validate like ``etp validate STRATEGY --episodes N --seed S``: the
    strategy simulated in-process against its prediction. ``.report``
    equals that command's ``--json`` object; a failing check is returned
    in ``.failed``, not raised. ``plot_episodes=N`` also draws the map with
    N sampled trajectories coloured by γ̄(δ) (``--plot --plot-episodes N``:
    ``<strategy>-map.png``/``.svg`` beside the file, ``.plots``; existing
    ones are replaced only with ``force``). Raises :class:`FileFormatError`
    for an unreadable or edited strategy file."""
    if isinstance(strategy, Strategy):
        strategy = strategy.path
    text, failed, plots = _native.validate(
        os.fspath(strategy),
        episodes=int(episodes),
        seed=int(seed),
        plot_episodes=None if plot_episodes is None else int(plot_episodes),
        force=bool(force),
        progress=progress,
    )
    return Validation(json.loads(text), list(failed), [Path(p) for p in plots])


def study(
    spec: Union[Dict[str, Any], PathLike],
    out: Optional[PathLike] = None,
    *,
    progress: Optional[ProgressCallback] = None,
) -> Dict[str, Any]:
    """Run a study like ``etp study SPEC -o OUT --json``: every scenario ×
    trigger family × request of the SPEC synthesized, its strategy selected
    and predicted as ``etp strategy`` does and validated as ``etp validate``
    does, through the same library (``etp-pipeline``). Returns the study's
    table: the dict that command prints (``study.json``; ``["rows"]`` one
    dict per case). The files go into ``out`` (default
    ``out/study-<name>``): ``study.json``, ``study.csv``, ``timings.csv`` and
    each case's under ``cases/``; a study stopped half-way resumes on the
    same folder, and a folder of another SPEC is refused
    (:class:`OutputError`, naming each key that differs).

    ``spec`` is a SPEC file (TOML) or its keys as a dict, e.g.
    ``{"scenarios": ["winding-2d"], "requests": [{"min_target": 0.9}],
    "samples": 300, "episodes": 500}`` (scenario paths relative to the
    working folder; ``name`` defaults to ``"study"``, a file's to its stem).
    A refused SPEC raises :class:`StudySpecError` naming the key (a scenario
    that cannot be used: :class:`ScenarioError`); a case's failing step
    raises that step's class.
    """
    if isinstance(spec, dict):
        text = _native.study(
            spec_json=json.dumps(spec, default=os.fspath),
            out=None if out is None else os.fspath(out),
            progress=progress,
        )
    else:
        text = _native.study(
            spec_file=os.fspath(spec),
            out=None if out is None else os.fspath(out),
            progress=progress,
        )
    return json.loads(text)


class RunReport:
    """The report of :func:`run`: ``.report`` the dict ``etp run … --json``
    prints, ``.problems`` the ``(exit code, text)`` pairs that make the run
    not clean (empty: ``etp run`` would exit 0), ``.exit_code`` that exit
    code, and ``.episodes`` the per-episode records of the report when it
    has them (``episode_details=True``)."""

    def __init__(self, report: Dict[str, Any], problems: List[Tuple[int, str]]) -> None:
        self.report = report
        self.problems = problems

    @property
    def exit_code(self) -> int:
        return max((code for code, _ in self.problems), default=0)

    @property
    def clean(self) -> bool:
        return not self.problems

    @property
    def sensors(self) -> pd.DataFrame:
        """The per-sensor rows of the report (``name``, ``transmissions``,
        ``received``, ``energy``, ``predicted_energy``, …)."""
        return pd.DataFrame(self.report.get("sensors") or [])

    def __repr__(self) -> str:
        r = self.report
        return f"RunReport(run_id={r.get('run_id')!r}, episodes={r.get('episodes')}, clean={self.clean})"


def _process_dir(bin_dir: Optional[PathLike]) -> str:
    """The folder of the run's process binaries: ``bin_dir``, else
    ``ETP_PROCESS_DIR``, else the folder of ``etp`` on ``PATH``."""
    if bin_dir is not None:
        return os.fspath(bin_dir)
    if os.environ.get("ETP_PROCESS_DIR"):
        return os.environ["ETP_PROCESS_DIR"]
    etp = shutil.which("etp")
    if etp:
        return str(Path(etp).resolve().parent)
    raise RunBinaryError(
        "no folder of the run's processes: pass bin_dir= (e.g. target/release of a built "
        "workspace: cargo build --release --workspace) or set ETP_PROCESS_DIR"
    )


def run(
    strategy: Optional[PathLike] = None,
    *,
    scenario: Optional[Union[str, Scenario]] = None,
    delta: Optional[float] = None,
    episodes: Optional[int] = None,
    seed: Optional[int] = None,
    record: Optional[PathLike] = None,
    force: bool = False,
    config: Optional[PathLike] = None,
    bin_dir: Optional[PathLike] = None,
    **keys: Any,
) -> RunReport:
    """A multi-process run — coordinator, agent, one process per sensor,
    recorder — like ``etp run STRATEGY`` (or ``etp run --scenario S --delta
    D``), through the launcher library; returns its report.

    Every keyword but ``force``, ``config`` and ``bin_dir`` is a key of a run
    file (``etp run --config RUN.toml``; its names are ``etp run``'s long
    flags with ``_``): ``record`` = ``--record FILE``, and e.g.
    ``predict_episodes=500``, ``deadline=600``, ``loss=0.3``, ``retries=1``,
    ``slot_deadline=50``, ``allow_degraded=True``, ``listen=...`` with
    ``remote=["s0"]`` and ``tls=DIR``. An unknown key or a value of the wrong
    type raises :class:`RunRequestError` naming it. ``config`` reads a run
    file under these keys (a keyword wins). The processes' binaries are
    looked up in ``bin_dir`` (or ``ETP_PROCESS_DIR``, or next to ``etp`` on
    ``PATH``). When the run cannot start it raises the :class:`RunError`
    subclass of the failure (see the module's docstring) with the message
    ``etp run`` prints after ``error:``; an interrupt before any episode
    raises :class:`RunExit` (``.code`` 130). A run that ran but is not clean
    returns its report with ``.problems``.
    """
    given: Dict[str, Any] = {}
    if strategy is not None:
        given["strategy"] = os.fspath(strategy)
    if scenario is not None:
        given["scenario"] = scenario.source if isinstance(scenario, Scenario) else str(scenario)
    if delta is not None:
        given["delta"] = float(delta)
    if episodes is not None:
        given["episodes"] = int(episodes)
    if seed is not None:
        given["seed"] = int(seed)
    if record is not None:
        given["record"] = os.fspath(record)
    for key, value in keys.items():
        given[key] = os.fspath(value) if isinstance(value, os.PathLike) else value
    os.environ["ETP_PROCESS_DIR"] = _process_dir(bin_dir)
    text, problems = _native.run(
        json.dumps(given), os.fspath(config) if config is not None else None, force
    )
    return RunReport(json.loads(text), [(int(c), str(t)) for c, t in problems])

