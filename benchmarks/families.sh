#!/usr/bin/env bash
# Trigger families compared (docs/performance.md, "Trigger families"): each
# family's own synthesis of a scenario, the least energy each needs for two
# requests (`etp compare`, ratios to box), the fronts on one figure and the
# literature's error-vs-rate curves. SCENARIO (default winding-2d) and the
# requests (KF − 2 pt and KF − 5 pt of winding-2d) can be changed.
# About 25 min per scenario on 2 cores.
set -euo pipefail
source "$(dirname "$0")/common.sh"
SCENARIO=${SCENARIO:-winding-2d}
TARGETS=${TARGETS:-0.9417,0.9117}
dirs=()
for family in box stochastic send-on-delta periodic variance; do
  "$ETP" synthesize "$SCENARIO" --trigger "$family" -o "$OUT/$SCENARIO-$family" --force > /dev/null
  dirs+=("$OUT/$SCENARIO-$family")
done
"$ETP" compare "${dirs[@]}" --min-target "$TARGETS" --json > "$OUT/$SCENARIO-compare.json"
"$ETP" fronts "${dirs[@]}" --max-collision 0.05,0.1 -o "$OUT/$SCENARIO-fronts" --force
"$ETP" trigger-curves "$SCENARIO" -o "$OUT/$SCENARIO-curves" --force --json > "$OUT/$SCENARIO-curves.json"
"$ETP" compare "${dirs[@]}" --min-target "$TARGETS"
