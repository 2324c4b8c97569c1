//! The trust boundary of a run across hosts (network namespaces as in
//! `remote.rs`): outsiders with a real Zenoh client (the Python
//! `eclipse-zenoh` 1.10.2 package, installed into `target/pyenv` on first
//! use), forged and garbage traffic, a duplicate sensor host, a stalled
//! subscriber, and the ordering of a sensor's messages across the link.

use super::remote::{Guard, NS_OUT, certs_init, hosts};
use super::{assert_ledgers_match, num, serial};
use etp_tests::bin_dir;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const DELTA: &str = "1.0518";
const ZENOH_PY: &str = "eclipse-zenoh==1.10.2";

/// The Python interpreter of `target/pyenv` with `eclipse-zenoh` 1.10.2;
/// made on first use. Never skipped: a failure says how to fix it.
fn python() -> PathBuf {
    static MADE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _once = MADE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let env = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .expect("target folder")
        .join("pyenv");
    let py = env.join("bin/python");
    let has = |py: &Path| {
        Command::new(py)
            .args([
                "-c",
                "import zenoh, sys; sys.exit(0 if zenoh.__version__.startswith('1.10') else 1)",
            ])
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if has(&py) {
        return py;
    }
    let fail = |what: &str, out: &std::process::Output| -> ! {
        panic!(
            "{what} failed: {}\n(these tests need Python 3 with venv and access to PyPI: \
             python3 -m venv {0} && {0}/bin/pip install {ZENOH_PY})",
            String::from_utf8_lossy(&out.stderr),
            env.display()
        )
    };
    let out = Command::new("python3")
        .args(["-m", "venv"])
        .arg(&env)
        .output()
        .expect("python3");
    if !out.status.success() {
        fail("python3 -m venv", &out);
    }
    let out = Command::new(env.join("bin/pip"))
        .args(["install", "-q", ZENOH_PY])
        .output()
        .expect("pip");
    if !out.status.success() || !has(&py) {
        fail(&format!("pip install {ZENOH_PY}"), &out);
    }
    py
}

/// Run the outsider script in namespace `ns` with `args`.
fn outsider(ns: &str, args: &Value) -> Guard {
    use std::os::unix::process::CommandExt;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/runtime/outsider.py");
    let mut c = Command::new("ip");
    c.args(["netns", "exec", ns])
        .arg(python())
        .arg(script)
        .arg(args.to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0);
    Guard(Some(c.spawn().expect("spawning the outsider")))
}

fn outsider_report(g: Guard) -> Value {
    let (code, out, err) = g.finish();
    assert_eq!(code, Some(0), "outsider: {err}\n{out}");
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}\n{err}"))
}

