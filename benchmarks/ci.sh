#!/usr/bin/env bash
# The time of CI (docs/performance.md, "CI"): `.ci/run` on a fresh clone of
# the current commit, wall seconds. Cold (an empty target/) by default; with
# WARM=1 the clone starts from a copy of this checkout's target/.
# About 30 min on 2 cores.
set -euo pipefail
source "$(dirname "$0")/common.sh"
rm -rf "$OUT/clone"
git clone --quiet . "$OUT/clone"
if [ "${WARM:-0}" = 1 ]; then cp -a target/release "$OUT/clone/target-release-copy" && mkdir -p "$OUT/clone/target" && mv "$OUT/clone/target-release-copy" "$OUT/clone/target/release"; fi
t=$(now)
(cd "$OUT/clone" && bash .ci/run) > "$OUT/ci.log" 2>&1
echo ".ci/run: exit 0 in $(elapsed "$t") s (log: $OUT/ci.log)"
