//! The trust boundary, round two (issue 41 items 3 and 1), inside network
//! namespaces: a certified peer that stops reading costs the run nothing,
//! and a flood of connections from another host does not keep the real
//! sensor host out.

use super::remote::{
    Guard, Hosts, LogWatch, NS_OUT, PY_CONNECT, certs_init, hosts, scratch, tls_args,
};
use super::{assert_ledgers_match, num, serial};
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const DELTA: &str = "1.0518";

/// A Python `eclipse-zenoh` peer in the second sensor host's namespace,
/// `script` run with `args`; stdin and stdout piped, killed with its process
/// group on drop.
fn python_child(h: &Hosts, script: &str, args: &[std::path::PathBuf]) -> Guard {
    use std::os::unix::process::CommandExt;
    let c = Command::new("ip")
        .args(["netns", "exec", &h.sensors[1]])
        .arg(etp_tests::pyenv::python())
        .args(["-c", script])
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .expect("python zenoh");
    Guard(Some(c))
}

/// The stalled peer: a certified host that may serve s1 (`rogue=s1`), like
/// the real one, on the second host's network. It asks for the run, then
/// subscribes to every downlink key it can name — s1's, the real host's,
/// its own, wildcards — with a callback that never returns, a 4 KiB receive
/// buffer and a 600 s lease (so it is never closed for silence, only for
/// not reading). Says `subscribed`, then waits for a line on stdin and
/// prints how many samples reached it.
fn rogue_script() -> String {
    format!(
        r#"{PY_CONNECT}
import threading
s = session(sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4],
            {{"transport/link/tls/so_rcvbuf": "4096", "transport/link/tx/lease": "600000"}})
seen = []
def on(sample):
    seen.append(str(sample.key_expr))
    threading.Event().wait(600)   # stops reading: this callback does not return
run = None
end = time.time() + 20
while run is None and time.time() < end:
    for r in s.get("etp/session", timeout=0.5):
        if r.ok is not None:
            run = json.loads(bytes(r.ok.payload.to_bytes()))["run_id"]
if run is None:
    sys.exit("the session query was not answered: not connected?")
subs = [s.declare_subscriber(k, on) for k in [
    "etp/**", f"etp/{{run}}/down/**", f"etp/{{run}}/down/sensor/1/**",
    f"etp/{{run}}/down/*/sensor/1/**", f"etp/{{run}}/down/b/sensor/1/**",
    f"etp/{{run}}/down/rogue/sensor/1/**"]]
print("subscribed", flush=True)
sys.stdin.readline()
print(json.dumps({{"run": run, "samples": len(seen)}}), flush=True)
os._exit(0)                      # its callback may still wait
"#
    )
}

/// One run of 600 episodes with s1 on sensor host `b`; with `rogue`, the
/// stalled peer is connected and subscribed before `b` starts. Returns the
/// seconds from `b`'s start to the run's end, the report and what the
/// rogue saw.
fn timed_run(
    h: &Hosts,
    dir: &std::path::Path,
    keys: &std::path::Path,
    run_id: &str,
    rogue: bool,
) -> (f64, Value, Option<Value>) {
    let ns_keys = format!("{NS_OUT}/keys");
    let run = h.spawn_out(
        &h.agent,
        dir,
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            DELTA,
            "--episodes",
            "600",
            "--seed",
            "6",
            "--run-id",
            run_id,
            "--listen",
            "tls/0.0.0.0:7447",
            "--tls",
            &ns_keys,
            "--remote",
            "s1",
            "--episode-details",
            "--json",
            "--join-timeout",
            "60",
        ],
    );
    let mut peer = rogue.then(|| {
        let mut g = python_child(h, &rogue_script(), &tls_args(keys, "rogue"));
        let out = g.0.as_mut().and_then(|c| c.stdout.take()).expect("stdout");
        let mut lines = BufReader::new(out).lines();
        match lines.next() {
            Some(Ok(l)) if l.trim() == "subscribed" => {}
            other => {
                let err =
                    g.0.as_mut()
                        .and_then(|c| c.stderr.take())
                        .map(|mut e| {
                            let mut s = String::new();
                            let _ = std::io::Read::read_to_string(&mut e, &mut s);
                            s
                        })
                        .unwrap_or_default();
                panic!("the rogue did not subscribe: {other:?}: {err}")
            }
        }
        (g, lines)
    });
    let started = Instant::now();
    let b = h.spawn_out(
        &h.sensors[0],
        dir,
        &[
            "sensor-host",
            "--connect",
            "tls/10.77.1.1:7447",
            "--tls",
            &format!("{ns_keys}/b"),
            "--name",
            "b",
            "--join-timeout",
            "60",
        ],
    );
    let (code, out, err) = run.finish();
    let secs = started.elapsed().as_secs_f64();
    let _ = b.finish();
    let seen = peer.as_mut().map(|(g, lines)| {
        if let Some(stdin) = g.0.as_mut().and_then(|c| c.stdin.as_mut()) {
            let _ = stdin.write_all(b"end\n");
            let _ = stdin.flush();
        }
        let last = lines.map_while(Result::ok).last().unwrap_or_default();
        serde_json::from_str::<Value>(&last).unwrap_or_else(|e| panic!("rogue: {e}: {last}"))
    });
    drop(peer);
    assert_eq!(code, Some(0), "etp run {run_id}: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    (secs, v, seen)
}

