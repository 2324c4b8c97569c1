"""run: a multi-process run through the launcher, its report the dict of
`etp run --json`; its recording read back."""

from __future__ import annotations

import pytest

import etpareto
from conftest import REPO, etp_bin, etp_error, etp_json
from test_recording import check_against_cli


def test_a_run_reports_like_the_cli_and_its_recording_reads_back(tmp_path):
    rec = tmp_path / "run.mcap"
    r = etpareto.run(scenario="open-2d", delta=1.0518, episodes=3, seed=7, record=rec,
                     bin_dir=etp_bin().parent)
    assert r.clean, r.problems
    assert r.exit_code == 0
    rep = r.report
    assert rep["episodes"] == 3 and rep["seed"] == 7 and rep["scenario"] == "open-2d"
    assert isinstance(rep["run_id"], str)
    # The same seed run by the CLI: the same outcomes and per-sensor counts
    # (the processes are deterministic given the seed).
    cli = etp_json("run", "--scenario", "open-2d", "--delta", "1.0518", "--episodes", "3",
                   "--seed", "7", "--json")
    for key in ("p_target", "p_collision", "p_free", "transmissions", "received"):
        assert rep[key] == cli[key], key
    assert [(s["name"], s["transmissions"]) for s in rep["sensors"]] == [
        (s["name"], s["transmissions"]) for s in cli["sensors"]]
    assert list(r.sensors["name"]) == [s["name"] for s in cli["sensors"]]
    tables, info = check_against_cli(rec, tmp_path)
    assert len(tables["outcome"]) == 3
    # The recording is this run's: its id in the file, one run tag (the
    # header's 64-bit hash of the id, a string) in every table.
    assert info["run_id"] == rep["run_id"]
    # A new recording is format 7: every channel protobuf.
    assert info["format_version"] == 7
    assert {c["message_encoding"] for c in info["channels"]} == {"protobuf"}
    tags = set().union(*(set(df["run"]) for df in tables.values()))
    assert len(tags) == 1 and next(iter(tags)).isdigit()

def test_a_bad_request_raises_the_cli_message():
    with pytest.raises(etpareto.RunError) as e:
        etpareto.run(scenario="open-2d", delta=1.0518, episodes=0, bin_dir=etp_bin().parent)
    # The launcher's own refusal (the same check as for a run file), naming
    # the option and its range.
    assert "--episodes must be at least 1" in str(e.value)


def test_run_keys_are_a_run_files_keys_each_checked_by_name(tmp_path):
    # Nothing runs: each request is refused before any process starts.
    with pytest.raises(etpareto.RunError) as e:
        etpareto.run(scenario="open-2d", delta=1.0518, episodez=3, bin_dir=etp_bin().parent)
    assert "episodez" in str(e.value)
    with pytest.raises(etpareto.RunError) as e:
        etpareto.run(scenario="open-2d", delta=1.0518, loss="high", bin_dir=etp_bin().parent)
    assert "`loss`" in str(e.value)
    with pytest.raises(etpareto.RunError) as e:
        etpareto.run(scenario="open-2d", delta=1.0518, listen="tls/127.0.0.1:7447",
                     bin_dir=etp_bin().parent)
    assert "`listen` and `remote` go together" in str(e.value)
    # A run file under the keys: its own refusals name the file.
    file = tmp_path / "run.toml"
    file.write_text('scenario = "open-2d"\nestimator = "clever"\n')
    with pytest.raises(etpareto.RunError) as e:
        etpareto.run(delta=1.0518, config=file, bin_dir=etp_bin().parent)
    assert str(file) in str(e.value) and "`clever`" in str(e.value)


def refused_like_the_cli(cls, cli_args, **request):
    """A run Python refuses with exactly `cls` — still a RunError and an
    EtpError, what older code catches — whose message is the text `etp run`
    prints after `error: ` for the same request."""
    with pytest.raises(etpareto.RunError) as e:
        etpareto.run(bin_dir=etp_bin().parent, **request)
    assert type(e.value) is cls, (type(e.value), str(e.value))
    assert isinstance(e.value, etpareto.EtpError)
    assert str(e.value) == etp_error("run", *cli_args)
    return str(e.value)


def test_each_kind_of_refused_run_raises_its_own_class_with_the_cli_message(tmp_path):
    # Nothing runs: each request is refused before any process starts.
    run = ("--scenario", "open-2d", "--delta", "1.0518")
    file = tmp_path / "run.toml"
    file.write_text('scenario = "open-2d"\ndelta = 1.0518\nepisodes = 0\n')
    text = refused_like_the_cli(etpareto.RunRequestError, ["--config", str(file)], config=file)
    assert text == f"run file {file}: --episodes must be at least 1"
    refused_like_the_cli(etpareto.RunRequestError, [*run, "--record", str(tmp_path)],
                         scenario="open-2d", delta=1.0518, record=tmp_path)
    refused_like_the_cli(etpareto.RunRequestError, [*run, "--run-id", "Not An Id"],
                         scenario="open-2d", delta=1.0518, run_id="Not An Id")
    # A run file's own errors name it once (as `etp run --config` prints them).
    bad = tmp_path / "bad.toml"
    bad.write_text('scenario = "open-2d"\ndelta = 1.0518\nestimator = "clever"\n')
    text = refused_like_the_cli(etpareto.RunRequestError, ["--config", str(bad)], config=bad)
    assert text.count(str(bad)) == 1 and "`clever`" in text
    missing = tmp_path / "missing.toml"
    refused_like_the_cli(etpareto.RunOutputError, ["--config", str(missing)], config=missing)
    refused_like_the_cli(etpareto.RunScenarioError,
                         ["--scenario", "no-such-scenario", "--delta", "1.0518"],
                         scenario="no-such-scenario", delta=1.0518)
    strategy = tmp_path / "strategy.json"
    strategy.write_text("{}\n")
    refused_like_the_cli(etpareto.RunStrategyError, [str(strategy)], strategy=strategy)


def test_run_binaries_not_found_raise_run_binary_error(tmp_path):
    # An empty folder as the processes' folder: the run stops at the first
    # process it would start.
    with pytest.raises(etpareto.RunBinaryError) as e:
        etpareto.run(scenario="open-2d", delta=1.0518, episodes=1, predict_episodes=1,
                     bin_dir=tmp_path)
    assert isinstance(e.value, etpareto.RunError)
    assert f"ETP_PROCESS_DIR={tmp_path}" in str(e.value)


def test_every_run_class_is_a_run_error():
    classes = [etpareto.RunRequestError, etpareto.RunScenarioError, etpareto.RunStrategyError,
               etpareto.RunOutputError, etpareto.RunIdInUseError, etpareto.RunLinkError,
               etpareto.RunLiveError, etpareto.RunBinaryError, etpareto.RunProcessError,
               etpareto.RunExit]
    assert all(issubclass(c, etpareto.RunError) for c in classes)
    assert len(set(classes)) == len(classes)
