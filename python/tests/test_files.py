"""read_front and read_strategy on a synthesis the CLI makes; an edited
strategy is refused with `etp validate`'s message."""

from __future__ import annotations

import json

import pytest

import etpareto
from conftest import etp, etp_error


@pytest.fixture(scope="module")
def synthesis(tmp_path_factory):
    d = tmp_path_factory.mktemp("synthesis") / "open-2d"
    etp("synthesize", "open-2d", "--samples", "100", "--seed", "1", "-o", str(d))
    etp("strategy", str(d), "--min-target", "0.9", "--quick", "-o", str(d / "strategy.json"))
    return d


def test_front_tables_are_the_file(synthesis):
    data = json.loads((synthesis / "front.json").read_text())
    front = etpareto.read_front(synthesis)
    assert front.data == data
    assert front.epsilon == data["epsilon"]
    assert len(front.vertices) == len(data["vertices"]) > 0
    assert list(front.vertices["objectives_p_target"]) == [
        v["objectives"]["p_target"] for v in data["vertices"]]
    assert list(front.baselines["delta"]) == [b["delta"] for b in data["baselines"]]
    assert len(front.certified) == len(data["certified"]["points"])
    # The file itself or its folder.
    assert etpareto.read_front(synthesis / "front.json").data == data


def test_a_front_of_another_format_is_refused(tmp_path):
    bad = tmp_path / "front.json"
    bad.write_text('{"format_version": 1}')
    with pytest.raises(etpareto.FileFormatError) as e:
        etpareto.read_front(bad)
    assert str(e.value).startswith(f"loading {bad}: front format version 1 is not supported")


def test_strategy_omega_is_the_policy(synthesis):
    data = json.loads((synthesis / "strategy.json").read_text())
    s = etpareto.read_strategy(synthesis / "strategy.json")
    assert s.data == data
    assert s.predicted is None  # --quick: no prediction
    n_deltas = len(data["deltas"])
    assert len(s.omega) == len(data["states"]) * n_deltas
    sums = s.omega.groupby("state")["omega"].sum()
    assert ((sums - 1.0).abs() < 1e-9).all()
    for i, state in enumerate(data["states"]):
        rows = s.omega[s.omega["state"] == i]
        assert list(rows["omega"]) == state["omega"]
        assert list(rows["delta"]) == data["deltas"]
        assert set(rows["decision_point"]) == {state["decision_point"]}


def test_an_edited_strategy_raises_the_cli_message(synthesis, tmp_path):
    text = (synthesis / "strategy.json").read_text()
    edited = tmp_path / "strategy.json"
    data = json.loads(text)
    data["label"] = data["label"] + " (edited)"
    edited.write_text(json.dumps(data, indent=2))
    with pytest.raises(etpareto.FileFormatError) as e:
        etpareto.read_strategy(edited)
    assert str(e.value) == etp_error("validate", str(edited))
