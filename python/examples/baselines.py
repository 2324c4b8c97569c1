"""The constant-δ baselines of a scenario, from Python.

For each candidate threshold δ of the scenario: P_tar, P_coll and the
energy per episode with their 95 % half-widths, and per sensor the
transmissions — the numbers ``etp simulate SCENARIO --delta δ --episodes N
--seed S --json`` prints. With ``--check ETP`` each row is compared with
that command's output and the script fails on any difference (``python/ci.sh``
runs it so).

    python python/examples/baselines.py winding-2d --episodes 500 --seed 7
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

import pandas as pd

import etpareto


def table(scenario: etpareto.Scenario, episodes: int, seed: int) -> pd.DataFrame:
    rows = []
    for delta in scenario.deltas:
        s = etpareto.simulate(scenario, delta=delta, episodes=episodes, seed=seed,
                              records=False).summary
        rows.append({
            "delta": delta,
            "p_target": s["p_target"], "p_target_ci95": s["p_target_ci95"],
            "p_collision": s["p_collision"], "p_collision_ci95": s["p_collision_ci95"],
            "energy_mean": s["energy_mean"], "energy_mean_ci95": s["energy_mean_ci95"],
            **{f"tx_{x['name']}": x["transmissions"] for x in s["sensors"]},
        })
    return pd.DataFrame(rows)


def check(df: pd.DataFrame, etp: str, scenario: str, episodes: int, seed: int) -> int:
    """Rows that differ from `etp simulate --json` (0: every number equal)."""
    bad = 0
    for row in df.to_dict("records"):
        out = subprocess.run(
            [etp, "simulate", scenario, "--delta", repr(row["delta"]), "--episodes",
             str(episodes), "--seed", str(seed), "--json"],
            capture_output=True, text=True, check=True)
        cli = json.loads(out.stdout)
        want = {k: cli[k] for k in row if not k.startswith("tx_") and k != "delta"}
        want.update({f"tx_{x['name']}": x["transmissions"] for x in cli["sensors"]})
        got = {k: v for k, v in row.items() if k != "delta"}
        if got != want:
            bad += 1
            print(f"δ = {row['delta']}: {got} != etp's {want}", file=sys.stderr)
    return bad


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="winding-2d")
    p.add_argument("--episodes", type=int, default=3000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--check", metavar="ETP", help="compare every row with this etp binary")
    a = p.parse_args()
    scenario = etpareto.load_scenario(a.scenario)
    df = table(scenario, a.episodes, a.seed)
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(f"{scenario.name} · {a.episodes} episodes · seed {a.seed}")
        print(df.to_string(index=False))
    if a.check:
        bad = check(df, a.check, a.scenario, a.episodes, a.seed)
        if bad:
            print(f"{bad} row(s) differ from etp simulate", file=sys.stderr)
            return 1
        print(f"every row equals `etp simulate … --json` ({len(df)} thresholds)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
