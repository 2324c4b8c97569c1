//! End-to-end tests of the multi-process runtime: `etp run` spawning the real
//! `etp-coordinator`, `etp-agent` and `etp-sensor-node` binaries.

use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::Threshold;
use etp_shared::rng::streams;
use etp_shared::scenario::Scenario;
use etp_shared::stats::Estimate;
use etp_synthesis::simulate::simulate;
use etp_tests::{EtpRun, kill, no_leftovers, processes_of_run, unique_run_id, wait_for_process};
use serde_json::Value;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

#[path = "runtime/recording.rs"]
mod recording;

// Recording format 5 read by other tools; the format-4 fixture (issue 43).
#[path = "runtime/mcap_tools.rs"]
mod mcap_tools;
#[path = "runtime/mcap_tools_fixtures.rs"]
mod mcap_tools_fixtures;

#[path = "runtime/publish.rs"]
mod publish;

#[path = "runtime/foxglove.rs"]
mod foxglove;

#[path = "runtime/layering.rs"]
mod layering;

#[path = "runtime/code_shape.rs"]
mod code_shape;

#[path = "runtime/faults.rs"]
mod faults;

#[path = "runtime/remote.rs"]
mod remote;

// Certificate failures named, one bundle per host (issue 41).
#[path = "runtime/certs.rs"]
mod certs;

// A stalled peer's cost bounded, the flood inside namespaces (issue 41
// round two, items 3 and 1).
#[path = "runtime/stalls.rs"]
mod stalls;

// A real network between the hosts: the fault proxy's matrix (issue 53).
#[path = "runtime/network.rs"]
mod network;

#[path = "runtime/lossy.rs"]
mod lossy;

// A leg's OPEN that reaches its sensor after the leg's first truth (issue 53's hang).
#[path = "runtime/late_open.rs"]
mod late_open;

#[path = "runtime/folders.rs"]
mod folders;

// Trigger families as processes (issue 40 item 2).
#[path = "runtime/families.rs"]
mod families;

// The live view over the Foxglove WebSocket protocol (issue 43 item 3).
#[path = "runtime/live.rs"]
mod live;

// Interrupted runs recorded as they happened: 20 seeded interrupts, local
// and with a remote sensor (issue 52 item 4).
#[path = "runtime/interrupts.rs"]
mod interrupts;
// An interrupt before the first episode leaves nothing.
#[path = "runtime/early_interrupts.rs"]
mod early_interrupts;

const DELTA: &str = "1.4986";

/// Multi-process runs take both cores; run them one at a time so the timing
/// assertions (fault detection < 100 ms, exit < 1 s) measure the runtime, not
/// the other tests. Poisoning (a failed test) must not fail the others.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn run_json(tag: &str, args: &[&str]) -> (String, Value) {
    let id = unique_run_id(tag);
    let (ok, out, err) = EtpRun::spawn(&id, args).finish();
    assert!(ok, "etp run failed: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("bad JSON ({e}): {out}"));
    (id, v)
}

fn num(v: &Value, k: &str) -> f64 {
    v[k].as_f64()
        .unwrap_or_else(|| panic!("no number `{k}` in {v}"))
}

fn est(v: &Value, k: &str) -> Estimate {
    Estimate {
        value: num(v, k),
        ci95: num(v, &format!("{k}_ci95")),
    }
}

/// Every leg's ledger: attempts = delivered + lost and delivered = what
/// the agent received; per sensor too.
fn assert_ledgers_match(v: &Value, skip_degraded: bool) {
    let mut per_sensor = std::collections::HashMap::<u64, [u64; 4]>::new();
    for e in v["episode_results"].as_array().expect("episode_results") {
        if skip_degraded && e["degraded"].as_bool() == Some(true) {
            continue;
        }
        assert_eq!(e["degraded"].as_bool(), Some(false), "episode {e}");
        for l in e["legs"].as_array().expect("legs") {
            let received = l["received"].as_u64().expect("received");
            let count = |k: &str| l[k].as_u64().unwrap_or_else(|| panic!("no ledger: {l}"));
            let (attempts, delivered, lost) =
                (count("transmissions"), count("delivered"), count("lost"));
            let at = format!("episode {} leg {}", e["episode"], l["leg"]);
            assert_eq!(attempts, delivered + lost, "{at}");
            assert_eq!(delivered, received, "{at}");
            let s = per_sensor
                .entry(l["sensor"].as_u64().expect("sensor"))
                .or_default();
            for (t, x) in s.iter_mut().zip([attempts, delivered, lost, received]) {
                *t += x;
            }
        }
    }
    if !skip_degraded {
        for (i, s) in v["sensors"].as_array().expect("sensors").iter().enumerate() {
            let t = per_sensor.get(&(i as u64)).copied().unwrap_or_default();
            for (k, x) in ["transmissions", "delivered", "lost", "received"]
                .iter()
                .zip(t)
            {
                assert_eq!(s[*k].as_u64(), Some(x), "{k}: {s}");
            }
        }
    }
}

