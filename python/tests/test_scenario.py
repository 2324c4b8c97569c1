"""load_scenario: built-ins and TOML paths, and the CLI's error messages."""

from __future__ import annotations

import pytest

import etpareto
from conftest import REPO, etp_error, etp_json


def test_builtins_load_and_match_etp_check():
    names = etpareto.builtin_scenarios()
    assert "winding-2d" in names and len(names) == 5
    for name in names:
        s = etpareto.load_scenario(name)
        check = etp_json("check", name, "--json")
        assert s.name == check["name"]
        assert s.dim == check["dim"]
        assert s.content_hash == check["content_hash"]
        assert s.sensors == [x["name"] for x in check["sensors"]]
        assert s.legs == [leg["sensor"] for leg in check["legs"]]
        assert s.deltas == [t["delta"] for t in check["thresholds"]]
        assert s.warnings == check["warnings"]


def test_a_toml_path_is_the_same_scenario_as_its_builtin():
    from_file = etpareto.load_scenario(REPO / "scenarios" / "winding-2d.toml")
    builtin = etpareto.load_scenario("winding-2d")
    assert from_file.content_hash == builtin.content_hash
    assert from_file.source.endswith("winding-2d.toml")


def test_a_missing_file_raises_the_cli_message():
    with pytest.raises(etpareto.ScenarioError) as e:
        etpareto.load_scenario("/nonexistent/x.toml")
    assert str(e.value) == etp_error("check", "/nonexistent/x.toml")
    assert str(e.value).startswith("`/nonexistent/x.toml` is neither a built-in scenario")
    assert isinstance(e.value, etpareto.EtpError)


def test_an_invalid_file_raises_the_cli_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[plant]\nA = "not a matrix"\n')
    with pytest.raises(etpareto.ScenarioError) as e:
        etpareto.load_scenario(bad)
    assert str(e.value) == etp_error("check", str(bad))
    assert str(e.value).startswith(f"scenario file {bad}: ")
