"""to_stormpy: a synthesis as a stormpy model, the one `etp export --format
drn` writes, with its labels, choice labels and reward; Storm's answers on it
equal the front's extremes and `etp strategy --quick`'s exact energy."""

from __future__ import annotations

import builtins

import pytest
import stormpy

import etpareto
from conftest import etp, etp_json


@pytest.fixture(scope="module")
def synthesis(tmp_path_factory):
    root = tmp_path_factory.mktemp("storm")
    return etpareto.synthesize(
        "winding-2d", root / "w", samples=100, seed=3, kf_baseline=False,
        aggregation_episodes=0,
    )


def value(model, formula):
    prop = stormpy.parse_properties(formula)[0]
    res = stormpy.model_checking(model, prop, only_initial_states=True)
    return res.get_value(model.initial_states[0])


def test_the_model_is_the_drn_export(synthesis, tmp_path):
    model = etpareto.to_stormpy(synthesis)
    states = synthesis.report["mdp"]["states"]
    assert model.nr_states == states + 3
    assert {"init", "coll", "tar", "free"} <= set(model.labeling.get_labels())
    assert list(model.reward_models) == ["energy"]
    assert model.has_choice_labeling()
    assert "done" in model.choice_labeling.get_labels()
    # The same model as Storm's reading of the CLI's file.
    etp("export", str(synthesis.dir), str(tmp_path / "drn"), "--format", "drn")
    cli = stormpy.build_model_from_drn(str(tmp_path / "drn" / "model.drn"))
    assert (cli.nr_states, cli.nr_choices, cli.nr_transitions) == (
        model.nr_states, model.nr_choices, model.nr_transitions)
    # A folder path works as well as the Synthesis.
    assert etpareto.to_stormpy(str(synthesis.dir)).nr_transitions == model.nr_transitions


def test_storm_agrees_with_the_front_and_the_strategy(synthesis, tmp_path):
    model = etpareto.to_stormpy(synthesis)
    vertices = [v["objectives"] for v in synthesis.front.data["vertices"]]
    assert abs(value(model, 'Pmax=? [ F "tar" ]') - max(v["p_target"] for v in vertices)) <= 1e-9
    assert abs(value(model, 'Pmin=? [ F "coll" ]') - min(v["p_collision"] for v in vertices)) <= 1e-9
    lo = min(v["p_target"] for v in vertices)
    hi = max(v["p_target"] for v in vertices)
    p = lo + 0.7 * (hi - lo)
    quick = etp_json("strategy", str(synthesis.dir), "--min-target", repr(p), "--quick",
                     "-o", str(tmp_path / "s.json"), "--json")
    ours = quick["diagnostics"]["selection_time"]["energy_mean"]
    # Storm's default multi-objective precision: 1e-4, absolute.
    storm = value(model, 'multi(R{"energy"}min=? [ C ], P>=%r [ F "tar" ])' % p)
    assert abs(storm - ours) <= 1e-4, (storm, ours)


def test_without_stormpy_the_error_says_how_to_install_it(synthesis, monkeypatch):
    real_import = builtins.__import__

    def no_stormpy(name, *args, **kwargs):
        if name == "stormpy" or name.startswith("stormpy."):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_stormpy)
    with pytest.raises(ImportError, match="pip install stormpy"):
        etpareto.to_stormpy(synthesis)


def test_a_folder_without_an_mdp_is_a_file_format_error(tmp_path):
    with pytest.raises(etpareto.SynthesisError, match="mdp.bin") as e:
        etpareto.to_stormpy(tmp_path)
    assert isinstance(e.value, etpareto.FileFormatError)
