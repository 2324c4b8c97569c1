#!/usr/bin/env bash
# The remote soak (docs/performance.md, "Runs across hosts"): RUNS all-remote
# runs of winding-2d (all seven sensors on one sensor host, EPISODES each,
# a fresh seed per run), TLS and plain TCP alternating (LINK=tls or tcp for
# one only), beside HOGS busy loops. A run that has not ended BOUND seconds
# after it started is a hang: the stacks of every process of the run
# (gdb, every thread) and their logs are kept under $OUT/hang-N/, then the
# run is interrupted. A run that ends with exit ≠ 0 is kept under
# $OUT/fail-N/. Every run's counts are checked: each sensor's transmissions
# (attempts = delivered + lost) received by the agent. Logs at RUST_LOG
# (default debug for the bridges and the runtime).
#   RUNS=300 EPISODES=20 bash benchmarks/soak.sh
# Needs the bridge beside etp: cargo build --release -p etp -p etp-bridge
set -euo pipefail
source "$(dirname "$0")/common.sh"
RUNS=${RUNS:-300}
EPISODES=${EPISODES:-20}
HOGS=${HOGS:-2}
BOUND=${BOUND:-300}
LINK=${LINK:-both}
export RUST_LOG=${RUST_LOG:-etp_bridge=debug,etp_runtime=debug,info}
command -v gdb > /dev/null || { echo "soak: gdb is needed for the stacks of a hang (apt-get install gdb)" >&2; exit 1; }
"$ETP" certs init "$OUT/keys" --sensor-host b --force > /dev/null
hogs=()
for _ in $(seq "$HOGS"); do (while :; do :; done) & hogs+=($!); done
trap 'kill "${hogs[@]}" 2>/dev/null || true' EXIT
# Every descendant of the given pids, the pids themselves first.
tree() {
  local p
  for p in "$@"; do
    echo "$p"
    tree $(pgrep -P "$p" || true)
  done
}
ok=0 hangs=0 fails=0 wrong=0
rates=()
for n in $(seq "$RUNS"); do
  link=tls
  case "$LINK" in tcp) link=tcp ;; both) [ $((n % 2)) = 0 ] && link=tcp ;; esac
  agent_link=(--tls "$OUT/keys/agent-host") host_link=(--tls "$OUT/keys/b" --name b)
  [ "$link" = tcp ] && { agent_link=(--insecure); host_link=(--insecure); }
  port=$((18000 + n % 2000))
  dir="$OUT/run"
  rm -rf "$dir"; mkdir -p "$dir"
  start=$(now)
  "$ETP" run --scenario winding-2d --delta 1.4986 --episodes "$EPISODES" --seed $((1000 + n)) \
    --remote s0,s1,s2,s3,s4,s5,s6 --run-id "soak-$n" --listen "$link/127.0.0.1:$port" "${agent_link[@]}" \
    --json > "$dir/run.json" 2> "$dir/run.log" & agent=$!
  sleep 0.5
  "$ETP" sensor-host --connect "$link/127.0.0.1:$port" "${host_link[@]}" > "$dir/host.out" 2> "$dir/host.log" & host=$!
  code=
  while :; do
    if ! kill -0 "$agent" 2> /dev/null; then
      set +e; wait "$agent"; code=$?; set -e
      break
    fi
    if awk -v a="$start" -v b="$(now)" -v m="$BOUND" 'BEGIN { exit !(b - a > m) }'; then
      hangs=$((hangs + 1))
      keep="$OUT/hang-$n"
      rm -rf "$keep"; mkdir -p "$keep"
      for p in $(tree "$agent" "$host"); do
        {
          echo "== $p: $(tr '\0' ' ' < "/proc/$p/cmdline" 2> /dev/null)"
          gdb -p "$p" -batch -ex "thread apply all bt" 2>&1 | grep -E '^(Thread|#)' || true
        } >> "$keep/stacks.txt"
      done
      kill -INT "$agent" 2> /dev/null || true
      sleep 10
      kill -9 $(tree "$agent" "$host") 2> /dev/null || true
      set +e; wait "$agent"; code=$?; set -e
      cp "$dir"/* "$keep/"
      echo "run $n ($link): HANG after $BOUND s; stacks in $keep/stacks.txt" >&2
      break
    fi
    sleep 1
  done
  set +e; wait "$host"; set -e
  secs=$(elapsed "$start")
  if [ "$code" != 0 ]; then
    [ -d "$OUT/hang-$n" ] || { fails=$((fails + 1)); rm -rf "$OUT/fail-$n"; cp -r "$dir" "$OUT/fail-$n"; }
    echo "run $n ($link): exit $code after $secs s" >&2
    continue
  fi
  # Every transmission of every sensor accounted: the run's own identity
  # check gave exit 0; here the agent's receptions against the sensors'.
  verdict=$(python3 -c '
import json, sys
v = json.load(open(sys.argv[1]))
bad = [s["name"] for s in v["sensors"]
       if s["transmissions"] != s["delivered"] + s["lost"] or s["delivered"] != s["received"]]
ok = not bad and v["episodes"] == int(sys.argv[2]) and not v["degraded"]
episodes, degraded = v["episodes"], v["degraded"]
print("ok" if ok else f"WRONG sensors {bad} episodes {episodes} degraded {degraded}", v["steps_per_second"])' "$dir/run.json" "$EPISODES")
  if [ "${verdict%% *}" = ok ]; then
    ok=$((ok + 1)); rates+=("${verdict##* }")
  else
    wrong=$((wrong + 1)); rm -rf "$OUT/wrong-$n"; cp -r "$dir" "$OUT/wrong-$n"
    echo "run $n ($link): $verdict" >&2
  fi
  if [ $((n % 10)) = 0 ]; then
    echo "$n runs: $ok exact, $hangs hangs, $fails exit ≠ 0, $wrong wrong counts; load $(cut -d' ' -f1 /proc/loadavg)" >&2
  fi
done
median=$(printf '%s\n' "${rates[@]}" | sort -g | awk '{ a[NR] = $1 } END { if (NR) print a[int((NR + 1) / 2)]; else print "-" }')
echo "soak: $RUNS all-remote runs ($LINK, $EPISODES episodes, $HOGS hogs, bound $BOUND s): $ok exact, $hangs hangs, $fails exit ≠ 0, $wrong wrong counts; median $median steps/s"
[ "$hangs" = 0 ] && [ "$fails" = 0 ] && [ "$wrong" = 0 ]
