#!/usr/bin/env python3
"""Independent check of etp's MDPs by Storm (stormpy): load the files written
by `etp export --format drn` and `--format jani` as they are, and answer on
them what etp answers. Shares no code with etp.

Usage: storm_check.py DRN_DIR JANI_DIR < REQUEST
REQUEST (JSON): {"queries": [[P, C or null], ...], "precision": 1e-6,
"exact": bool}: per query the least expected energy with P(F "tar") >= P and
(if C) P(F "coll") <= C.

Prints one JSON object:
  model: states, choices, labels and reward models of the DRN model
         (and of the JANI model under "jani_model");
  max_target, min_collision: Pmax=? [F "tar"], Pmin=? [F "coll"] (DRN);
  jani: every property of model.jani, checked on the JANI model, by name;
  least_energy: per query Storm's value (null: Storm says infeasible);
  least_energy_exact: the same in exact (rational) arithmetic, or null;
  pareto: multi(Pmax=? [F "tar"], R{"energy"}min=? [C]): the achievable
          points (P_tar, energy) and the over-approximation's halfspaces;
  schedulers: for Pmax(F tar), Pmin(F coll) and Rmin(C): Storm's optimal
          scheduler (one choice index per state) and the values of the chain
          it induces (P_tar, P_coll, energy), computed by Storm.
"""

import json
import os
import sys
import time

import stormpy
import stormpy.environments as envs


def multi(p, c):
    s = 'multi(R{"energy"}min=? [ C ], P>=%r [ F "tar" ]' % p
    if c is not None:
        s += ', P<=%r [ F "coll" ]' % c
    return s + ")"


def environment(precision, exact=False):
    env = envs.exact() if exact else envs.sound()
    mo = env.modelchecker().multi()
    mo.precision = stormpy.Rational(precision)
    return env


def truth(res, state):
    """A qualitative result's value in `state`."""
    return bool(res.get_truth_values_vector()[state])


def value(model, formula, env=None):
    prop = stormpy.parse_properties(formula)[0]
    res = stormpy.model_checking(model, prop, only_initial_states=True, environment=env)
    init = model.initial_states[0]
    if res.is_qualitative():
        # Storm answers a numerical multi-objective query it finds
        # infeasible with false.
        if truth(res, init):
            raise SystemExit(f"{formula}: Storm answered true to a numerical query")
        return None
    return float(res.get_value(init))


def corners(polytope):
    """The vertices of a 2-D polytope {x : n.x <= b}, from its halfspaces:
    every pairwise intersection that satisfies all of them (stormpy's own
    vertex list drops some)."""
    hs = [(h.normal_vector, h.offset) for h in polytope.halfspaces]
    out = []
    for i, (a, b) in enumerate(hs):
        for c, d in hs[i + 1:]:
            det = a[0] * c[1] - a[1] * c[0]
            if abs(det) < 1e-12:
                continue
            x = ((b * c[1] - a[1] * d) / det, (a[0] * d - b * c[0]) / det)
            if all(n[0] * x[0] + n[1] * x[1] <= o + 1e-9 * (1 + abs(o)) for n, o in hs):
                out.append(list(x))
    return sorted(out)


def describe(model):
    return {
        "states": model.nr_states,
        "choices": model.nr_choices,
        "labels": sorted(model.labeling.get_labels()),
        "rewards": sorted(model.reward_models),
        "initial": list(model.initial_states),
    }


def scheduler_values(model, formula):
    prop = stormpy.parse_properties(formula)[0]
    res = stormpy.model_checking(model, prop, extract_scheduler=True)
    sched = res.get_scheduler()
    assert sched.deterministic and sched.memoryless, formula
    choices = [sched.get_choice(s).get_deterministic_choice() for s in range(model.nr_states)]
    chain = model.apply_scheduler(sched)
    init = chain.initial_states[0]

    def on_chain(f):
        r = stormpy.model_checking(chain, stormpy.parse_properties(f)[0])
        return float(r.get_value(init))

    return {
        "formula": formula,
        "optimum": float(res.get_value(model.initial_states[0])),
        "choices": choices,
        "p_target": on_chain('P=? [ F "tar" ]'),
        "p_collision": on_chain('P=? [ F "coll" ]'),
        "energy": on_chain('R{"energy"}=? [ C ]'),
    }


START = time.monotonic()


def log(stage):
    print(f"storm_check: {stage} done at {time.monotonic() - START:.1f} s", file=sys.stderr)


def main():
    # Storm's C++ log (e.g. WARN lines) writes to the process's stdout: it
    # goes to stderr, the JSON answer alone to the real stdout.
    answer = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    drn_dir, jani_dir = sys.argv[1], sys.argv[2]
    req = json.load(sys.stdin)
    out = {}
    drn = stormpy.build_model_from_drn(f"{drn_dir}/model.drn")
    out["model"] = describe(drn)
    # Every property of model.jani but the Pareto curve (checked on the DRN
    # model below).
    jani_model, jani_props = stormpy.parse_jani_model(f"{jani_dir}/model.jani")
    jani_props = [p for p in jani_props if not p.get_name().startswith("pareto")]
    jani = stormpy.build_model(jani_model)
    out["jani_model"] = describe(jani)
    out["jani"] = {}
    for prop in jani_props:
        res = stormpy.model_checking(jani, prop, only_initial_states=True)
        init = jani.initial_states[0]
        if res.is_qualitative():
            out["jani"][prop.get_name()] = truth(res, init)
        elif res.is_pareto_curve_check_result():
            out["jani"][prop.get_name()] = corners(res.get_under_approximation())
        else:
            out["jani"][prop.get_name()] = float(res.get_value(init))
    log("jani")
    out["max_target"] = value(drn, 'Pmax=? [ F "tar" ]')
    out["min_collision"] = value(drn, 'Pmin=? [ F "coll" ]')
    precision = req["precision"]
    env = environment(precision)
    out["precision"] = precision
    out["least_energy"] = [value(drn, multi(p, c), env) for p, c in req["queries"]]
    log("least energy")
    out["least_energy_exact"] = None
    if req.get("exact"):
        exact = stormpy.build_model_from_drn[stormpy.Rational](f"{drn_dir}/model.drn")
        start = time.monotonic()
        out["least_energy_exact"] = [
            value(exact, multi(p, c), environment(0, exact=True)) for p, c in req["queries"]
        ]
        out["exact_seconds"] = time.monotonic() - start
        log("exact")
    # The curve to precision 1e-3: Storm's default (1e-4) takes a minute
    # on the test's MDPs, and its points are achievable at any precision.
    out["pareto_precision"] = req["pareto_precision"]
    pareto = stormpy.model_checking(
        drn,
        stormpy.parse_properties('multi(Pmax=? [ F "tar" ], R{"energy"}min=? [ C ])')[0],
        environment=environment(req["pareto_precision"]),
    )
    log("pareto")
    out["pareto"] = {
        "points": corners(pareto.get_under_approximation()),
        "over": [h.normal_vector + [h.offset] for h in pareto.get_over_approximation().halfspaces],
    }
    out["schedulers"] = [
        scheduler_values(drn, f)
        for f in ('Pmax=? [ F "tar" ]', 'Pmin=? [ F "coll" ]', 'R{"energy"}min=? [ C ]')
    ]
    answer.write(json.dumps(out))
    answer.close()


if __name__ == "__main__":
    main()
