#!/usr/bin/env bash
# The predicted front of a synthesis validated point by point
# (docs/performance.md, "The predicted front and the least energy that meets
# the request"): `etp strategy front DIR`, then each point's strategy file
# simulated (`etp validate --episodes 3000`), the prediction against the
# simulation's 95 % interval for P_tar, P_coll and energy.
#   bash benchmarks/predicted-front.sh out/w        (a synthesis of etp synthesize)
set -euo pipefail
DIR=$1
ETP=${ETP:-target/release/etp}
echo "machine: $(nproc) cores, $(free -g | awk '/Mem:/{print $2}') GiB; $ETP"
start=$(date +%s)
"$ETP" strategy front "$DIR" --json > "$DIR.front.json"
end=$(date +%s)
echo "front: $((end - start)) s"
for f in "$DIR"/predicted-front/point-*.json; do
  "$ETP" validate "$f" --episodes 3000 --json > "$f.validate" || true
done
python3 - "$DIR" <<'PY'
import json, sys, glob
d = sys.argv[1]
front = json.load(open(d + ".front.json"))
inside = total = 0
for k, p in enumerate(front["curves"][0]["points"]):
    v = json.load(open(f"{d}/predicted-front/point-{k}.json.validate"))
    row = [f"P≥{p['min_target']:.4f} {p['verdict']:<12}"]
    for q, vk in [("p_target", "p_target"), ("p_collision", "p_collision"), ("energy", "energy_mean")]:
        pred, sim, ci = p["predicted"][q], v[vk], v[vk + "_ci95"]
        ok = abs(pred - sim) <= ci
        inside += ok; total += 1
        row.append(f"{q} pred {pred:.4f} sim {sim:.4f} ± {ci:.4f} (pred − sim {pred - sim:+.4f}) {'in' if ok else 'OUT'}")
    print(" | ".join(row))
print(f"inside the simulation's 95 % interval: {inside} of {total}")
PY
