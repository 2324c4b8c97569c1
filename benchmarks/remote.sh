#!/usr/bin/env bash
# A run with remote sensors on one machine (docs/performance.md, "Runs across
# hosts"): the sensor host in its own iceoryx2 domain, over TLS and over plain
# TCP (`--insecure`), ROUNDS interleaved rounds; steps per second and the
# counts of each run. Needs the bridge beside etp (it links Zenoh):
#   cargo build --release -p etp -p etp-bridge
# About 5 min on 2 cores.
set -euo pipefail
source "$(dirname "$0")/common.sh"
ROUNDS=${ROUNDS:-5}
if [ ! -x "$(dirname "$ETP")/etp-bridge" ]; then
  echo "benchmarks: $(dirname "$ETP")/etp-bridge is missing: cargo build --release -p etp -p etp-bridge" >&2
  exit 1
fi
"$ETP" certs init "$OUT/keys" --sensor-host b --force > /dev/null
rate() { python3 -c 'import json,sys; v=json.load(open(sys.argv[1])); print(v["steps_per_second"], "steps/s, transmissions", v.get("transmissions"), "received", v.get("received"))' "$1"; }
one() { # $1 tls|tcp, $2 port
  local link=(--tls "$OUT/keys/agent-host") host=(--tls "$OUT/keys/b" --name b)
  if [ "$1" = tcp ]; then link=(--insecure); host=(--insecure); fi
  "$ETP" run --scenario winding-2d --delta 1.4986 --episodes 300 --seed 3 --remote s0,s3 \
    --listen "$1/127.0.0.1:$2" "${link[@]}" --json > "$OUT/$1.json" & local agent=$!
  sleep 1
  "$ETP" sensor-host --connect "$1/127.0.0.1:$2" "${host[@]}" > /dev/null
  wait "$agent"
  echo "$1: $(rate "$OUT/$1.json")"
}
for round in $(seq "$ROUNDS"); do
  one tls $((17440 + round))
  one tcp $((17460 + round))
done
