#!/usr/bin/env bash
# The Python package's check, from a clean state: a fresh venv under
# target/ (target/pyvenv-etpareto), the package installed by the README's
# one command (`pip install ./python`, maturin as its build backend), the
# CLI built for the comparisons, and pytest. A missing tool fails the
# script (never a skip) and says how to get it.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
# Cargo's target folder (CARGO_TARGET_DIR when set, as cargo itself does).
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
VENV=${ETPARETO_VENV:-$TARGET/pyvenv-etpareto}
PYTHON=${PYTHON:-python3}

need() {
  command -v "$1" >/dev/null 2>&1 || {
    echo "python/ci.sh: \`$1\` is missing: $2" >&2
    exit 1
  }
}
need "$PYTHON" "install CPython ≥ 3.9 (Debian: apt-get install -y python3 python3-venv python3-dev) or set PYTHON"
need cargo "install Rust (https://rustup.rs) — the package compiles the workspace's crates"
"$PYTHON" -c 'import sys; assert sys.version_info >= (3, 9), sys.version' || {
  echo "python/ci.sh: $PYTHON is older than 3.9" >&2
  exit 1
}
"$PYTHON" -m venv --help >/dev/null 2>&1 || {
  echo "python/ci.sh: $PYTHON has no venv module (Debian: apt-get install -y python3-venv)" >&2
  exit 1
}

# A fresh venv each time: what a user gets from the README's command.
rm -rf "$VENV"
"$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --upgrade pip
# stormpy (Storm's Python API, wheels for CPython 3.11): etpareto.to_stormpy's tests.
"$VENV/bin/python" -m pip install --quiet maturin pytest pandas numpy \
  nbformat nbclient ipykernel matplotlib stormpy==2.0.0 || {
  echo "python/ci.sh: pip could not install maturin, pytest, pandas, numpy, nbformat, nbclient, ipykernel, matplotlib, stormpy==2.0.0 (is PyPI reachable? stormpy has wheels for CPython 3.11 on Linux x86-64 and aarch64)" >&2
  exit 1
}
# The README's command. It builds the extension in the workspace's
# target/release (shared with `cargo build --release`).
"$VENV/bin/python" -m pip install --quiet ./python
# The CLI and the run's processes, for the comparisons and etpareto.run.
# `cargo test --no-run`, not `cargo build -p …`: the feature set of the
# workspace's tests, so that after `.ci/run`'s `cargo test` nothing is rebuilt
# (a `cargo build -p …` resolves features apart and rebuilt every crate, 4 min).
cargo test --release --workspace --no-run
# Run from python/tests so `import etpareto` is the installed package, not
# the source folder.
cd "$ROOT/python/tests"
ETP_BIN="$TARGET/release/etp" "$VENV/bin/python" -m pytest -q -p no:cacheprovider "$@"
# The example: the constant-δ table of winding-2d, every row checked
# against `etp simulate --json` (it fails on any difference).
cd "$ROOT"
"$VENV/bin/python" python/examples/baselines.py winding-2d --episodes 300 --seed 7 \
  --check "$TARGET/release/etp"
# The example notebook (python/examples/demo.ipynb): executed end to end
# in a kernel of the venv (nbclient), at CI's sizes, its last cell checking
# every number against `etp demo --json` for the same seeds (ETP_NB_CHECK:
# that comparison must run).
NB_OUT=$(mktemp -d "$TARGET/notebook-XXXXXX")
trap 'rm -rf "$NB_OUT"' EXIT
ETP_BIN="$TARGET/release/etp" ETP_PROCESS_DIR="$TARGET/release" ETP_NB_CHECK=1 \
  ETP_NB_SAMPLES=1500 ETP_NB_VALIDATE_EPISODES=1000 ETP_NB_RUN_EPISODES=40 ETP_NB_SEED=0 \
  ETP_NB_OUT="$NB_OUT" \
  "$VENV/bin/python" - <<'PY'
import os
import sys

import nbformat
from jupyter_client.manager import KernelManager
from nbclient import NotebookClient

path = "python/examples/demo.ipynb"
nb = nbformat.read(path, as_version=4)
# The kernel over IPC sockets (files in the run's own folder), not TCP.
km = KernelManager(kernel_name="python3", transport="ipc",
                   ip=os.path.join(os.environ["ETP_NB_OUT"], "kernel"))
try:
    NotebookClient(nb, timeout=1200, km=km).execute()
finally:
    # A kernel manager handed in is not shut down by nbclient: do it here,
    # so no kernel outlives the run.
    if km.has_kernel:
        km.shutdown_kernel(now=False)
outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
figures = sum("image/png" in o.get("data", {}) for o in outputs)
last = "".join(o.get("text", "") for o in nb.cells[-1].outputs if o.get("output_type") == "stream")
print(f"{path}: executed, {len(nb.cells)} cells, {figures} figures; last cell: {last.strip()}")
# The demo's figures: the front (drawn here and etp's), the map, the recording's sends.
if figures < 4:
    sys.exit(f"{path}: {figures} figures, expected 4")
if "every number equals" not in last:
    sys.exit(f"{path}: the comparison with etp demo did not run")
PY
