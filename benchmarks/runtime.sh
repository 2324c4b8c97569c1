#!/usr/bin/env bash
# The multi-process runtime (docs/performance.md, "Runtime"): `etp run`'s
# steps per second (the episodes alone, `steps_per_second`) plain and
# recorded, ROUNDS interleaved rounds of 100 winding-2d episodes; the
# recording's size; then the live view's cost through live/bench_speed.py.
# About 5 min on 2 cores, idle.
set -euo pipefail
source "$(dirname "$0")/common.sh"
ROUNDS=${ROUNDS:-7}
rate() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["steps_per_second"])' "$1"; }
run=(--scenario winding-2d --delta 1.4986 --episodes 100 --seed 3 --json)
for round in $(seq "$ROUNDS"); do
  "$ETP" run "${run[@]}" > "$OUT/plain.json"
  "$ETP" run "${run[@]}" --record "$OUT/run.mcap" --force > "$OUT/recorded.json"
  echo "round $round: plain $(rate "$OUT/plain.json") steps/s, recorded $(rate "$OUT/recorded.json") steps/s, $(stat -c %s "$OUT/run.mcap") bytes"
done
"$ETP" replay verify "$OUT/run.mcap" > /dev/null && echo "the last recording verifies"
python3 live/bench_speed.py "$ETP" 10 100
