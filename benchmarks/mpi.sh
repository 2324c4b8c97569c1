#!/usr/bin/env bash
# MPI efficiency on one machine (docs/performance.md, "MPI"): each command on
# 1 rank and on 2 ranks of one thread each, interleaved ROUNDS times; the
# medians give E = T1 / (2 T2). Needs Open MPI and the MPI build:
#   cargo build --release -p etp --features mpi
# Every 2-rank output is compared with the 1-rank one byte for byte.
# About 20 min on 2 cores (the 20 000-sample rows take 5 of them).
set -euo pipefail
source "$(dirname "$0")/common.sh"
ROUNDS=${ROUNDS:-3}
mpi() { mpirun --oversubscribe -n "$1" -x RAYON_NUM_THREADS=1 "${@:2}"; }
[ "$(id -u)" -eq 0 ] && mpi() { mpirun --allow-run-as-root --oversubscribe -n "$1" -x RAYON_NUM_THREADS=1 "${@:2}"; }
"$ETP" synthesize winding-2d --samples 2000 -o "$OUT/strategy-source" --force > /dev/null
"$ETP" strategy "$OUT/strategy-source" --min-target 0.9 -o "$OUT/strategy.json" --force > /dev/null
for round in $(seq "$ROUNDS"); do
  for ranks in 1 2; do
    for samples in 2000 6000 20000; do
      t=$(now)
      mpi "$ranks" "$ETP" synthesize winding-2d --no-kf-baseline --samples "$samples" -o "$OUT/s$samples-r$ranks" --force > /dev/null
      echo "synthesize S=$samples ranks=$ranks round=$round: $(elapsed "$t") s"
    done
    t=$(now)
    mpi "$ranks" "$ETP" validate "$OUT/strategy.json" --episodes 100000 --json > "$OUT/validate-r$ranks.json"
    echo "validate 100000 ranks=$ranks round=$round: $(elapsed "$t") s"
    t=$(now)
    mpi "$ranks" "$ETP" simulate winding-2d --delta 1.4986 --episodes 100000 --json > "$OUT/simulate-r$ranks.json"
    echo "simulate 100000 ranks=$ranks round=$round: $(elapsed "$t") s"
    t=$(now)
    mpi "$ranks" "$ETP" study benchmarks/mpi-study.toml -o "$OUT/study-r$ranks-$round" > /dev/null
    echo "study (4 jobs) ranks=$ranks round=$round: $(elapsed "$t") s"
  done
done
for samples in 2000 6000 20000; do
  cmp "$OUT/s$samples-r1/mdp.bin" "$OUT/s$samples-r2/mdp.bin"
  cmp "$OUT/s$samples-r1/front.json" "$OUT/s$samples-r2/front.json"
done
echo "2-rank outputs are the 1-rank bytes"