/// Per sensor: `transmissions` (Σ ledgers) = `received` = Σ received on
/// the legs with a ledger, and `received_without_ledger` = Σ received on the
/// legs without; returns the latter per sensor and what the agent received
/// on the first leg without a ledger (the open leg of the first death).
fn assert_totals_over_ledgered_legs(v: &Value) -> (Vec<u64>, u64) {
    let sensors = v["sensors"].as_array().expect("sensors");
    let (mut led, mut got, mut without) = (
        vec![0u64; sensors.len()],
        vec![0u64; sensors.len()],
        vec![0u64; sensors.len()],
    );
    let mut open = None;
    for e in v["episode_results"].as_array().expect("episode_results") {
        for l in e["legs"].as_array().expect("legs") {
            let i = l["sensor"].as_u64().expect("sensor") as usize;
            let r = l["received"].as_u64().expect("received");
            match l["transmissions"].as_u64() {
                Some(t) => {
                    led[i] += t;
                    got[i] += r;
                }
                None => {
                    without[i] += r;
                    open.get_or_insert(r);
                }
            }
        }
    }
    for (i, s) in sensors.iter().enumerate() {
        assert_eq!(s["transmissions"].as_u64(), Some(led[i]), "{s}");
        assert_eq!(s["received"].as_u64(), Some(got[i]), "{s}");
        assert_eq!(s["transmissions"], s["received"], "{s}");
        assert_eq!(
            s["received_without_ledger"].as_u64(),
            Some(without[i]),
            "{s}"
        );
    }
    (without, open.unwrap_or(0))
}

#[test]
fn ledgers_equal_received_and_outcomes_agree_with_in_process_simulation() {
    let _serial = serial();
    let (id, v) = run_json(
        "agree",
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            "300",
            "--seed",
            "11",
            "--episode-details",
        ],
    );
    for k in [
        "episodes",
        "p_target",
        "p_collision",
        "energy_mean",
        "predicted",
        "sensors",
        "processes",
        "degraded",
    ] {
        assert!(v.get(k).is_some(), "key `{k}` missing");
    }
    for k in ["p_target", "p_collision", "energy_mean"] {
        assert!(v["predicted"].get(k).is_some(), "predicted.{k} missing");
    }
    for s in v["sensors"].as_array().expect("sensors") {
        for k in ["name", "transmissions", "received", "predicted_energy"] {
            assert!(s.get(k).is_some(), "sensors[].{k} missing");
        }
    }
    assert_eq!(num(&v, "episodes"), 300.0);
    assert_eq!(num(&v, "processes"), 9.0, "coordinator + agent + 7 sensors");
    assert_eq!(num(&v, "degraded"), 0.0);
    for p in v["process_exits"].as_array().expect("process_exits") {
        assert_eq!(p["status"].as_str(), Some("exit 0"), "{p}");
    }
    assert_ledgers_match(&v, false);

    // The same strategy in-process (independent random streams).
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let c = CompiledScenario::<2>::new(&s);
    let t = Threshold::new(DELTA.parse().expect("δ"));
    let policy = move |_: usize, _: &_, _: &mut _| LegMode::<2>::EventTriggered(t);
    let sim = simulate(&c, &policy, 3000, 5, streams::VALIDATE, &|_: u64| {})
        .expect("simulates")
        .summary();
    for (k, inproc) in [
        ("p_target", sim.p_target),
        ("p_collision", sim.p_collision),
        ("energy_mean", sim.energy_mean),
    ] {
        let ipc = est(&v, k);
        assert!(
            (ipc.value - inproc.value).abs() <= ipc.ci95 + inproc.ci95,
            "{k}: IPC {:.4} ± {:.4} vs in-process {:.4} ± {:.4}",
            ipc.value,
            ipc.ci95,
            inproc.value,
            inproc.ci95
        );
    }
    assert!(processes_of_run(&id).is_empty());
    no_leftovers(&id).expect("clean /dev/shm and root folder");
}

#[test]
fn the_same_seed_gives_the_same_episodes() {
    let _serial = serial();
    let args = [
        "--scenario",
        "open-2d",
        "--delta",
        "1.4986",
        "--episodes",
        "25",
        "--seed",
        "3",
        "--episode-details",
    ];
    let (_, a) = run_json("seed-a", &args);
    let (_, b) = run_json("seed-b", &args);
    assert_eq!(a["episode_results"], b["episode_results"]);
    let other = [
        "--scenario",
        "open-2d",
        "--delta",
        "1.4986",
        "--episodes",
        "25",
        "--seed",
        "4",
        "--episode-details",
    ];
    let (_, c) = run_json("seed-c", &other);
    assert_ne!(a["episode_results"], c["episode_results"]);
}

