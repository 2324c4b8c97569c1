#!/usr/bin/env bash
# The time of the default path (docs/performance.md, "The default path"):
# `etp synthesize SCENARIO` then `etp strategy DIR --min-target 0.95`, the
# plain command, on the built-ins of dimension 4 and 6, and `etp demo`;
# wall seconds of each, and the prediction each strategy stands by.
# About 5 min on 2 cores, idle.
set -euo pipefail
source "$(dirname "$0")/common.sh"
for scenario in winding-2d inertia-2d inertia-3d; do
  dir="$OUT/$scenario"
  t=$(now)
  "$ETP" synthesize "$scenario" -o "$dir" --force --json > "$dir.synthesize.json"
  synth=$(elapsed "$t")
  t=$(now)
  "$ETP" strategy "$dir" --min-target 0.95 --force --json > "$dir.strategy.json"
  strat=$(elapsed "$t")
  echo "$scenario: synthesize $synth s, strategy $strat s"
done
t=$(now)
"$ETP" demo -o "$OUT/demo" --json > "$OUT/demo.json"
echo "demo: $(elapsed "$t") s"
