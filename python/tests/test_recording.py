"""read_recording: one DataFrame per channel, equal to `etp replay
export`'s tables, counts equal to `etp replay info` / `replay summary`."""

from __future__ import annotations

import pandas as pd
import pytest

import etpareto
from conftest import REPO, etp, etp_error, etp_json

FIXTURE = REPO / "recordings" / "fixtures" / "open-2d-4-episodes.mcap"


def check_against_cli(path, tmp_path):
    tables = etpareto.read_recording(path)
    info = etp_json("replay", "info", str(path), "--json")
    counts = {c["topic"]: c["messages"] for c in info["channels"]}
    assert {t: len(df) for t, df in tables.items()} == counts
    summary = etp_json("replay", "summary", str(path), "--json")
    assert {t: len(df) for t, df in tables.items()} == summary["counts"]
    # Every cell equals the CSV `etp replay export` writes.
    out = tmp_path / "export"
    etp("replay", "export", str(path), str(out))
    for topic, df in tables.items():
        csv = pd.read_csv(out / (topic.replace("/", "-") + ".csv"), dtype={"run": str},
                          keep_default_na=False, na_values=[""])
        assert list(df.columns) == list(csv.columns), topic
        for col in df.columns:
            got, want = df[col], csv[col]
            if pd.api.types.is_float_dtype(got):
                assert got.equals(want.astype(float)), (topic, col)
            elif pd.api.types.is_bool_dtype(got):
                assert list(got) == [str(x).lower() == "true" for x in want], (topic, col)
            else:
                text = [None if pd.isna(x) else str(x) for x in got]
                assert text == [None if pd.isna(x) else str(x) for x in want], (topic, col)
    return tables, info


def test_the_fixture_equals_the_cli_export(tmp_path):
    tables, info = check_against_cli(FIXTURE, tmp_path)
    # The run id is a string column (a 64-bit hash: no float rounding).
    for df in tables.values():
        assert df["run"].dtype == "string"
        assert df["run"].str.fullmatch(r"[0-9]+").all()
    assert tables["outcome"]["outcome"].isin(["target", "collision", "free"]).all()
    assert len(tables["outcome"]) == info["episodes"] == 4
    # The fixture is the old format (bincode channels): still read.
    assert info["format_version"] == 4
    assert {c["message_encoding"] for c in info["channels"]} == {"bincode2-serde-legacy"}


def test_metadata_comes_with_the_tables():
    tables, meta = etpareto.read_recording(FIXTURE, with_metadata=True)
    assert "outcome" in tables
    assert any("scenario" in name for name in meta)


def test_a_file_that_is_not_mcap_raises_the_cli_message(tmp_path):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    with pytest.raises(etpareto.RecordingNotEtpError) as e:
        etpareto.read_recording(bad)
    # Still a RecordingError, what older code catches.
    assert isinstance(e.value, etpareto.RecordingError)
    assert str(e.value) == etp_error("replay", "summary", str(bad))


def test_a_missing_file_is_unreadable_not_unfinished(tmp_path):
    missing = tmp_path / "missing.mcap"
    with pytest.raises(etpareto.RecordingUnreadableError) as e:
        etpareto.read_recording(missing)
    assert isinstance(e.value, etpareto.RecordingError)
    assert str(e.value) == etp_error("replay", "summary", str(missing))


def test_a_cut_file_is_refused_with_the_repair_hint(tmp_path):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(FIXTURE.read_bytes()[: FIXTURE.stat().st_size // 2])
    with pytest.raises(etpareto.RecordingUnfinishedError) as e:
        etpareto.read_recording(cut)
    assert isinstance(e.value, etpareto.RecordingError)
    assert "unfinished" in str(e.value) and "etp replay repair" in str(e.value)
