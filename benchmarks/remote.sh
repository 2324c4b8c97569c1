#!/usr/bin/env bash
# A run with remote sensors on one machine (docs/performance.md, "Runs across
# hosts"): the sensor host in its own iceoryx2 domain, over TLS and over plain
# TCP (`--insecure`), ROUNDS interleaved rounds; steps per second and the
# counts of each run. REMOTE=all: all seven sensors remote (default s0,s3);
# EPISODES (default 300) per run.
# OLD=DIR: also the binaries in DIR (etp and etp-bridge, e.g. a copy of
# target/release before a change), interleaved with ETP's in each round.
# Needs the bridge beside etp (it links Zenoh):
#   cargo build --release -p etp -p etp-bridge
# About 5 min on 2 cores (REMOTE=all: about 15 min); twice that with OLD.
set -euo pipefail
source "$(dirname "$0")/common.sh"
ROUNDS=${ROUNDS:-5}
EPISODES=${EPISODES:-300}
case "${REMOTE:-s0,s3}" in
  all) REMOTE=s0,s1,s2,s3,s4,s5,s6 ;;
  *) REMOTE=${REMOTE:-s0,s3} ;;
esac
BINS=("$ETP")
if [ -n "${OLD:-}" ]; then BINS+=("$OLD/etp"); fi
if [ ! -x "$(dirname "$ETP")/etp-bridge" ]; then
  echo "benchmarks: $(dirname "$ETP")/etp-bridge is missing: cargo build --release -p etp -p etp-bridge" >&2
  exit 1
fi
"$ETP" certs init "$OUT/keys" --sensor-host b --force > /dev/null
rate() { python3 -c 'import json,sys; v=json.load(open(sys.argv[1])); print(v["steps_per_second"], "steps/s, transmissions", v.get("transmissions"), "received", v.get("received"))' "$1"; }
# With OLD: whether the two runs of a round have the same counts and outcomes
# (the JSON without its timing fields and run id).
same() { python3 -c '
import json, sys
drop = {"seconds", "steps_per_second", "wall_seconds", "run_id", "pid", "lost", "reordered"}
def strip(v):
    if isinstance(v, dict): return {k: strip(x) for k, x in v.items() if k not in drop}
    if isinstance(v, list): return [strip(x) for x in v]
    return v
a, b = (strip(json.load(open(f))) for f in sys.argv[1:3])
print("same counts and outcomes" if a == b else "DIFFERENT counts or outcomes")' "$1" "$2"; }
one() { # $1 tls|tcp, $2 port, $3 the etp binary, $4 the JSON's name
  local link=(--tls "$OUT/keys/agent-host") host=(--tls "$OUT/keys/b" --name b)
  if [ "$1" = tcp ]; then link=(--insecure); host=(--insecure); fi
  "$3" run --scenario winding-2d --delta 1.4986 --episodes "$EPISODES" --seed 3 --remote "$REMOTE" \
    --listen "$1/127.0.0.1:$2" "${link[@]}" --json > "$OUT/$4.json" & local agent=$!
  sleep 1
  "$3" sensor-host --connect "$1/127.0.0.1:$2" "${host[@]}" > /dev/null
  wait "$agent"
  echo "$3 $1 $REMOTE: $(rate "$OUT/$4.json")"
}
for round in $(seq "$ROUNDS"); do
  for b in "${!BINS[@]}"; do
    name=("" "-old")
    one tls $((17440 + 40 * b + round)) "${BINS[$b]}" "tls${name[$b]}"
    one tcp $((17460 + 40 * b + round)) "${BINS[$b]}" "tcp${name[$b]}"
  done
  if [ -n "${OLD:-}" ]; then
    echo "round $round: tls $(same "$OUT/tls.json" "$OUT/tls-old.json"), tcp $(same "$OUT/tcp.json" "$OUT/tcp-old.json")"
  fi
done
