#!/usr/bin/env bash
# The simulator's throughput (docs/performance.md, "Simulator"): episode-steps
# per second on one thread and on all threads, at δ = 0 and at the largest δ,
# per scenario and trigger family. EPISODES and REPEATS shrink it to a check.
#   bash benchmarks/simulator.sh                 # a few minutes on 2 cores
#   EPISODES=200 REPEATS=1 bash benchmarks/simulator.sh   # seconds
set -euo pipefail
source "$(dirname "$0")/common.sh"
EPISODES=${EPISODES:-8000}
REPEATS=${REPEATS:-5}
for scenario in winding-2d inertia-2d inertia-3d; do
  for family in box stochastic send-on-delta; do
    "$ETP" bench "$scenario" --trigger "$family" --episodes "$EPISODES" --repeats "$REPEATS" --json \
      > "$OUT/$scenario-$family.json"
    echo "$scenario $family: $(tr -d '\n' < "$OUT/$scenario-$family.json" | head -c 300)…"
  done
done
