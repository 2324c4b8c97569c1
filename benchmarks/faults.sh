#!/usr/bin/env bash
# Fault runs (docs/performance.md, "Faults"): four recorded runs of winding-2d
# (δ = 1.4986, 300 episodes) with both cores hogged by busy loops; A and B at
# once. A: stochastic trigger, loss 0.3, one retry, aware filter, sensor s0
# stopped for 2 s; B: send-on-delta, ideal radio; C: as A with s0 killed
# (`--allow-degraded`); D: as A with the recorder killed. Each report's
# counts, then `etp replay verify` of each recording. About 5 min on 2 cores.
set -euo pipefail
source "$(dirname "$0")/common.sh"
# D leaves its unfinished recording beside d.mcap by design; a run id's
# partial file from an earlier D would refuse the next one.
rm -f "$OUT/d.mcap.faults-d.partial"
lossy=(--scenario winding-2d --delta 1.4986 --episodes 300 --trigger stochastic --loss 0.3 --retries 1 --estimator aware --episode-details)
hogs=()
for _ in 1 2; do (while :; do :; done) & hogs+=($!); done
trap 'kill "${hogs[@]}" 2>/dev/null || true' EXIT
# The pid of run RUN's process whose command line holds every other word.
pid_of() {
  local lines
  lines=$(ps -eo pid=,args= | grep -F -- "$1")
  for w in "${@:2}"; do lines=$(grep -F -- "$w" <<< "$lines" || true); done
  awk 'NR == 1 { print $1 }' <<< "$lines"
}
"$ETP" run "${lossy[@]}" --seed 5 --run-id faults-a --record "$OUT/a.mcap" --force --json > "$OUT/a.json" & a=$!
"$ETP" run --scenario winding-2d --delta 1.4986 --episodes 300 --trigger send-on-delta --seed 6 \
  --run-id faults-b --record "$OUT/b.mcap" --force --json > "$OUT/b.json" & b=$!
sleep 6
s0=$(pid_of faults-a sensor "--sensor s0" || true)
if [ -n "$s0" ]; then kill -STOP "$s0"; sleep 2; kill -CONT "$s0"; fi
wait "$a" && echo "A exit 0" || echo "A exit $?"
wait "$b" && echo "B exit 0" || echo "B exit $?"
"$ETP" run "${lossy[@]}" --seed 5 --run-id faults-c --allow-degraded --record "$OUT/c.mcap" --force --json > "$OUT/c.json" & c=$!
sleep 6
s0=$(pid_of faults-c sensor "--sensor s0" || true)
[ -n "$s0" ] && kill -9 "$s0"
wait "$c" && echo "C exit 0" || echo "C exit $?"
"$ETP" run "${lossy[@]}" --seed 5 --run-id faults-d --record "$OUT/d.mcap" --force --json > "$OUT/d.json" & d=$!
sleep 6
rec=$(pid_of faults-d recorder || true)
[ -n "$rec" ] && kill -9 "$rec"
wait "$d" && echo "D exit 0" || echo "D exit $? (4 expected: the recording did not finish)"
# D's recording is unfinished: beside its target when an older d.mcap is
# kept as it was, else at d.mcap itself (verify exits 3: unfinished).
for x in a b c d; do
  f="$OUT/$x.mcap"
  [ "$x" = d ] && [ -e "$OUT/d.mcap.faults-d.partial" ] && f="$OUT/d.mcap.faults-d.partial"
  "$ETP" replay verify "$f" > "$OUT/$x.verify.txt" && echo "verify $x: exit 0" || echo "verify $x: exit $?"
done
