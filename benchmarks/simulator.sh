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
    python3 -c 'import json, sys
for r in json.load(open(sys.argv[1])):
    print("%s %s δ = %s, %s thread(s): %.2f M steps/s per thread" % (r["scenario"], r["trigger"],
          r["delta"], r["threads"], r["steps_per_second_per_thread"] / 1e6))' "$OUT/$scenario-$family.json"
  done
done
