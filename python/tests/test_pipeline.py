"""synthesize, select_strategy and validate against the CLI: the same
files byte for byte, the same JSON, the same error messages; the progress
callback sees the steps."""

from __future__ import annotations

import json
import threading

import pytest

import etpareto
from conftest import etp, etp_error, etp_json

SYN = ["--samples", "100", "--seed", "1", "--aggregation-episodes", "2000"]
FILES = ["mdp.bin", "front.json", "scenario.toml", "mdp-kf-convergence.bin"]
# What a second run measures anew: times and speeds, and the folder's name.
VOLATILE = {"seconds", "segment_steps_per_second", "path", "files"}


def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if k not in VOLATILE}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """The same synthesis by the package (with a progress callback) and by the CLI."""
    root = tmp_path_factory.mktemp("pipeline")
    calls = []
    py = etpareto.synthesize(
        "open-2d", root / "py", samples=100, seed=1, aggregation_episodes=2000,
        progress=lambda stage, done, total: calls.append((stage, done, total)),
    )
    cli = etp_json("synthesize", "open-2d", *SYN, "-o", str(root / "cli"), "--json")
    return root, py, cli, calls


def test_synthesize_writes_the_cli_bytes(pair):
    root, py, cli, _ = pair
    for f in FILES:
        assert (root / "py" / f).read_bytes() == (root / "cli" / f).read_bytes(), f
    assert strip(py.report) == strip(cli)
    assert py.front.data == json.loads((root / "cli" / "front.json").read_text())
    assert py.report["mdp"]["samples"] == 100 and py.report["mdp"]["seed"] == 1


def test_progress_sees_the_steps(pair):
    *_, calls = pair
    assert calls, "the progress callback was never called"
    for stage, done, total in calls:
        assert stage in {"synthesize", "aggregation check", "splitting"}, stage
        assert total == 0 or 0 <= done <= total


def test_an_existing_synthesis_is_refused_with_the_cli_message(pair):
    root, *_ = pair
    before = (root / "py" / "front.json").read_bytes()
    with pytest.raises(etpareto.OutputError) as e:
        etpareto.synthesize("open-2d", root / "py", samples=100, seed=1)
    assert isinstance(e.value, etpareto.EtpError)
    assert str(e.value) == etp_error("synthesize", "open-2d", *SYN, "-o", str(root / "py"))
    assert (root / "py" / "front.json").read_bytes() == before


def test_select_strategy_writes_the_cli_strategy(pair):
    root, *_ = pair
    s = etpareto.select_strategy(root / "py", min_target=0.9, aggregation_check=300)
    etp("strategy", str(root / "cli"), "--min-target", "0.9", "--aggregation-check", "300")
    assert (root / "py" / "strategy.json").read_bytes() == (root / "cli" / "strategy.json").read_bytes()
    assert s.path == root / "py" / "strategy.json"
    assert s.verdict == "met" and s.rounds >= 1
    # Met: the prediction itself meets the request (`etp strategy --help`).
    assert s.predicted["p_target"] >= 0.9


def test_validate_is_the_cli_json(pair):
    root, *_ = pair
    path = root / "py" / "strategy.json"
    if not path.exists():
        etpareto.select_strategy(root / "py", min_target=0.9, aggregation_check=300)
    v = etpareto.validate(path, episodes=500, seed=4)
    out = etp("validate", str(path), "--episodes", "500", "--seed", "4", "--json", check=False)
    assert out.returncode in (0, 6), out.stderr
    assert v.report == json.loads(out.stdout)
    assert v.holds == (out.returncode == 0)
    t = v.table()
    assert t.loc["p_target", "simulated"] == v.report["p_target"]
    assert t.loc["p_target", "predicted_ci95"] == v.report["predicted_ci95"]["p_target"]
    # One sign: predicted − simulated.
    assert t.loc["energy_mean", "predicted_minus_simulated"] == (
        v.report["predicted"]["energy_mean"] - v.report["energy_mean"])
    # The checks at 95 % family-wise, as the CLI states them.
    assert v.report["checks_level"]["family_wise_level"] == 0.95


def test_two_threads_each_see_their_own_steps(pair, tmp_path):
    """Two steps at once on two threads: each callback sees its own step's
    bars, never the other's."""
    root, *_ = pair
    path = root / "py" / "strategy.json"
    if not path.exists():
        etpareto.select_strategy(root / "py", min_target=0.9, aggregation_check=300)
    seen = {"synthesize": [], "validate": []}
    errors = []

    def synthesize():
        etpareto.synthesize("open-2d", tmp_path / "syn", samples=100, seed=3,
                            aggregation_episodes=500,
                            progress=lambda stage, *_: seen["synthesize"].append(stage))

    def validate():
        etpareto.validate(path, episodes=20000, seed=2,
                          progress=lambda stage, *_: seen["validate"].append(stage))

    def guarded(step):
        try:
            step()
        except Exception as e:  # raised in the test's thread below
            errors.append(e)

    threads = [threading.Thread(target=guarded, args=(f,)) for f in (synthesize, validate)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert seen["validate"] and set(seen["validate"]) == {"validate"}, seen
    assert seen["synthesize"], seen
    assert set(seen["synthesize"]) <= {"synthesize", "aggregation check", "splitting"}, seen


def test_bad_requests_raise_value_errors(pair):
    root, *_ = pair
    with pytest.raises(ValueError, match="exactly one of min_target, max_energy"):
        etpareto.select_strategy(root / "py", min_target=0.9, max_energy=1.0)
    with pytest.raises(ValueError, match="min_target must be a probability"):
        etpareto.select_strategy(root / "py", min_target=1.5)


def test_a_raising_callback_is_raised(tmp_path):
    def boom(stage, done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        etpareto.synthesize("open-2d", tmp_path / "x", samples=50, seed=2,
                            aggregation_episodes=0, kf_baseline=False, progress=boom)


def test_each_kind_of_failure_raises_its_own_class(tmp_path):
    # A folder without a synthesis: the folder's kind, a file-format error.
    with pytest.raises(etpareto.SynthesisError, match="mdp.bin") as e:
        etpareto.select_strategy(tmp_path, min_target=0.9)
    assert isinstance(e.value, etpareto.FileFormatError)
    # A scenario that names nothing: the scenario's kind, with the CLI's words.
    with pytest.raises(etpareto.ScenarioError) as e:
        etpareto.synthesize("no-such-scenario", tmp_path / "syn", samples=10)
    assert str(e.value) == etp_error("synthesize", "no-such-scenario", "-o", str(tmp_path / "syn"))
    assert not (tmp_path / "syn").exists()