/// `etp run` args of a run of open-2d with `remote` served elsewhere.
fn run_args(
    run_id: &str,
    episodes: &str,
    link: &[&str],
    remote: &str,
    extra: &[&str],
) -> Vec<String> {
    let mut v: Vec<String> = [
        "run",
        "--scenario",
        "open-2d",
        "--delta",
        DELTA,
        "--episodes",
        episodes,
        "--seed",
        "3",
        "--run-id",
        run_id,
        "--remote",
        remote,
        "--episode-details",
        "--json",
        "--join-timeout",
        "30",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    v.extend(link.iter().map(|s| s.to_string()));
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

fn scratch(tag: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("trust-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch");
    d
}

fn refusal_kinds(v: &Value) -> Vec<String> {
    v["link"]["refusals"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|r| r["kind"].as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default()
}

/// Verify the recording: recorded measurements == ledgers == received.
fn assert_recording_matches_ledgers(rec: &Path, v: &Value) {
    let out = Command::new(bin_dir().join("etp"))
        .args(["replay", &rec.display().to_string(), "--verify", "--json"])
        .output()
        .expect("replay");
    let r: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{e}: {out:?}"));
    let ledgers: u64 = v["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .filter_map(|s| s["transmissions"].as_u64())
        .sum();
    assert!(ledgers > 0, "{v}");
    assert_eq!(r["measurements"].as_u64(), Some(ledgers), "{r}");
    assert_eq!(r["transmissions"].as_u64(), Some(ledgers), "{r}");
    assert_eq!(r["received"].as_u64(), Some(ledgers), "{r}");
    assert!(out.status.success(), "{out:?}");
}

#[test]
fn over_tls_an_outsider_cannot_connect_query_or_subscribe_and_another_identity_cannot_put() {
    let _serial = serial();
    let Some(h) = hosts("tl", 2) else { return };
    let dir = scratch("tls");
    certs_init(&dir.join("certs"), &["b=s1", "c=s4"]);
    let certs = format!("{NS_OUT}/certs");
    let run_id = format!("tls{}", std::process::id());
    let args = run_args(
        &run_id,
        "150",
        &["--listen", "tls/0.0.0.0:7447", "--tls", &certs],
        "s1",
        &[],
    );
    let run = h.spawn_out(&h.agent, &dir, &strs(&args));
    let b = h.spawn_out(
        &h.sensors[0],
        &dir,
        &[
            "sensor-host",
            "--connect",
            "tls/10.77.1.1:7447",
            "--tls",
            &certs,
            "--identity",
            "b",
            "--json",
        ],
    );
    // From the other sensor namespace: the network, not a host of the run.
    let ca = dir.join("certs/ca.pem").display().to_string();
    let key = |n: &str| dir.join(format!("certs/{n}")).display().to_string();
    let run_keys = format!("etp/{run_id}/**");
    let garbage = hex(&[0u8; 7]);
    let attempts = [
        (
            "plain tcp",
            json!({"endpoint": "tcp/10.77.2.1:7447", "tls": null}),
        ),
        (
            "tls without a certificate",
            json!({"endpoint": "tls/10.77.2.1:7447", "tls": {"ca": ca}}),
        ),
        (
            "a self-made certificate",
            json!({"endpoint": "tls/10.77.2.1:7447",
                   "tls": {"ca": ca, "cert": key("own.pem"), "key": key("own-key.pem")}}),
        ),
    ];
    // A certificate of another CA (made the same way, never trusted here).
    certs_init(&dir.join("other"), &["own"]);
    for f in ["own.pem", "own-key.pem"] {
        std::fs::copy(dir.join("other").join(f), dir.join("certs").join(f)).expect("copy");
    }
    let mut reports = Vec::new();
    for (what, mut a) in attempts {
        a["run"] = json!(run_id);
        a["query"] = json!(true);
        a["subscribe"] = json!(run_keys);
        a["seconds"] = json!(1);
        reports.push((what, outsider_report(outsider(&h.sensors[1], &a))));
    }
    // A valid certificate of host c, which may serve s4 only: it may not
    // subscribe to the run's traffic nor put on b's keys or its own.
    let c = outsider(
        &h.sensors[1],
        &json!({"endpoint": "tls/10.77.2.1:7447", "run": run_id,
                "tls": {"ca": ca, "cert": key("c.pem"), "key": key("c-key.pem")},
                "subscribe": run_keys, "wait": 1, "seconds": 2,
                "puts": [[format!("etp/{run_id}/up/b/measurement"), garbage],
                         [format!("etp/{run_id}/up/c/measurement"), garbage]]}),
    );
    let c = outsider_report(c);
    let (code, out, err) = run.finish();
    let (bcode, _, berr) = b.finish();
    for (what, r) in &reports {
        assert_eq!(r["connected"], json!(false), "{what}: {r}");
        assert_eq!(r["replies"], json!(0), "{what}: {r}");
        assert_eq!(r["received"], json!(0), "{what}: {r}");
    }
    assert_eq!(c["connected"], json!(true), "{c}");
    assert_eq!(c["received"], json!(0), "host c subscribed to the run: {c}");
    assert_eq!(code, Some(0), "etp run: {err}\nhost b: {berr}");
    assert_eq!(bcode, Some(0), "host b: {berr}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(num(&v, "degraded"), 0.0);
    assert_eq!(v["link"]["refused"].as_u64(), Some(0), "{}", v["link"]);
    assert_ledgers_match(&v, false);
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

#[test]
fn garbage_and_forged_traffic_is_refused_as_a_fault_and_never_recorded() {
    let _serial = serial();
    let Some(h) = hosts("fg", 2) else { return };
    let dir = scratch("forged");
    let run_id = format!("forged{}", std::process::id());
    let rec = format!("{NS_OUT}/forged.mcap");
    let args = run_args(
        &run_id,
        "200",
        &["--listen", "tcp/0.0.0.0:7447", "--insecure"],
        "s1",
        &["--record", &rec],
    );
    let run = h.spawn_out(&h.agent, &dir, &strs(&args));
    let b = h.spawn(
        &h.sensors[0],
        &[
            "sensor-host",
            "--connect",
            "tcp/10.77.1.1:7447",
            "--insecure",
            "--identity",
            "b",
            "--json",
        ],
    );
    let o = outsider(
        &h.sensors[1],
        &json!({"endpoint": "tcp/10.77.2.1:7447", "run": run_id, "query": true,
                "subscribe": format!("etp/{run_id}/down/**"), "capture": true, "host": "b", "wait": 1,
                "puts": [[format!("etp/{run_id}/up/b/measurement"), hex(&[0u8; 7])],
                         [format!("etp/{run_id}/up/x/slot"), hex(b"garbage")]]}),
    );
    let o = outsider_report(o);
    let (code, out, err) = run.finish();
    let _ = b.finish();
    assert_eq!(o["connected"], json!(true), "{o}");
    assert!(o["forged"].as_array().is_some_and(|f| f.len() >= 5), "{o}");
    assert_eq!(code, Some(6), "a refused message is a fault: {err}");
    assert!(err.contains("refused"), "{err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    let kinds = refusal_kinds(&v);
    for k in ["malformed", "replayed", "not-remote"] {
        assert!(kinds.iter().any(|x| x == k), "{k} not in {kinds:?}");
    }
    // Nothing forged got in: the exact three-way count holds.
    assert_eq!(num(&v, "degraded"), 0.0);
    assert_ledgers_match(&v, false);
    assert_recording_matches_ledgers(&dir.join("forged.mcap"), &v);
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_second_host_claiming_a_served_sensor_is_refused() {
    let _serial = serial();
    let Some(h) = hosts("dp", 2) else { return };
    let dir = scratch("dup");
    let run_id = format!("dup{}", std::process::id());
    let rec = format!("{NS_OUT}/dup.mcap");
    let args = run_args(
        &run_id,
        "100",
        &["--listen", "tcp/0.0.0.0:7447", "--insecure"],
        "s1",
        &["--record", &rec],
    );
    let run = h.spawn_out(&h.agent, &dir, &strs(&args));
    let b = h.spawn(
        &h.sensors[0],
        &[
            "sensor-host",
            "--connect",
            "tcp/10.77.1.1:7447",
            "--insecure",
            "--identity",
            "b",
            "--json",
        ],
    );
    let c = h.spawn(
        &h.sensors[1],
        &[
            "sensor-host",
            "--connect",
            "tcp/10.77.2.1:7447",
            "--insecure",
            "--identity",
            "c",
            "--json",
        ],
    );
    let (code, out, err) = run.finish();
    let _ = (b.finish(), c.finish());
    assert_eq!(code, Some(6), "a duplicate host is a fault: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    let kinds = refusal_kinds(&v);
    assert!(kinds.iter().any(|k| k == "duplicate-host"), "{kinds:?}");
    assert_eq!(num(&v, "degraded"), 0.0);
    assert_ledgers_match(&v, false);
    assert_recording_matches_ledgers(&dir.join("dup.mcap"), &v);
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_stalled_subscriber_cannot_stall_the_run() {
    let _serial = serial();
    let Some(h) = hosts("st", 2) else { return };
    let dir = scratch("stall");
    let run_id = format!("stall{}", std::process::id());
    let args = run_args(
        &run_id,
        "200",
        &["--listen", "tcp/0.0.0.0:7447", "--insecure"],
        "s1",
        &[],
    );
    let started = Instant::now();
    let run = h.spawn_out(&h.agent, &dir, &strs(&args));
    let b = h.spawn(
        &h.sensors[0],
        &[
            "sensor-host",
            "--connect",
            "tcp/10.77.1.1:7447",
            "--insecure",
            "--identity",
            "b",
            "--json",
        ],
    );
    // Reads one sample of everything, then never again.
    let o = outsider(
        &h.sensors[1],
        &json!({"endpoint": "tcp/10.77.2.1:7447", "run": run_id,
                "subscribe": format!("etp/{run_id}/**"), "stall": true, "seconds": 60}),
    );
    let (code, out, err) = run.finish();
    let took = started.elapsed();
    let _ = b.finish();
    drop(o);
    eprintln!("run with a stalled subscriber: {:.1} s", took.as_secs_f64());
    assert_eq!(code, Some(0), "etp run: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(num(&v, "degraded"), 0.0);
    assert_ledgers_match(&v, false);
    assert!(took < Duration::from_secs(55), "the run took {took:?}");
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Finding 6: all seven sensors of winding-2d on one sensor host; a slot
/// must never overtake its measurement. 20 runs in a row.
#[test]
fn seven_remote_sensors_on_one_host_keep_their_order_20_times() {
    let _serial = serial();
    let Some(h) = hosts("sv", 1) else { return };
    let dir = scratch("seven");
    for k in 0..20 {
        let run_id = format!("seven{}-{k}", std::process::id());
        let run = h.spawn_out(
            &h.agent,
            &dir,
            &[
                "run",
                "--scenario",
                "winding-2d",
                "--delta",
                "1.4986",
                "--episodes",
                "60",
                "--seed",
                "21",
                "--run-id",
                &run_id,
                "--listen",
                "tcp/0.0.0.0:7461",
                "--insecure",
                "--remote",
                "s0,s1,s2,s3,s4,s5,s6",
                "--episode-details",
                "--json",
                "--join-timeout",
                "30",
            ],
        );
        let b = h.spawn(
            &h.sensors[0],
            &[
                "sensor-host",
                "--connect",
                "tcp/10.77.1.1:7461",
                "--insecure",
                "--json",
            ],
        );
        let (code, out, err) = run.finish();
        let (bcode, _, berr) = b.finish();
        assert_eq!(code, Some(0), "run {k}: {err}\nsensor host: {berr}");
        assert_eq!(bcode, Some(0), "run {k}: {berr}");
        let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
        assert_eq!(num(&v, "degraded"), 0.0, "run {k}");
        assert_eq!(
            v["link"]["refused"].as_u64(),
            Some(0),
            "run {k}: {}",
            v["link"]
        );
        assert_ledgers_match(&v, false);
    }
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}
