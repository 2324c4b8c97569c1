"""etpareto.study against ``etp study --json``: the same table and the same
files from a SPEC file or its dict; a refused SPEC raises the class of its
kind, naming the key, with the CLI's message."""

from __future__ import annotations

import json

import pytest

import etpareto
from conftest import etp_error, etp_json

# One job (open-2d under its own trigger family) × one request, small.
SPEC = {
    "scenarios": ["open-2d"],
    "requests": [{"min_target": 0.8}],
    "samples": 200,
    "episodes": 300,
    "aggregation_check": 200,
    "replicates": 2,
    "rounds": 2,
}
TOML = """scenarios = ["open-2d"]
requests = [{ min_target = 0.8 }]
samples = 200
episodes = 300
aggregation_check = 200
replicates = 2
rounds = 2
"""


def test_a_study_s_table_is_the_cli_s_from_a_file_or_a_dict(tmp_path):
    spec = tmp_path / "tiny.toml"
    spec.write_text(TOML)
    cli = etp_json("study", str(spec), "-o", str(tmp_path / "cli"), "--json")
    calls = []
    py = etpareto.study(
        spec, tmp_path / "py", progress=lambda stage, done, total: calls.append(stage)
    )
    assert py == cli
    assert py["study"] == "tiny" and len(py["rows"]) == 1
    assert py["rows"] == cli["rows"]
    assert calls, "the progress callback was never called"
    for f in ["study.json", "study.csv", "spec.json", "cases/00-open-2d-box/strategy-0.json"]:
        assert (tmp_path / "py" / f).read_bytes() == (tmp_path / "cli" / f).read_bytes(), f
    assert json.loads((tmp_path / "py" / "study.json").read_text()) == py
    # The same SPEC as a dict (named as the file is) resumes the folder:
    # every case is finished, the table is the same.
    again = etpareto.study({**SPEC, "name": "tiny"}, out=tmp_path / "py")
    assert again == cli
    # Another SPEC in that folder is refused, naming what differs.
    with pytest.raises(etpareto.OutputError, match="settings.samples 200 in the folder, 201"):
        etpareto.study({**SPEC, "name": "tiny", "samples": 201}, out=tmp_path / "py")


@pytest.mark.parametrize(
    "text, key, cls",
    [
        ('scenarios = ["open-2d"]\nsampels = 3\n', "sampels", etpareto.StudySpecError),
        (
            'scenarios = ["open-2d"]\nrequests = [{ min_target = 1.2 }]\n',
            "requests[0].min_target",
            etpareto.StudySpecError,
        ),
        ('scenarios = ["open-2d"]\nfamilies = ["boxy"]\n', "families", etpareto.StudySpecError),
        ('scenarios = ["nowhere-2d"]\n', "scenarios[0]", etpareto.ScenarioError),
    ],
)
def test_a_bad_spec_raises_its_class_naming_the_key(tmp_path, text, key, cls):
    spec = tmp_path / "bad.toml"
    spec.write_text(text)
    out = tmp_path / "out"
    message = etp_error("study", str(spec), "-o", str(out))
    with pytest.raises(cls) as raised:
        etpareto.study(spec, out)
    assert str(raised.value) == message
    assert key in message
    assert isinstance(raised.value, etpareto.EtpError)
    assert not (out / "spec.json").exists()


def test_a_bad_dict_spec_names_the_key(tmp_path):
    with pytest.raises(etpareto.StudySpecError, match="sampels"):
        etpareto.study({"scenarios": ["open-2d"], "sampels": 3}, tmp_path / "out")
    with pytest.raises(etpareto.StudySpecError, match=r"replicates: 2 to 64"):
        etpareto.study({"scenarios": ["open-2d"], "replicates": 1}, tmp_path / "out")
    with pytest.raises(etpareto.StudySpecError, match="reading study spec"):
        etpareto.study(tmp_path / "missing.toml", tmp_path / "out")
