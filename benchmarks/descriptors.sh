#!/usr/bin/env bash
# The choices of docs/MODEL.md §7 on inertia-2d (docs/performance.md,
# "Descriptors, lumping, splitting"): the MDP of each descriptor at
# comparable size, each asked for the least energy with P_tar ≥ 0.9383
# (the full KF's 0.9583 − 2 pt) and validated on 3000 episodes; then the
# default MDP lumped at α = 0.05 and 0.01. About 10 min on 2 cores (estimated).
set -euo pipefail
source "$(dirname "$0")/common.sh"
SCENARIO=${SCENARIO:-inertia-2d}
TARGET=${TARGET:-0.9383}
variant() { # name, then the synthesize options
  local name=$1; shift
  "$ETP" synthesize "$SCENARIO" --holdout-samples 0 --no-kf-baseline "$@" -o "$OUT/$name" --force --json > "$OUT/$name.synthesize.json"
  "$ETP" strategy "$OUT/$name" --min-target "$TARGET" --quick --force > /dev/null
  "$ETP" validate "$OUT/$name/strategy.json" --episodes 3000 --json > "$OUT/$name.validate.json" || [ $? -eq 6 ]
  echo "$name: $OUT/$name.validate.json"
}
variant default
variant per-axis --descriptor per-axis
variant lookahead0 --lookahead 0 --range propagation
variant lookahead5 --lookahead 5 --range propagation
variant lookahead10 --lookahead 10 --range propagation
variant lookahead20 --lookahead 20 --range propagation
variant merge0.05 --merge 0.05
variant merge0.01 --merge 0.01
