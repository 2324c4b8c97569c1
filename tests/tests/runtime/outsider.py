"""An outsider on the network, as a real Zenoh client (eclipse-zenoh 1.10.2).

Argument: one JSON object
  endpoint   the agent host's endpoint (tcp/… or tls/…)
  tls        null, or {"ca": PEM path, "cert": PEM path or null, "key": …}
  run        the run id (an outsider may have read it elsewhere)
  query      true: get("etp/session")
  subscribe  a key expression to subscribe to, or null
  stall      true: the subscriber's callback never returns (a stalled reader)
  capture    true: keep the first measurement and ledger seen on up keys and
             put forged variants of them (see below)
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
        if a.get("capture") and topic in ("measurement", "ledger") and topic not in captured:
            captured[topic] = (key, bytes(sample.payload.to_bytes()))
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
    deadline = time.time() + 20
    while time.time() < deadline:
        with lock:
            if len(captured) == 2:
                break
        time.sleep(0.05)
    with lock:
        got = dict(captured)
    # Header: run u64, episode u64, step u32, leg u32, sender u32, seq u32.
    if "measurement" in got:
        key, m = got["measurement"]
        s.put(key, m)  # replayed verbatim
        out["forged"].append("replayed measurement")
        local = bytearray(m)
        struct.pack_into("<I", local, 24, 3)  # as sensor s3, a local one
        s.put(key, bytes(local))
        out["forged"].append("measurement as a local sensor")
    if "ledger" in got:
        key, l = got["ledger"]
        forged = bytearray(l)
        (t,) = struct.unpack_from("<I", forged, 36)
        struct.pack_into("<I", forged, 36, t + 1000)  # 1000 more transmissions
        s.put(key, bytes(forged))
        out["forged"].append("ledger +1000")
time.sleep(a.get("seconds", 0))
print(json.dumps(out), flush=True)
if a.get("stall"):
    import os

    os._exit(0)
s.close()
