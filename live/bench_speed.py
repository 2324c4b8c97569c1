#!/usr/bin/env python3
"""`etp run` steps/s without a view, with `--live` and no client, and with a
Foxglove client subscribed to every channel: interleaved rounds (the three
modes in a rotating order, the same seed within a round), medians.

    python3 live/bench_speed.py target/release/etp [ROUNDS] [EPISODES]

The client mode needs the `websockets` package (e.g. in a venv:
`pip install websockets==15.0.1`); without it only the first two modes run.
steps/s is `etp run --json`'s `steps_per_second` (the episodes alone, so the
wait of `--live-wait` for the client is not counted).
"""

import json
import re
import statistics
import subprocess
import sys
import threading

try:
    from websockets.sync.client import connect
except ImportError:
    connect = None

ETP = sys.argv[1] if len(sys.argv) > 1 else "target/release/etp"
ROUNDS = int(sys.argv[2]) if len(sys.argv) > 2 else 9
EPISODES = sys.argv[3] if len(sys.argv) > 3 else "100"


def args(seed):
    return [ETP, "run", "--scenario", "winding-2d", "--delta", "1.4986",
            "--episodes", EPISODES, "--seed", str(seed), "--json"]


def plain(seed):
    out = subprocess.run(args(seed), capture_output=True, text=True, check=True)
    return json.loads(out.stdout)["steps_per_second"]


def live(seed):
    out = subprocess.run(args(seed) + ["--live", "127.0.0.1:0"],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)["steps_per_second"]


def client(seed):
    p = subprocess.Popen(args(seed) + ["--live", "127.0.0.1:0", "--live-wait"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    port = None
    for line in p.stderr:
        m = re.search(r"ws://127\.0\.0\.1:(\d+)", line)
        if m:
            port = int(m.group(1))
            break
    got = {"messages": 0}

    def watch():
        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:
            subscribed = False
            try:
                for msg in ws:
                    if isinstance(msg, str):
                        v = json.loads(msg)
                        if v.get("op") == "advertise" and not subscribed:
                            subs = [{"id": c["id"], "channelId": c["id"]} for c in v["channels"]]
                            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                            subscribed = True
                    else:
                        got["messages"] += 1
            except Exception:
                pass

    t = threading.Thread(target=watch)
    t.start()
    out, _ = p.communicate()
    t.join()
    if p.returncode != 0:
        raise SystemExit(f"etp run --live exited {p.returncode}")
    client.messages.append(got["messages"])
    return json.loads(out)["steps_per_second"]


client.messages = []
modes = {"plain": plain, "live, no client": live}
if connect is not None:
    modes["live, client"] = client
names = list(modes)
rates = {n: [] for n in names}
for r in range(ROUNDS):
    order = names[r % len(names):] + names[:r % len(names)]
    for n in order:
        rates[n].append(modes[n](r))
    print(f"round {r}: " + ", ".join(f"{n} {rates[n][-1]:.0f}" for n in names), flush=True)
base = statistics.median(rates["plain"])
for n in names:
    m = statistics.median(rates[n])
    print(f"{n:16s} median {m:8.0f} steps/s  ({100 * (m / base - 1):+.1f} % vs plain)  "
          f"all: {[round(x) for x in rates[n]]}")
if client.messages:
    print(f"messages the client received per run: {client.messages}")
