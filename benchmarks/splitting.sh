#!/usr/bin/env bash
# Adaptive splitting (docs/performance.md, "Descriptors, lumping,
# splitting"): three random n = 4 agents synthesized without and with two
# rounds of splitting (budget 40), two requests each (the full KF's P_tar
# − 0.5 and − 2 pt, read from `etp simulate --delta 0`), validated on 3000
# episodes. About 25 min on 2 cores (estimated).
set -euo pipefail
source "$(dirname "$0")/common.sh"
for seed in 1 2 3; do
  s="$OUT/n4-$seed.toml"
  "$ETP" scenario random --dim-agent 4 --seed "$seed" -o "$s" --force
  kf=$("$ETP" simulate "$s" --delta 0 --episodes 1000 --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["p_target"])')
  for split in off on; do
    opts=(--samples 2000 --holdout-samples 2000 --no-kf-baseline --aggregation-episodes 10000)
    [ "$split" = on ] && opts+=(--split-budget 40 --split-rounds 2 --split-episodes 10000)
    "$ETP" synthesize "$s" "${opts[@]}" -o "$OUT/n4-$seed-$split" --force > /dev/null
    for drop in 0.005 0.02; do
      target=$(python3 -c "print(round($kf - $drop, 4))")
      "$ETP" strategy "$OUT/n4-$seed-$split" --min-target "$target" --quick -o "$OUT/n4-$seed-$split/s$drop.json" --force > /dev/null || continue
      "$ETP" validate "$OUT/n4-$seed-$split/s$drop.json" --episodes 3000 --json > "$OUT/n4-$seed-$split-$drop.validate.json" || [ $? -eq 6 ]
      echo "seed $seed, splitting $split, KF − $drop: $OUT/n4-$seed-$split-$drop.validate.json"
    done
  done
done
