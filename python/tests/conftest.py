"""Shared fixtures: the repository, the CLI (`target/release/etp`, or
``ETP_BIN``) the package is compared with, and helpers to run it."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]


def etp_bin() -> Path:
    path = Path(os.environ.get("ETP_BIN", REPO / "target" / "release" / "etp"))
    if not path.is_file():
        # Fail, never skip: the comparison with the CLI is the point.
        pytest.fail(f"{path} is missing: cargo build --release -p etp (python/ci.sh does)")
    return path


def etp(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    """Run the CLI; its output as text."""
    out = subprocess.run(
        [str(etp_bin()), *args], capture_output=True, text=True, cwd=REPO
    )
    if check and out.returncode != 0:
        pytest.fail(f"etp {' '.join(args)} exited {out.returncode}: {out.stderr}")
    return out


def etp_json(*args: str) -> Any:
    return json.loads(etp(*args).stdout)


def etp_error(*args: str) -> str:
    """The message ``etp`` prints after ``error: `` for a failing command."""
    out = etp(*args, check=False)
    assert out.returncode == 1, (out.returncode, out.stderr)
    # `eprintln!("error: {e:#}")`: the message is what lies between.
    assert out.stderr.startswith("error: ") and out.stderr.endswith("\n"), out.stderr
    return out.stderr[len("error: "):-1]

@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO
