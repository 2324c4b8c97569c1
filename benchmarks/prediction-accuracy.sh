#!/usr/bin/env bash
# The prediction against a precise reference (docs/performance.md,
# "Prediction accuracy"): the study benchmarks/prediction-accuracy.toml, then
# every strategy it wrote simulated on 100 000 episodes (`etp validate`,
# seed 1); a validate exit 6 is a failed check, reported, not an error.
set -euo pipefail
source "$(dirname "$0")/common.sh"
"$ETP" study benchmarks/prediction-accuracy.toml -o "$OUT/study" --json > "$OUT/study.json"
for s in "$OUT"/study/cases/*/strategy-*.json; do
  code=0
  "$ETP" validate "$s" --episodes 100000 --seed 1 --json > "${s%.json}-reference.json" || code=$?
  [ "$code" -eq 0 ] || [ "$code" -eq 6 ]
  echo "$s: reference exit $code"
done
