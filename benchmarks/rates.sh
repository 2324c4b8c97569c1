#!/usr/bin/env bash
# Measured trigger rates against each family's model rate, and NEES/n, at
# every δ of three scenarios (docs/performance.md, "Trigger families"):
# `trigger_rate` against `trigger_rate_expected` of `etp simulate --json`.
# A few minutes on 2 cores; EPISODES=300 makes it a quick check.
set -euo pipefail
source "$(dirname "$0")/common.sh"
EPISODES=${EPISODES:-3000}
"$ETP" scenario random --dim-agent 4 --seed 9103 -o "$OUT/random-n4-s9103.toml" --force
for scenario in winding-2d inertia-2d "$OUT/random-n4-s9103.toml"; do
  for family in box stochastic periodic variance send-on-delta; do
    for delta in 1.0518 1.4986 1.9488 2.2365; do
      "$ETP" simulate "$scenario" --trigger "$family" --delta "$delta" --episodes "$EPISODES" --seed 17 --json \
        > "$OUT/sim.json"
      python3 -c 'import json,sys; v=json.load(open(sys.argv[1])); print(sys.argv[2], sys.argv[3], sys.argv[4], "rate", v.get("trigger_rate"), "expected", v.get("trigger_rate_expected"), "nees/n", v.get("nees"))' \
        "$OUT/sim.json" "$(basename "$scenario" .toml)" "$family" "$delta"
    done
  done
done