fn unix_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

#[test]
fn a_killed_sensor_is_detected_the_episode_degraded_and_the_run_continues() {
    let _serial = serial();
    let id = unique_run_id("kill");
    let run = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            "400",
            "--seed",
            "2",
            "--episode-details",
            "--allow-degraded",
        ],
    );
    // s2 serves legs 3 and 4 of every episode that gets that far.
    let victim = wait_for_process(&id, "etp-sensor-node", Some(("--sensor", "s2")));
    std::thread::sleep(Duration::from_millis(1500));
    let killed_at = unix_ns();
    kill("-KILL", &victim.to_string());
    let (ok, out, err) = run.finish();
    assert!(ok, "etp run failed: {err}");
    let v: Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(num(&v, "episodes"), 400.0, "the run continued to the end");
    assert!(num(&v, "degraded") >= 1.0);
    let faults = v["faults"].as_array().expect("faults");
    let f = faults.first().expect("a fault is reported");
    assert_eq!(f["sensor"].as_str(), Some("s2"));
    let detected = f["detected_unix_ns"].as_u64().expect("detected");
    let waited_from = f["wait_started_unix_ns"]
        .as_u64()
        .expect("wait start")
        .max(killed_at);
    let latency_ms = (detected.saturating_sub(waited_from)) as f64 / 1e6;
    eprintln!("dead link of s2 detected {latency_ms:.1} ms after it mattered");
    assert!(
        latency_ms < 100.0,
        "dead link seen {latency_ms:.1} ms after it mattered"
    );
    assert!(f["dead_slots"].as_u64().expect("dead slots") >= 1);
    // Healthy episodes still balance exactly; the dead sensor's status is the kill.
    assert_ledgers_match(&v, true);
    // Issue 24 item 2: exit 0 with --allow-degraded means every identity
    // holds over what it counts. The dead sensor's legs without a ledger
    // (the one it died in, and its later ones) are reported apart; every
    // sensor's totals, s2's included, balance over the legs with a ledger.
    let (without, open_received) = assert_totals_over_ledgered_legs(&v);
    let s2 = &v["sensors"][2];
    assert_eq!(
        s2["received_without_ledger"].as_u64(),
        Some(without[2]),
        "{s2}"
    );
    assert!(s2["missing_ledgers"].as_u64() >= Some(1), "{s2}");
    eprintln!(
        "s2 killed {}: {} measurement(s) received on its open leg, reported apart",
        if open_received > 0 {
            "mid-leg"
        } else {
            "between its legs"
        },
        open_received
    );
    let exits = v["process_exits"].as_array().expect("exits");
    for p in exits {
        let expected = if p["pid"].as_u64() == Some(u64::from(victim)) {
            "signal 9"
        } else {
            "exit 0"
        };
        assert_eq!(p["status"].as_str(), Some(expected), "{p}");
    }
    assert!(processes_of_run(&id).is_empty());
    no_leftovers(&id).expect("clean /dev/shm and root folder");
}