/// Issue 41 item 3: a certified host that may serve s1, like the real one
/// (`b`), subscribes to every downlink key it can name and stops reading
/// (its callback never returns). Before, the agent host's puts towards s1
/// waited for its full queue until Zenoh closed it (5 s), then it
/// reconnected and stalled again: 29.5 s against 10.0 s. Now each remote
/// sensor's downlink goes only to the host granted it at join, under keys
/// access control grants that host alone: the rogue gets no sample, holds
/// nothing up, and the run takes as long as without it (measured: wall
/// time from the sensor host's start to the run's end, with and without).
#[test]
fn a_stalled_certified_peer_of_a_served_sensor_costs_the_run_nothing() {
    let _serial = serial();
    let Some(h) = hosts("st", 2) else { return };
    let dir = scratch("st");
    let keys = dir.join("keys");
    certs_init(&keys, &["b=s1", "rogue=s1"]);
    // The agent host's send buffers capped at 16 KiB: a peer that stops
    // reading fills its queue at once.
    let wmem = Command::new("ip")
        .args(["netns", "exec", &h.agent, "sysctl", "-qw"])
        .arg("net.ipv4.tcp_wmem=4096 16384 16384")
        .status()
        .expect("sysctl");
    assert!(wmem.success(), "capping the agent host's send buffers");
    let p = std::process::id();
    let (base, vb, _) = timed_run(&h, &dir, &keys, &format!("t{p}-stbase"), false);
    let (with, vr, seen) = timed_run(&h, &dir, &keys, &format!("t{p}-strogue"), true);
    // Where a long run's time went: the report's `seconds` count the
    // episodes alone, `wall_seconds` the whole of `etp run`.
    eprintln!(
        "stalled certified peer of s1: run {with:.1} s with it, {base:.1} s without (+{:.1} s); \
         stalled without: {}, with: {}; episodes {} s and etp run {} s without, {} s and {} s with",
        with - base,
        vb["link"]["stalled"],
        vr["link"]["stalled"],
        vb["seconds"],
        vb["wall_seconds"],
        vr["seconds"],
        vr["wall_seconds"]
    );
    for v in [&vb, &vr] {
        assert_eq!(num(v, "episodes"), 600.0);
        assert_eq!(num(v, "degraded"), 0.0);
        assert_eq!(v["link"]["refused"], serde_json::json!({}), "{v}");
        // No put waited until Zenoh closed a peer (a put towards b may wait
        // a moment on a loaded machine).
        for (k, st) in v["link"]["stalled"].as_object().into_iter().flatten() {
            assert_eq!(st["refused"], false, "{k}: {}", v["link"]);
            assert!(
                st["longest_ms"].as_u64() < Some(4_000),
                "{k}: {}",
                v["link"]
            );
        }
        assert_ledgers_match(v, false);
    }
    let seen = seen.expect("the rogue's count");
    assert_eq!(seen["samples"], 0, "the rogue got downlink samples: {seen}");
    // Zenoh closes a peer that stays full for 5 s: one stall would show.
    assert!(
        with <= base + 4.0,
        "the stalled peer cost {:.1} s ({with:.1} s against {base:.1} s)",
        with - base
    );
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The flooder, on the second sensor host's network (one source address):
/// 64 threads each keep a connection to the agent host's TLS port open that
/// sends nothing (held 12 s, beyond the 10 s handshake deadline, then
/// opened again), and 4 threads send junk (a bogus 12-byte TLS record, then
/// close). Bounded: it stops at a line on stdin, or after 120 s, and prints
/// its counts (connections opened, and how many the agent host closed at
/// once).
const FLOODER: &str = r#"
import json, select, socket, sys, threading, time
host, port = sys.argv[1], int(sys.argv[2])
stop = threading.Event()
stats = {"idle": 0, "closed_at_once": 0, "held": 0, "junk": 0}
lock = threading.Lock()
def add(k):
    with lock:
        stats[k] += 1
def idle():
    while not stop.is_set():
        try:
            s = socket.create_connection((host, port), timeout=1)
        except OSError:
            time.sleep(0.05)
            continue
        add("idle")
        s.settimeout(0.3)
        try:
            closed = s.recv(1) == b""
        except socket.timeout:
            closed = False
        except OSError:
            closed = True
        if closed:
            add("closed_at_once")
            s.close()
            time.sleep(0.2)
            continue
        add("held")
        end = time.time() + 12
        while time.time() < end and not stop.is_set():
            time.sleep(0.1)
        s.close()
def junk():
    while not stop.is_set():
        try:
            s = socket.create_connection((host, port), timeout=1)
            s.sendall(b"\x16\x03\x01\xff\xffgarbage")
            s.close()
            add("junk")
        except OSError:
            pass
        time.sleep(0.01)
threads = [threading.Thread(target=idle) for _ in range(64)] + [threading.Thread(target=junk) for _ in range(4)]
for t in threads:
    t.start()
time.sleep(1.0)
print("flooding", flush=True)
select.select([sys.stdin], [], [], 120)
stop.set()
for t in threads:
    t.join()
print(json.dumps(stats), flush=True)
"#;

/// Issue 41 item 1, inside namespaces: a host floods the agent host's TLS
/// port from one address with connections that send nothing (64 at a time,
/// each held beyond the handshake deadline) and with junk. At most
/// `PER_SOURCE_HANDSHAKES` (4) of its handshakes are under way at once; the
/// others are closed at once and counted (`too-many-from-source`). The real
/// sensor host, on another network, started once the flood is under way,
/// joins within seconds; the run is exact, and the refusals reach
/// `link.handshakes_refused`.
#[test]
fn a_flood_from_one_address_holds_at_most_four_handshakes_and_the_sensor_host_joins() {
    let _serial = serial();
    let Some(h) = hosts("fl", 2) else { return };
    let dir = scratch("fl");
    let keys = dir.join("keys");
    certs_init(&keys, &["b=s1"]);
    let ns_keys = format!("{NS_OUT}/keys");
    let run_id = format!("t{}-flood", std::process::id());
    let run = h.spawn_out(
        &h.agent,
        &dir,
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            DELTA,
            "--episodes",
            "100",
            "--seed",
            "2",
            "--run-id",
            &run_id,
            "--listen",
            "tls/0.0.0.0:7447",
            "--tls",
            &ns_keys,
            "--remote",
            "s1",
            "--episode-details",
            "--json",
            "--join-timeout",
            "60",
        ],
    );
    // The agent host listens once its bridge is up: give it a moment, then
    // flood (the flooder retries refused connects).
    std::thread::sleep(Duration::from_millis(500));
    let mut flooder = {
        use std::os::unix::process::CommandExt;
        Guard(Some(
            Command::new("ip")
                .args(["netns", "exec", &h.sensors[1]])
                .arg(etp_tests::pyenv::python())
                .args(["-c", FLOODER, "10.77.2.1", "7447"])
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::null())
                .process_group(0)
                .spawn()
                .expect("flooder"),
        ))
    };
    let mut lines = BufReader::new(
        flooder
            .0
            .as_mut()
            .and_then(|c| c.stdout.take())
            .expect("stdout"),
    )
    .lines();
    assert!(
        matches!(lines.next(), Some(Ok(l)) if l.trim() == "flooding"),
        "the flooder did not start"
    );
    let started = Instant::now();
    let b = h.spawn_out(
        &h.sensors[0],
        &dir,
        &[
            "sensor-host",
            "--connect",
            "tls/10.77.1.1:7447",
            "--tls",
            &format!("{ns_keys}/b"),
            "--name",
            "b",
            "--join-timeout",
            "60",
        ],
    );
    let (code, out, err) = run.finish();
    let secs = started.elapsed().as_secs_f64();
    let (bcode, _, berr) = b.finish();
    if let Some(stdin) = flooder.0.as_mut().and_then(|c| c.stdin.as_mut()) {
        let _ = stdin.write_all(b"end\n");
        let _ = stdin.flush();
    }
    let last = lines.map_while(Result::ok).last().unwrap_or_default();
    drop(flooder);
    let flood: Value =
        serde_json::from_str(&last).unwrap_or_else(|e| panic!("flooder: {e}: {last}"));
    assert_eq!(bcode, Some(0), "sensor host: {berr}");
    assert_eq!(code, Some(0), "etp run: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    let refused = &v["link"]["handshakes_refused"];
    eprintln!(
        "flood from one address: {flood}; agent host refused {refused}; \
         sensor host started → run over in {secs:.1} s"
    );
    assert_eq!(num(&v, "episodes"), 100.0);
    assert_eq!(num(&v, "degraded"), 0.0);
    assert_eq!(v["link"]["refused"], serde_json::json!({}), "{v}");
    assert_ledgers_match(&v, false);
    assert!(
        refused["too-many-from-source"].as_u64() >= Some(1),
        "no connection refused for its source's handshakes: {refused}"
    );
    // Of the 64 idle connections at a time, at most 4 are held.
    let held = flood["held"].as_u64().unwrap_or(u64::MAX);
    let idle = flood["idle"].as_u64().unwrap_or(0);
    assert!(idle >= 64, "{flood}");
    assert!(
        flood["closed_at_once"].as_u64() >= Some(idle / 2),
        "the flooder's idle connections were not closed at once: {flood}"
    );
    assert!(held < idle, "{flood}");
    // The sensor host joined within seconds: 100 episodes take about 2 s.
    assert!(secs < 30.0, "sensor host start → run end took {secs:.1} s");
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `etp run` for the granted-host test: s1 remote over TLS, `episodes`,
/// `--allow-degraded`, `--episode-details --json`.
fn owner_run(h: &Hosts, dir: &std::path::Path, run_id: &str, episodes: &str) -> (Guard, LogWatch) {
    let ns_keys = format!("{NS_OUT}/keys");
    h.spawn_watched_out(
        &h.agent,
        dir,
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            DELTA,
            "--episodes",
            episodes,
            "--seed",
            "4",
            "--run-id",
            run_id,
            "--listen",
            "tls/0.0.0.0:7447",
            "--tls",
            &ns_keys,
            "--remote",
            "s1",
            "--allow-degraded",
            "--episode-details",
            "--json",
            "--join-timeout",
            "60",
        ],
    )
}

