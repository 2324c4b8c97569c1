#!/usr/bin/env bash
# Predictions on fresh scenarios (docs/performance.md, "Predictions on fresh
# scenarios"): the study benchmarks/fresh-scenarios.toml, then the same on
# five random agents under a lossy radio (loss 0.2, aware filter), whose
# scenario files are made here. Each case's row says whether the strategy met
# its request and every miss of the prediction with its sign
# (`OUT/*/study.csv`). Several hours on 2 cores.
set -euo pipefail
source "$(dirname "$0")/common.sh"
"$ETP" study benchmarks/fresh-scenarios.toml -o "$OUT/ideal" --json > "$OUT/ideal.json"
mkdir -p "$OUT/lossy"
for n_seed in 4:301 4:302 4:303 4:304 6:205; do
  n=${n_seed%%:*} seed=${n_seed##*:}
  "$ETP" scenario random --dim-agent "$n" --seed "$seed" -o "$OUT/lossy/n$n-$seed.toml" --force
  "$ETP" scenario radio "$OUT/lossy/n$n-$seed.toml" --loss 0.2 --estimator aware -o "$OUT/lossy/n$n-$seed-l0.2.toml" --force
done
{
  echo 'scenarios = ["n4-301-l0.2.toml", "n4-302-l0.2.toml", "n4-303-l0.2.toml", "n4-304-l0.2.toml", "n6-205-l0.2.toml"]'
  echo 'requests = [{ min_target = "kf-0.005" }, { min_target = "kf-0.02" }, { min_target = "kf-0.04" }]'
  echo 'episodes = 3000'
} > "$OUT/lossy/spec.toml"
"$ETP" study "$OUT/lossy/spec.toml" -o "$OUT/lossy/study" --json > "$OUT/lossy.json"
