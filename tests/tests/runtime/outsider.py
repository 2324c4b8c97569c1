"""An outsider on the network, as a real Zenoh client (eclipse-zenoh 1.10.2).

Argument: one JSON object
  endpoint   the agent host's endpoint (tcp/… or tls/…)
  tls        null, or {"ca": PEM path, "cert": PEM path or null, "key": …}
  run        the run id (an outsider may have read it elsewhere)
  query      true: get("etp/session")
  subscribe  a key expression to subscribe to, or null
  stall      true: the subscriber's callback never returns (a stalled reader)
  capture    true: read the run's tag from a down message, then put forged
             measurements and a ledger as host `host` (see below)
  puts       [[key, hex bytes], …] put after `wait` seconds
  wait, seconds
Prints one JSON object: connected, replies, received, forged (what was put).
"""

import json
import struct
import sys
import threading
import time

import zenoh

a = json.loads(sys.argv[1])
conf = zenoh.Config()
for k, v in [
    ("mode", '"peer"'),
    ("scouting/multicast/enabled", "false"),
    ("scouting/gossip/enabled", "false"),
    ("listen/endpoints", "[]"),
    ("connect/endpoints", json.dumps([a["endpoint"]])),
    ("connect/timeout_ms", "4000"),
    ("connect/exit_on_failure", "true"),
]:
    conf.insert_json5(k, v)
tls = a.get("tls")
if tls:
    conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(tls["ca"]))
    conf.insert_json5("transport/link/tls/verify_name_on_connect", "false")
    if tls.get("cert"):
        conf.insert_json5("transport/link/tls/connect_certificate", json.dumps(tls["cert"]))
        conf.insert_json5("transport/link/tls/connect_private_key", json.dumps(tls["key"]))
        conf.insert_json5("transport/link/tls/enable_mtls", "true")

out = {"connected": False, "replies": 0, "received": 0, "forged": []}
try:
    s = zenoh.open(conf)
except Exception as e:  # refused: no certificate, wrong protocol
    out["error"] = str(e)
    print(json.dumps(out))
    sys.exit(0)
out["connected"] = True
run = a["run"]
captured = {}
lock = threading.Lock()


def on_sample(sample):
    with lock:
        out["received"] += 1
        key = str(sample.key_expr)
        topic = key.rsplit("/", 1)[-1]
        payload = bytes(sample.payload.to_bytes())
        # A real down message (this session's own puts come back too).
        if a.get("capture") and "/down/" in key and len(payload) >= 48 and "tag" not in captured:
            captured["tag"] = payload[:8]
    if a.get("stall"):
        time.sleep(3600)


sub = None
if a.get("subscribe"):
    sub = s.declare_subscriber(a["subscribe"], on_sample)
if a.get("query"):
    for r in s.get("etp/session", timeout=2.0):
        if r.ok is not None:
            out["replies"] += 1
time.sleep(a.get("wait", 0))
for key, hexbytes in a.get("puts", []):
    s.put(key, bytes.fromhex(hexbytes))
    out["forged"].append(key)
if a.get("capture"):
    # The run's tag is the first 8 bytes of any message of the run (the
    # down traffic this outsider can read on an insecure link).
    deadline = time.time() + 20
    while time.time() < deadline:
        with lock:
            if "tag" in captured:
                break
        time.sleep(0.05)
    with lock:
        tag = captured.get("tag")
    if tag is not None:
        up = f"etp/{run}/up/{a['host']}"

        def header(sender, seq, episode=0, leg=0, step=1):
            return tag + struct.pack("<QIIII", episode, step, leg, sender, seq)

        y = struct.pack("<6d", *([0.5] * 6))
        # A measurement as sensor s3, a local sensor.
        s.put(f"{up}/measurement", header(3, 1) + struct.pack("<II", 2, 1) + y)
        out["forged"].append("measurement as a local sensor")
        # A measurement and a ledger of the remote sensor s1, old sequence numbers.
        s.put(f"{up}/measurement", header(1, 1) + struct.pack("<II", 2, 1) + y)
        out["forged"].append("measurement of s1")
        s.put(f"{up}/ledger", header(1, 2) + struct.pack("<IId", 10, 1000, 1.0))
        out["forged"].append("ledger of s1, 1000 transmissions")
time.sleep(a.get("seconds", 0))
print(json.dumps(out), flush=True)
if a.get("stall"):
    import os

    os._exit(0)
s.close()