/// [`Guard::finish`], but the process group is killed after `limit` (the
/// code is then `None`): a run that waits for ever fails the test instead
/// of hanging it.
fn finish_within(g: Guard, limit: Duration) -> (Option<i32>, String, String) {
    let pid = g.0.as_ref().map(std::process::Child::id).expect("child");
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watch = {
        let done = done.clone();
        std::thread::spawn(move || {
            let start = Instant::now();
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                if start.elapsed() >= limit {
                    etp_tests::kill("-KILL", &format!("-{pid}"));
                    return;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        })
    };
    let out = g.finish();
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = watch.join();
    out
}

/// The granted host itself stops reading: a Python `eclipse-zenoh` peer
/// with `b`'s certificate plays s1's host — it claims s1 in b's name,
/// subscribes to b's downlink keys with a callback that blocks on its first
/// sample (later calls only count), declares s1's token and says s1's hello
/// (forged with the run's tag), so the run starts; it never answers. The
/// agent waits for s1's slot (a live sensor is waited for), so the run puts
/// nothing more towards it: the agent host probes the host that owes an
/// answer (`session::probe_key`), the probes fill its queue, a put waits
/// until Zenoh closes it (5 s), and the host is refused for the rest of the
/// run. The unanswered slot passes the bound on waits (`answers::FLOOR`,
/// 5 s from the question, while the put is still waiting) first: s1 is cut
/// as a dead link (degraded episodes, exit 0 with `--allow-degraded`); the
/// put that was waiting ends in the close all the same. Its downlink is
/// dropped, and when the peer reconnects (Zenoh retries on its own) its
/// token is ignored, its claims of s1 are refused and it gets nothing more. `link.stalled` names the host
/// (the text report words the same record). The cost is measured against the same run with
/// the real sensor host `b`: the close's few seconds, once. Without the
/// refusal the reconnected peer is granted s1 again and the run waits on it
/// until the watchdog (180 s) ends it; without the probes it waits as long
/// as the peer's token lives.
#[test]
fn a_granted_host_that_stops_reading_is_closed_once_and_refused_for_the_rest_of_the_run() {
    let _serial = serial();
    let Some(h) = hosts("ow", 2) else { return };
    let dir = scratch("ow");
    let keys = dir.join("keys");
    certs_init(&keys, &["b=s1"]);
    let wmem = Command::new("ip")
        .args(["netns", "exec", &h.agent, "sysctl", "-qw"])
        .arg("net.ipv4.tcp_wmem=4096 16384 16384")
        .status()
        .expect("sysctl");
    assert!(wmem.success(), "capping the agent host's send buffers");
    let p = std::process::id();

    // Without the stalled host: the real `b` serves s1.
    let (run, run_log) = owner_run(&h, &dir, &format!("t{p}-ownbase"), "1000");
    std::thread::sleep(Duration::from_millis(500));
    let started = Instant::now();
    let (b, b_log) = h.spawn_watched_out(
        &h.sensors[0],
        &dir,
        &[
            "sensor-host",
            "--connect",
            "tls/10.77.1.1:7447",
            "--tls",
            &format!("{NS_OUT}/keys/b"),
            "--name",
            "b",
            "--join-timeout",
            "60",
        ],
    );
    let (code, out, _) = finish_within(run, Duration::from_secs(180));
    let base = started.elapsed().as_secs_f64();
    let (bcode, _, _) = b.finish();
    let tail = |w: &LogWatch| {
        let l = w.lines();
        l[l.len().saturating_sub(30)..].join("\n")
    };
    assert_eq!(
        code,
        Some(0),
        "etp run without the stalled host (None: killed after 180 s): {}\nsensor host b: {}",
        tail(&run_log),
        tail(&b_log)
    );
    assert_eq!(bcode, Some(0), "sensor host b: {}", tail(&b_log));
    let vb: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(num(&vb, "episodes"), 1000.0);
    assert_eq!(num(&vb, "degraded"), 0.0, "{vb}");
    assert_eq!(vb["link"]["refused"], serde_json::json!({}), "{vb}");
    assert_ledgers_match(&vb, false);

    // With the host that stops reading.
    let run_id = format!("t{p}-owner");
    let tag = etp_runtime::wire::RunId::new(&run_id)
        .expect("run id")
        .tag();
    let (mut run, log) = owner_run(&h, &dir, &run_id, "8000");
    let script = format!(
        r#"{PY_CONNECT}
import threading
# Zenoh logs to stdout: to the log file (stderr), the protocol lines to `out`.
out = os.fdopen(os.dup(1), "w")
os.dup2(2, 1)
zenoh.init_log_from_env_or("info")
s = session(sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4],
            {{"transport/link/tls/so_rcvbuf": "4096", "transport/link/tx/lease": "600000",
              # its own puts and queries towards the closed agent host give
              # up soon, so that it sees the close and reconnects at once
              "transport/link/tx/queue/congestion_control/block/wait_before_close": "200000",
              # and tries again every half second
              "connect/retry": '{{"period_init_ms": 500, "period_max_ms": 500, "period_increase_factor": 1}}'}})
tag = int(sys.argv[5])
def now():
    return time.strftime("%H:%M:%S", time.gmtime()) + f"{{time.time() % 1:.3f}}"[1:]
seen, events = [], []
closed = threading.Event()
def on(sample):
    seen.append(str(sample.key_expr))
    if len(seen) == 1:
        events.append(f"{{now()}} first sample: stops reading")
        closed.wait(120)   # stops reading (on Zenoh's network thread)
        events.append(f"{{now()}} reads again")
run = None
end = time.time() + 20
while run is None and time.time() < end:
    for r in s.get("etp/session", timeout=0.5):
        if r.ok is not None:
            run = json.loads(bytes(r.ok.payload.to_bytes()))["run_id"]
if run is None:
    sys.exit("the session query was not answered: not connected?")
claim = f"etp/{{run}}/join/1/b"
# A claim as an etp of link protocol 1 made it (its Zenoh id alone) is
# refused in words: its messages would lack their sender's time.
old = [bytes(r.err.payload.to_bytes()).decode(errors="replace")
       for r in s.get(claim, payload="python0", timeout=5) if r.ok is None]
if not any("link protocol 2, the sensor host 1" in e for e in old):
    sys.exit(f"a claim of link protocol 1 was not refused by name: {{old}}")
granted = [r.ok is not None for r in s.get(claim, payload="python0 link/2", timeout=5)]
if granted != [True]:
    sys.exit(f"s1 not granted: {{granted}}")
sub = s.declare_subscriber(f"etp/{{run}}/down/b/sensor/1/**",
                           zenoh.handlers.Callback(on, indirect=False))
token = s.liveliness().declare_token(f"etp/{{run}}/alive/sensor/1")
# s1's hello: its sender's time (a forged one: any number is only
# recorded), header (run, episode, step, leg, sender, seq), pid, pad
s.put(f"etp/{{run}}/up/1/hello",
      struct.pack("<QQQIIIIII", 2**64 - 1, tag, 0, 0, 0, 1, 1, 4242, 0))
print("hello", file=out, flush=True)
# stdin: "closed" (the agent host refused this peer: read again, so that
# Zenoh sees the closed transport and reconnects), then "end".
stop = threading.Event()
stalled_samples = []
def commands():
    for line in sys.stdin:
        if line.strip() == "closed":
            events.append(f"{{now()}} told: closed")
            stalled_samples.append(len(seen))
            closed.set()
        else:
            stop.set()
            return
    stop.set()
threading.Thread(target=commands, daemon=True).start()
# Until told to stop: claim s1 again every second (answered once Zenoh has
# reconnected this peer: its first transport no longer reads).
claims, refused_at = [], None
while not stop.is_set():
    try:
        for r in s.get(claim, payload="python0 link/2", timeout=1):
            claims.append("granted" if r.ok is not None
                          else bytes(r.err.payload.to_bytes()).decode(errors="replace"))
            events.append(f"{{now()}} claim: {{claims[-1]}}")
            if r.ok is None and "stopped reading" in claims[-1] and refused_at is None:
                refused_at = len(seen)
    except Exception as e:
        claims.append(f"error: {{e}}")
    stop.wait(1)
time.sleep(0.5)
print(json.dumps({{"run": run, "stalled_samples": stalled_samples[0] if stalled_samples else None,
                  "samples": len(seen),
                  "after_refused_claim": None if refused_at is None else len(seen) - refused_at,
                  "keys": sorted(set(seen)), "claims": claims, "events": events}}),
      file=out, flush=True)
os._exit(0)
"#
    );
    // Its log (Zenoh's, info) in a file: a pipe nobody reads would block it.
    let peer_log = dir.join("peer.log");
    let mut peer = {
        use std::os::unix::process::CommandExt;
        Guard(Some(
            Command::new("ip")
                .args(["netns", "exec", &h.sensors[1]])
                .arg(etp_tests::pyenv::python())
                .args(["-c", &script])
                .args(tls_args(&keys, "b"))
                .arg(tag.to_string())
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(std::fs::File::create(&peer_log).expect("peer log"))
                .process_group(0)
                .spawn()
                .expect("python zenoh"),
        ))
    };
    let mut lines = BufReader::new(
        peer.0
            .as_mut()
            .and_then(|c| c.stdout.take())
            .expect("stdout"),
    )
    .lines();
    let first = lines.next();
    if !matches!(&first, Some(Ok(l)) if l.trim() == "hello") {
        let e = std::fs::read_to_string(&peer_log).unwrap_or_default();
        panic!("the peer did not join: {first:?}: {e}");
    }
    let started = Instant::now();
    // Once the agent host refused it, the peer reads again (what it
    // reads is what was queued before the close), so that Zenoh reconnects
    // it and it tries again. Bounded: without a refusal, the run's end or
    // 120 s.
    let refusal = "closed for not reading: the host is refused for the rest of the run";
    while !log.lines().iter().any(|l| l.contains(refusal))
        && started.elapsed() < Duration::from_secs(120)
        && run
            .0
            .as_mut()
            .is_some_and(|c| matches!(c.try_wait(), Ok(None)))
    {
        std::thread::sleep(Duration::from_millis(50));
    }
    if let Some(stdin) = peer.0.as_mut().and_then(|c| c.stdin.as_mut()) {
        let _ = stdin.write_all(b"closed\n");
        let _ = stdin.flush();
    }
    let (code, out, _) = finish_within(run, Duration::from_secs(180));
    let with = started.elapsed().as_secs_f64();
    let err = log.lines().join("\n");
    if let Some(stdin) = peer.0.as_mut().and_then(|c| c.stdin.as_mut()) {
        let _ = stdin.write_all(b"end\n");
        let _ = stdin.flush();
    }
    let last = lines.map_while(Result::ok).last().unwrap_or_default();
    drop(peer);
    let peer_log = std::fs::read_to_string(&peer_log).unwrap_or_default();
    for l in peer_log
        .lines()
        .rev()
        .take(40)
        .collect::<Vec<_>>()
        .iter()
        .rev()
    {
        eprintln!("  peer: {}", l.chars().take(300).collect::<String>());
    }
    assert_eq!(
        code,
        Some(0),
        "etp run (None: still waiting after 180 s, killed): {err}"
    );
    let seen: Value = serde_json::from_str(&last).unwrap_or_else(|e| panic!("peer: {e}: {last}"));
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    let stalled = &v["link"]["stalled"];
    eprintln!(
        "granted host stopped reading: run of 8000 episodes {with:.1} s with it (from its \
         hello); 1000 episodes {base:.1} s with b (from b's start); stalled {stalled}; \
         degraded {}; the peer: {seen}",
        v["degraded"]
    );
    for l in err.lines().filter(|l| l.contains("WARN")) {
        eprintln!("  etp run: {l}");
    }
    assert_eq!(num(&v, "episodes"), 8000.0);
    assert!(num(&v, "degraded") >= 1.0, "s1 is a dead link: {v}");
    let s1 = &stalled["s1"];
    assert_eq!(s1["host"], "b", "{stalled}");
    assert_eq!(s1["refused"], true, "{stalled}");
    assert!(s1["longest_ms"].as_u64() >= Some(5_000), "{stalled}");
    // Closed once: no later put waited for it. While it did not read it got
    // its one sample (the one it blocked on); once reconnected, nothing.
    assert_eq!(s1["puts"], 1, "{stalled}");
    assert_eq!(seen["stalled_samples"], 1, "{seen}");
    assert_eq!(seen["after_refused_claim"], 0, "{seen}");
    assert!(
        err.contains("a host refused for not reading is back: ignored")
            || err.contains("a sensor cut as a dead link is back: ignored"),
        "its token, back after the reconnection, was not seen: {err}"
    );
    // It came back (Zenoh reconnected it) and its claims were refused.
    let claims = seen["claims"].as_array().cloned().unwrap_or_default();
    assert!(
        claims.iter().any(|c| c
            .as_str()
            .is_some_and(|c| c.contains("closed for the rest of the run"))),
        "the peer's claims after the close: {seen}"
    );
    assert!(
        !claims.iter().skip(1).any(|c| c == "granted"),
        "granted again (its first claim is its join): {seen}"
    );
    // The text report (without `--json`) says it in words from the same
    // `link.stalled` (unit test `remote::tests::the_text_report_names_…`).
    // What it cost: the agent waited for s1 once, until the host was
    // closed (1 s before the probes, their filling its queue, Zenoh's 5 s);
    // the other episodes ran with s1 dead (prediction only, cheaper than
    // served, so the run may even end sooner than with b).
    let waits: Vec<f64> = v["faults"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|f| f["detect_ms"].as_f64())
        .collect();
    eprintln!("the agent's waits for s1 before it was dead (ms): {waits:?}");
    assert_eq!(waits.len(), 1, "one wait: {}", v["faults"]);
    assert!(waits[0] <= 15_000.0, "held {} ms", waits[0]);
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}