/// Issue 24 item 2: `--allow-degraded` after a sensor dies with its leg
/// open (the run: seed 9, δ = 1.4986, kill -9 of s2). The death is
/// made to fall inside one of s2's legs: s2 is stopped first, so the run
/// goes on until the agent waits on a slot of s2's next (or current) leg,
/// and is killed there. Every identity holds over what is counted (the
/// legs with a ledger), the open leg's received measurements are excused
/// and reported apart (`received_without_ledger`), exit 0; the recording's
/// replay agrees and exits 0 too.
#[test]
fn a_sensor_killed_with_its_leg_open_is_excused_exactly_and_every_identity_holds() {
    let _serial = serial();
    let id = unique_run_id("openleg");
    let dir = std::env::temp_dir().join(format!("etp-{id}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch");
    let rec = dir.join("run.mcap");
    let run = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            "300",
            "--seed",
            "9",
            "--episode-details",
            "--allow-degraded",
            "--record",
            rec.to_str().expect("utf-8"),
        ],
    );
    let victim = wait_for_process(&id, "etp-sensor-node", Some(("--sensor", "s2")));
    std::thread::sleep(Duration::from_millis(1000));
    kill("-STOP", &victim.to_string());
    // The agent now runs on until it waits on a slot of s2 (a stopped
    // sensor is alive: it is waited for), i.e. until s2's leg is open.
    std::thread::sleep(Duration::from_millis(500));
    kill("-KILL", &victim.to_string());
    let (ok, out, err) = run.finish();
    assert!(ok, "etp run --allow-degraded failed: {err}");
    let v: Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(num(&v, "episodes"), 300.0, "the run continued to the end");
    let f = &v["faults"][0];
    assert_eq!(f["sensor"].as_str(), Some("s2"), "{}", v["faults"]);
    // The episode s2 died in: its open leg is one of s2's, without a ledger.
    let episode = f["episode"].as_u64().expect("episode");
    let e = v["episode_results"]
        .as_array()
        .expect("episode_results")
        .iter()
        .find(|e| e["episode"].as_u64() == Some(episode))
        .expect("the fault's episode");
    assert_eq!(e["degraded"].as_bool(), Some(true), "{e}");
    let open: Vec<&Value> = e["legs"]
        .as_array()
        .expect("legs")
        .iter()
        .filter(|l| l["transmissions"].is_null())
        .collect();
    assert!(
        !open.is_empty() && open.iter().all(|l| l["sensor"].as_u64() == Some(2)),
        "the open leg is s2's: {e}"
    );
    let (without, open_received) = assert_totals_over_ledgered_legs(&v);
    // Only s2 has anything excused; every other sensor balances in full.
    for (i, w) in without.iter().enumerate() {
        if i != 2 {
            assert_eq!(*w, 0, "sensor {i}");
        }
    }
    let s2 = &v["sensors"][2];
    assert_eq!(s2["received_without_ledger"].as_u64(), Some(without[2]));
    assert!(s2["missing_ledgers"].as_u64() >= Some(1), "{s2}");
    eprintln!(
        "s2 killed with its leg open: {open_received} measurement(s) received on it, excused; \
         {} in all on legs without a ledger",
        without[2]
    );
    // The recording tells the same: episodes, counts, statistics and the
    // verdict equal the run's; identities hold, exit 0.
    interrupts::assert_replay_is_the_run("a degraded run", &v, &rec);
    let replay = std::process::Command::new(etp_tests::bin_dir().join("etp"))
        .args(["replay", rec.to_str().expect("utf-8"), "--json"])
        .output()
        .expect("etp replay");
    let r: Value = serde_json::from_slice(&replay.stdout).unwrap_or_else(|e| {
        panic!(
            "replay JSON ({e}): {}",
            String::from_utf8_lossy(&replay.stderr)
        )
    });
    assert_eq!(
        replay.status.code(),
        Some(0),
        "{}: {}",
        r["identity_failures"],
        String::from_utf8_lossy(&replay.stderr)
    );
    assert_eq!(r["identities_hold"].as_bool(), Some(true), "{r}");
    // Degraded episodes are complete episodes (their dead legs excused),
    // not partial ones: the replay counts what the run counted.
    assert_eq!(r["episodes"].as_u64(), Some(300), "{}", r["partial"]);
    assert_eq!(r["degraded_episodes"], v["degraded"]);
    for (i, s) in r["sensors"].as_array().expect("sensors").iter().enumerate() {
        assert_eq!(s["transmissions"], v["sensors"][i]["transmissions"], "{s}");
        assert_eq!(s["received"], v["sensors"][i]["received"], "{s}");
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(processes_of_run(&id).is_empty());
    no_leftovers(&id).expect("clean /dev/shm and root folder");
}

#[test]
fn when_the_coordinator_dies_agent_and_sensors_exit_within_a_second() {
    let _serial = serial();
    let id = unique_run_id("coord");
    let run = EtpRun::spawn(
        &id,
        &[
            "--scenario",
            "winding-2d",
            "--delta",
            DELTA,
            "--episodes",
            "100000",
        ],
    );
    let coordinator = wait_for_process(&id, "etp-coordinator", None);
    std::thread::sleep(Duration::from_millis(1000));
    let others = processes_of_run(&id).len();
    assert!(
        others >= 9,
        "etp run + coordinator + agent + 7 sensors, saw {others}"
    );
    kill("-KILL", &coordinator.to_string());
    let killed = Instant::now();
    loop {
        let left: Vec<_> = processes_of_run(&id)
            .into_iter()
            .filter(|(pid, _)| *pid != run.pid())
            .collect();
        if left.is_empty() {
            break;
        }
        assert!(
            killed.elapsed() < Duration::from_secs(1),
            "still running 1 s after the coordinator died: {left:?}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let (ok, _, err) = run.finish();
    assert!(!ok, "no report without a coordinator");
    assert!(err.contains("coordinator"), "{err}");
    no_leftovers(&id).expect("clean /dev/shm and root folder");
}
