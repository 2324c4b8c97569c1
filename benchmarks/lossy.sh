#!/usr/bin/env bash
# The lossy radio (docs/performance.md, "Lossy radio"): winding-2d
# synthesized for the ideal radio and for losses 0.1 and 0.3 (aware filter),
# one request (P_tar ≥ 0.7822, P_coll ≤ 0.07), each strategy validated under
# its own channel and the ideal one under the lossy channels; the fronts of
# the syntheses (and loss 0.3 with the naive filter) on one figure.
# About 10 min on 2 cores (estimated).
set -euo pipefail
source "$(dirname "$0")/common.sh"
for loss in 0 0.1 0.3; do
  if [ "$loss" = 0 ]; then scenario=winding-2d; else
    scenario="$OUT/winding-loss$loss.toml"
    "$ETP" scenario radio winding-2d --loss "$loss" --estimator aware -o "$scenario" --force
  fi
  "$ETP" synthesize "$scenario" -o "$OUT/w$loss" --force > /dev/null
  "$ETP" strategy "$OUT/w$loss" --min-target 0.7822 --max-collision 0.07 --force > /dev/null
  "$ETP" validate "$OUT/w$loss/strategy.json" --episodes 3000 --seed 11 --json > "$OUT/validate-w$loss.json"
  echo "synthesized for loss $loss: $OUT/validate-w$loss.json"
done
# The ideal-radio strategy evaluated under loss (a robustness study; its checks
# fail by design, exit 6).
for loss in 0.1 0.3; do
  "$ETP" validate "$OUT/w0/strategy.json" --loss "$loss" --episodes 3000 --seed 11 --json \
    > "$OUT/ideal-under-loss$loss.json" || [ $? -eq 6 ]
done
# Loss 0.3 with the naive filter (a lost packet read as silence), for the figure.
"$ETP" scenario radio winding-2d --loss 0.3 --estimator naive -o "$OUT/winding-loss0.3-naive.toml" --force
"$ETP" synthesize "$OUT/winding-loss0.3-naive.toml" -o "$OUT/w0.3n" --force > /dev/null
"$ETP" fronts "$OUT/w0" "$OUT/w0.1" "$OUT/w0.3" "$OUT/w0.3n" --max-collision 0.07 -o "$OUT/loss-fronts" --force
