#!/usr/bin/env python3
"""Independent check of `etp strategy`: solve the constrained queries on the
PRISM explicit files written by `etp export --format prism`, with our own parser and a
different LP solver (SciPy's HiGHS dual simplex), sharing no code with etp.

Usage: occupation_lp.py PRISM_DIR QUERY...
QUERY is `P` (least energy with P_tar >= P) or `P,C` (and P_coll <= C).
Prints one JSON list: per query the least expected energy, or null if the
query is infeasible.
"""

import json
import re
import sys

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import coo_matrix


def read_model(d):
    with open(f"{d}/model.lab") as f:
        header = f.readline()
        names = {name: int(i) for i, name in re.findall(r'(\d+)="([^"]*)"', header)}
        labels = {}
        for line in f:
            state, ids = line.split(":")
            labels[int(state)] = {int(x) for x in ids.split()}
    init = next(s for s, ids in labels.items() if names["init"] in ids)
    terminal = {
        kind: next(s for s, ids in labels.items() if names[kind] in ids)
        for kind in ("coll", "tar", "free")
    }
    trans = {}  # (i, k) -> list of (j, p)
    with open(f"{d}/model.tra") as f:
        n_states = int(f.readline().split()[0])
        for line in f:
            i, k, j, p = line.split()[:4]
            trans.setdefault((int(i), int(k)), []).append((int(j), float(p)))
    reward = {}
    with open(f"{d}/model.trew") as f:
        for line in f:
            if line.startswith("#"):
                continue
            parts = line.split()
            if len(parts) == 3:
                continue  # the header line "states choices transitions"
            i, k, j, r = parts
            reward[(int(i), int(k), int(j))] = float(r)
    return n_states, init, terminal, trans, reward


def solve(model, p_target, p_coll):
    n_states, init, terminal, trans, reward = model
    absorbing = set(terminal.values())
    pairs = sorted(key for key in trans if key[0] not in absorbing)
    index = {key: n for n, key in enumerate(pairs)}
    energy = np.zeros(len(pairs))
    to_tar = np.zeros(len(pairs))
    to_coll = np.zeros(len(pairs))
    rows, cols, vals = [], [], []
    for (i, k), n in index.items():
        rows.append(i)
        cols.append(n)
        vals.append(1.0)
        for j, p in trans[(i, k)]:
            energy[n] += p * reward.get((i, k, j), 0.0)
            if j == terminal["tar"]:
                to_tar[n] += p
            elif j == terminal["coll"]:
                to_coll[n] += p
            elif j not in absorbing:
                rows.append(j)
                cols.append(n)
                vals.append(-p)
    a_eq = coo_matrix((vals, (rows, cols)), shape=(n_states, len(pairs))).tocsr()
    b_eq = np.zeros(n_states)
    b_eq[init] = 1.0
    keep = [s for s in range(n_states) if s not in absorbing]
    a_ub = [-to_tar]
    b_ub = [-p_target]
    if p_coll is not None:
        a_ub.append(to_coll)
        b_ub.append(p_coll)
    res = linprog(
        energy,
        A_ub=np.array(a_ub),
        b_ub=np.array(b_ub),
        A_eq=a_eq[keep],
        b_eq=b_eq[keep],
        bounds=(0, None),
        method="highs-ds",
        options={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10},
    )
    if res.status == 2:
        return None
    if res.status != 0:
        raise SystemExit(f"linprog failed: {res.message}")
    return float(res.fun)


def main():
    model = read_model(sys.argv[1])
    out = []
    for q in sys.argv[2:]:
        parts = [float(x) for x in q.split(",")]
        out.append(solve(model, parts[0], parts[1] if len(parts) > 1 else None))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
