"""Writes demo.ipynb beside this file from the cells below (the notebook's
source of truth is this script: a reviewable diff, no stored outputs).
Run: python python/examples/make_demo_notebook.py"""

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

cells = [
    new_markdown_cell("""# etp demo, from Python

The whole pipeline of `etp demo` through the package `etpareto`: synthesize the
belief-space MDP of `winding-2d` and its Pareto front, select the least-energy
strategy with P_tar ≥ 0.95 (the request loop: its prediction comes from the
strategy's own rebuilds), validate it in-process, run it as processes over
iceoryx2 (coordinator, agent, one process per sensor, recorder), and read the
recording back. The table and figures are the demo's; the last cell runs
`etp demo --json` with the same seeds and checks that every number is equal.

Sizes come from the environment so CI can run a smaller version
(`ETP_NB_SAMPLES`, `ETP_NB_VALIDATE_EPISODES`, `ETP_NB_RUN_EPISODES`,
`ETP_NB_SEED`); the run's processes from `ETP_PROCESS_DIR` (e.g. `target/release`
of a built workspace) and the CLI for the check from `ETP_BIN`."""),
    new_code_cell("""import json, os, subprocess, tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from IPython.display import Image, display

# Figures readable at a column's width: larger text, and the colour-blind
# safe Okabe–Ito hues of etp's own figures.
plt.rcParams.update({"font.size": 13, "axes.prop_cycle": plt.cycler(color=[
    "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9"])})

import etpareto

SCENARIO = "winding-2d"
MIN_TARGET = 0.95
SAMPLES = int(os.environ.get("ETP_NB_SAMPLES", 6000))
VALIDATE_EPISODES = int(os.environ.get("ETP_NB_VALIDATE_EPISODES", 3000))
RUN_EPISODES = int(os.environ.get("ETP_NB_RUN_EPISODES", 200))
SEED = int(os.environ.get("ETP_NB_SEED", 0))
OUT = Path(os.environ.get("ETP_NB_OUT") or tempfile.mkdtemp(prefix="etp-notebook-"))
print(f"etpareto {etpareto.__version__}: {SCENARIO}, {SAMPLES} samples, seed {SEED}, files in {OUT}")"""),
    new_markdown_cell("## 1. Synthesis: the MDP and its Pareto front"),
    new_code_cell("""class Progress:
    \"\"\"A line per step and every 25 % (a notebook has no terminal bar).\"\"\"
    def __init__(self):
        self.seen = {}
    def __call__(self, stage, done, total):
        quarter = 4 * done // total if total else 0
        if self.seen.get(stage) != quarter:
            self.seen[stage] = quarter
            print(f"  {stage}: {done}/{total}")

# `etp demo` synthesizes with `etp synthesize`'s defaults but no Method 1
# baseline and no aggregation check.
syn = etpareto.synthesize(SCENARIO, OUT / "synthesis", samples=SAMPLES, seed=SEED,
                          kf_baseline=False, aggregation_episodes=0, progress=Progress())
front = syn.front
print(f"{syn.report['mdp']['states']} states; Pareto front: {len(front.vertices)} vertices, "
      f"certified ε = {front.epsilon:.2e}; energy of the full Kalman filter {syn.report['front']['energy_scale']:.1f}")"""),
    new_code_cell("""# The front is 3-D (P_tar, P_coll, energy): every vertex as a dot, and the
# least energy for each P_tar (its non-dominated vertices in this plane) as the curve.
v = front.vertices.sort_values(["objectives_energy", "objectives_p_target"], ascending=[True, False])
curve = v[v["objectives_p_target"] > v["objectives_p_target"].cummax().shift(fill_value=-1.0)]
fig, ax = plt.subplots(figsize=(7, 4.5))
ax.scatter(v["objectives_energy"], v["objectives_p_target"], s=6, c="#56B4E9", label=f"all {len(v)} vertices")
ax.plot(curve["objectives_energy"], curve["objectives_p_target"], "-", color="#0072B2", lw=2, label="least energy per P_tar")
b = front.baselines
ax.plot(b["objectives_energy"], b["objectives_p_target"], "k^", ms=6, label="constant δ")
for _, r in b.iterrows():
    ax.annotate(f"δ = {r['delta']:.4g}", (r["objectives_energy"], r["objectives_p_target"]), textcoords="offset points", xytext=(6, -14),
                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.85))
ax.axhline(MIN_TARGET, color="grey", lw=0.8, ls=":")
ax.set_xlabel("expected energy per episode (transmissions × cost)"); ax.set_ylabel("P_tar (probability)")
ax.legend(loc="lower right"); ax.set_title(f"{SCENARIO}: Pareto front")
plt.show()
display(Image(filename=str(syn.dir / "front.png"), width=640))  # the figure `etp` draws, per bound on P_coll"""),
    new_markdown_cell("## 2. The strategy: least energy with P_tar ≥ 0.95"),
    new_code_cell("""strategy = etpareto.select_strategy(syn, min_target=MIN_TARGET, aggregation_check=0, progress=Progress())
print(strategy.data["label"], "—", strategy.verdict, "after", strategy.rounds, "round(s)")
pd.DataFrame({"predicted": strategy.predicted, "±95 %": strategy.data["predicted_ci95"]})"""),
    new_markdown_cell("## 3. In-process validation"),
    new_code_cell("""validation = etpareto.validate(strategy, episodes=VALIDATE_EPISODES, seed=SEED, plot_episodes=40)
print("checks hold" if validation.holds else f"checks FAIL: {validation.failed}")
display(validation.table())
display(Image(filename=str(validation.plots[0]), width=640))  # trajectories coloured by γ̄(δ)"""),
    new_markdown_cell("## 4. The multi-process run over iceoryx2, and its recording"),
    new_code_cell("""run = etpareto.run(strategy.path, episodes=RUN_EPISODES, seed=SEED, record=OUT / "run.mcap",
                  predict_episodes=VALIDATE_EPISODES, deadline=600)
print("clean run" if run.clean else f"problems: {run.problems}")
mp = run.report
table = pd.DataFrame(
    {
        "predicted": [strategy.predicted[k] for k in ("p_target", "p_collision", "energy_mean")],
        "in-process": [validation.report[k] for k in ("p_target", "p_collision", "energy_mean")],
        "in-process ±": [validation.report[k + "_ci95"] for k in ("p_target", "p_collision", "energy_mean")],
        "multi-process": [mp[k] for k in ("p_target", "p_collision", "energy_mean")],
        "multi-process ±": [mp[k + "_ci95"] for k in ("p_target", "p_collision", "energy_mean")],
    },
    index=["P_tar", "P_coll", "energy"],
)
table"""),
    new_code_cell("""packets = run.sensors[["name", "transmissions", "received", "predicted_energy"]]
print(f"packets per sensor ({mp['episodes']} multi-process episodes): sensor ledger / agent received / predicted")
packets"""),
    new_code_cell("""tables = etpareto.read_recording(OUT / "run.mcap")
meas = tables["measurement"]
print({topic: len(df) for topic, df in tables.items()})
assert len(meas) == packets["transmissions"].sum(), "Σ ledgers = measurement messages in the recording"
fig, ax = plt.subplots(figsize=(7, 3.5))
for sender, df in meas.groupby("sender"):
    ax.plot((df["log_time_ns"] - meas["log_time_ns"].min()) / 1e9, range(1, len(df) + 1), label=str(sender))
ax.set_xlabel("seconds into the run (s)"); ax.set_ylabel("measurements sent (count)"); ax.legend(title="sensor")
# One sensor sending ten times another's: a log axis keeps the small ones readable.
sent = meas.groupby("sender").size()
if sent.max() >= 10 * sent.min():
    ax.set_yscale("log")
plt.show()"""),
    new_markdown_cell("## 5. The same numbers as `etp demo`"),
    new_code_cell("""etp = os.environ.get("ETP_BIN")
if etp:
    cli = json.loads(subprocess.run(
        [etp, "demo", "--json", "--samples", str(SAMPLES), "--seed", str(SEED),
         "--validate-episodes", str(VALIDATE_EPISODES), "--run-episodes", str(RUN_EPISODES),
         "-o", str(OUT / "cli-demo")],
        check=True, capture_output=True, text=True).stdout)
    assert cli["vertices"] == len(front.vertices)
    for k in ("p_target", "p_collision", "energy_mean"):
        assert cli["predicted"][k] == strategy.predicted[k], k
        assert cli["predicted_ci95"][k] == strategy.data["predicted_ci95"][k], k
        assert cli["in_process"][k] == validation.report[k], k
        assert cli["in_process"][k + "_ci95"] == validation.report[k + "_ci95"], k
        assert cli["multi_process"][k] == mp[k], k
    for a, b in zip(cli["multi_process"]["sensors"], mp["sensors"]):
        assert (a["name"], a["transmissions"], a["received"]) == (b["name"], b["transmissions"], b["received"])
    print("every number equals `etp demo --json`'s for the same seed")
elif os.environ.get("ETP_NB_CHECK"):
    raise RuntimeError("ETP_NB_CHECK is set but ETP_BIN is not: the comparison with `etp demo` cannot run")
else:
    print("ETP_BIN not set: the comparison with `etp demo` is skipped here (python/ci.sh sets it)")"""),
]

nb = new_notebook(cells=cells, metadata={
    "kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"},
    "language_info": {"name": "python"},
})
out = Path(__file__).with_name("demo.ipynb")
nbformat.write(nb, out)
print(f"wrote {out}")
