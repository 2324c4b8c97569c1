//! A real network between the hosts (issue 53 item 3): every sensor of
//! winding-2d served by one sensor host in its own namespace, reached over
//! TLS through `etp-fault-proxy` (a TCP proxy in the agent host's namespace
//! that adds latency with jitter, limits the rate, stalls, resets,
//! blackholes). Each case ends within its bound (printed) with exact counts
//! (exit 0) or a named fault (exit 5: the report names the dead link; the
//! identities hold on every leg with a ledger), its recording verifies, and
//! nothing of it is left running.

use super::remote::{Guard, Hosts, LogWatch, NS_OUT, certs_init, hosts, scratch};
use super::{assert_ledgers_match, num, serial};
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const REMOTE: &str = "s0,s1,s2,s3,s4,s5,s6";
/// Where the agent host's bridge listens (inside its namespace), and where
/// the proxy listens for the sensor host.
const BRIDGE_PORT: u16 = 7447;
const PROXY: &str = "10.77.1.1:7448";

/// The fault proxy in the agent host's namespace, forwarding [`PROXY`] to
/// the bridge; commands on its stdin, acknowledged on its stdout.
struct Proxy {
    guard: Guard,
    stdin: std::process::ChildStdin,
    acks: std::sync::mpsc::Receiver<String>,
}

impl Proxy {
    fn start(h: &Hosts) -> Self {
        use std::os::unix::process::CommandExt;
        let mut child = Command::new("ip")
            .args(["netns", "exec", &h.agent])
            .arg(env!("CARGO_BIN_EXE_etp-fault-proxy"))
            .args(["--listen", PROXY, "--to"])
            .arg(format!("127.0.0.1:{BRIDGE_PORT}"))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .process_group(0)
            .spawn()
            .expect("etp-fault-proxy");
        let stdin = child.stdin.take().expect("stdin");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, acks) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for l in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = tx.send(l);
            }
        });
        let first = acks.recv_timeout(Duration::from_secs(20));
        assert_eq!(first.as_deref(), Ok("listening"), "the proxy did not start");
        Self {
            guard: Guard(Some(child)),
            stdin,
            acks,
        }
    }

    /// Apply `cmd` and wait for the proxy's acknowledgement.
    fn send(&mut self, cmd: &str) {
        writeln!(self.stdin, "{cmd}").expect("proxy stdin");
        let ack = self.acks.recv_timeout(Duration::from_secs(10));
        assert_eq!(ack, Ok(format!("ok {cmd}")), "proxy command `{cmd}`");
    }
}

/// What happens to the link once the run is in its episodes.
#[derive(Clone, Copy)]
enum Fault {
    /// Proxy commands, given before the run starts.
    Network(&'static [&'static str]),
    /// Proxy commands, given mid-run.
    Proxy(&'static [&'static str]),
    /// The agent host's `etp-bridge` killed with SIGKILL.
    KillAgentBridge,
    /// Every process of the sensor host killed, then the sensor host
    /// started again.
    RestartSensorHost,
    /// Sensor s1's process stopped (SIGSTOP): alive, its host and link
    /// alive, but its slot never comes.
    StopSensor,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Expect {
    /// Exit 0, nothing degraded.
    Exact,
    /// Exit 5 with the fault named (`--allow-degraded`: exit 0).
    NamedFault,
}

struct Case {
    tag: &'static str,
    episodes: u32,
    fault: Fault,
    expect: Expect,
    /// The whole run, from its start to its report.
    bound: Duration,
    allow_degraded: bool,
}

fn pids_in(ns: &str) -> Vec<u32> {
    Command::new("ip")
        .args(["netns", "pids", ns])
        .output()
        .map(|o| {
            String::from_utf8_lossy(&o.stdout)
                .split_whitespace()
                .filter_map(|p| p.parse().ok())
                .collect()
        })
        .unwrap_or_default()
}

/// The pids in `ns` whose command line contains every word of `words`.
fn pids_of(ns: &str, words: &[&str]) -> Vec<u32> {
    pids_in(ns)
        .into_iter()
        .filter(|p| {
            let args = std::fs::read(format!("/proc/{p}/cmdline")).unwrap_or_default();
            let args: Vec<String> = args
                .split(|b| *b == 0)
                .map(|a| String::from_utf8_lossy(a).into_owned())
                .collect();
            words
                .iter()
                .all(|w| args.iter().any(|a| a == w || a.ends_with(&format!("/{w}"))))
        })
        .collect()
}

fn sensor_host(h: &Hosts, dir: &std::path::Path) -> (Guard, LogWatch) {
    h.spawn_watched_out(
        &h.sensors[0],
        dir,
        &[
            "sensor-host",
            "--connect",
            &format!("tls/{PROXY}"),
            "--tls",
            &format!("{NS_OUT}/keys/b"),
            "--name",
            "b",
            "--join-timeout",
            "30",
            "--json",
        ],
    )
}

fn run_case(c: &Case) {
    let _serial = serial();
    let Some(h) = hosts(c.tag, 1) else { return };
    let dir = scratch(c.tag);
    certs_init(&dir.join("keys"), &["b"]);
    let mut proxy = Proxy::start(&h);
    if let Fault::Network(cmds) = c.fault {
        for cmd in cmds {
            proxy.send(cmd);
        }
    }
    let rec = format!("{NS_OUT}/net.mcap");
    let episodes = c.episodes.to_string();
    let listen = format!("tls/0.0.0.0:{BRIDGE_PORT}");
    let keys = format!("{NS_OUT}/keys");
    let mut args = vec![
        "run",
        "--scenario",
        "winding-2d",
        "--delta",
        "1.4986",
        "--episodes",
        &episodes,
        "--seed",
        "5",
        "--listen",
        &listen,
        "--tls",
        &keys,
        "--remote",
        REMOTE,
        "--record",
        &rec,
        "--episode-details",
        "--json",
        "--join-timeout",
        "30",
        // A hang fails the test in bounded time instead of an hour.
        "--deadline",
        "300",
    ];
    if c.allow_degraded {
        args.push("--allow-degraded");
    }
    eprintln!(
        "network case {}: bound {:.0} s, expect {:?}",
        c.tag,
        c.bound.as_secs_f64(),
        c.expect
    );
    let started = Instant::now();
    let (run, run_log) = h.spawn_watched_out(&h.agent, &dir, &args);
    let (mut b, mut b_log) = sensor_host(&h, &dir);
    let in_episodes = |w: &LogWatch| w.ledger_episodes() >= 2;
    let mut stopped = None;
    match c.fault {
        Fault::Network(_) => {}
        Fault::Proxy(cmds) => {
            b_log.wait_for("the run in its episodes", in_episodes);
            for cmd in cmds {
                proxy.send(cmd);
            }
        }
        Fault::KillAgentBridge => {
            b_log.wait_for("the run in its episodes", in_episodes);
            let pids = pids_of(&h.agent, &["etp-bridge", "agent-host"]);
            assert_eq!(pids.len(), 1, "the agent host's bridge: {pids:?}");
            etp_tests::kill("-KILL", &pids[0].to_string());
        }
        Fault::RestartSensorHost => {
            b_log.wait_for("the run in its episodes", in_episodes);
            for p in pids_in(&h.sensors[0]) {
                etp_tests::kill("-KILL", &p.to_string());
            }
            drop(b);
            (b, b_log) = sensor_host(&h, &dir);
        }
        Fault::StopSensor => {
            b_log.wait_for("the run in its episodes", in_episodes);
            let pids = pids_of(&h.sensors[0], &["etp-sensor-node", "s1"]);
            assert_eq!(pids.len(), 1, "sensor s1's process: {pids:?}");
            etp_tests::kill("-STOP", &pids[0].to_string());
            stopped = Some(pids[0]);
        }
    }
    let (code, out, _) = run.finish();
    let took = started.elapsed();
    // The stopped sensor goes on once the run is over (and sees it over).
    if let Some(p) = stopped {
        etp_tests::kill("-CONT", &p.to_string());
    }
    let (bcode, _, _) = b.finish();
    let err = run_log.lines().join("\n");
    let berr = b_log.lines();
    let btail = berr[berr.len().saturating_sub(20)..].join("\n");
    eprintln!(
        "network case {}: exit {code:?} after {:.1} s (bound {:.0} s); sensor host exit {bcode:?}",
        c.tag,
        took.as_secs_f64(),
        c.bound.as_secs_f64()
    );
    let v: Value = serde_json::from_str(&out)
        .unwrap_or_else(|e| panic!("{}: no report ({e}): {err}\nsensor host: {btail}", c.tag));
    let want = match (c.expect, c.allow_degraded) {
        (Expect::Exact, _) | (Expect::NamedFault, true) => Some(0),
        (Expect::NamedFault, false) => Some(5),
    };
    assert_eq!(code, want, "{}: {err}\nsensor host: {btail}", c.tag);
    assert!(
        took <= c.bound,
        "{}: took {:.1} s, bound {:.0} s",
        c.tag,
        took.as_secs_f64(),
        c.bound.as_secs_f64()
    );
    assert_eq!(num(&v, "episodes"), f64::from(c.episodes), "{}", c.tag);
    match c.expect {
        Expect::Exact => {
            assert_eq!(num(&v, "degraded"), 0.0, "{}: {}", c.tag, v["faults"]);
            assert_ledgers_match(&v, false);
        }
        Expect::NamedFault => {
            // Named: a dead link the run's faults or the link report name.
            let named = !v["faults"].as_array().is_none_or(Vec::is_empty)
                || !v["link"]["dead_links"].as_array().is_none_or(Vec::is_empty);
            assert!(named, "{}: no named fault: {v}", c.tag);
            assert_ledgers_match(&v, true);
        }
    }
    // The agent host's recording verifies.
    let verify = Command::new(etp_tests::bin_dir().join("etp"))
        .args(["replay", "verify"])
        .arg(dir.join("net.mcap"))
        .arg("--json")
        .output()
        .expect("replay");
    assert!(
        verify.status.success(),
        "{}: replay verify: {verify:?}",
        c.tag
    );
    // Nothing left running in either namespace but the proxy.
    drop(proxy.guard);
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline
        && !(pids_in(&h.agent).is_empty() && pids_in(&h.sensors[0]).is_empty())
    {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        pids_in(&h.agent).is_empty() && pids_in(&h.sensors[0]).is_empty(),
        "{}: left running: agent host {:?}, sensor host {:?}",
        c.tag,
        pids_in(&h.agent),
        pids_in(&h.sensors[0])
    );
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_remote_sensor_that_stops_answering_is_a_named_dead_link_within_the_bound() {
    run_case(&Case {
        tag: "nstop",
        episodes: 6,
        fault: Fault::StopSensor,
        expect: Expect::NamedFault,
        bound: Duration::from_secs(60),
        allow_degraded: false,
    });
}

#[test]
fn twenty_ms_latency_with_jitter_runs_exactly() {
    run_case(&Case {
        tag: "nlat",
        episodes: 1,
        fault: Fault::Network(&["latency 20 5"]),
        expect: Expect::Exact,
        bound: Duration::from_secs(90),
        allow_degraded: false,
    });
}

#[test]
fn one_megabit_per_second_runs_exactly() {
    run_case(&Case {
        tag: "nrate",
        episodes: 6,
        fault: Fault::Network(&["rate 125000"]),
        expect: Expect::Exact,
        bound: Duration::from_secs(60),
        allow_degraded: false,
    });
}

#[test]
fn a_two_second_stall_ends_in_a_named_fault_within_the_bound() {
    run_case(&Case {
        tag: "nst2",
        episodes: 6,
        fault: Fault::Proxy(&["stall 2 both"]),
        expect: Expect::NamedFault,
        bound: Duration::from_secs(60),
        allow_degraded: false,
    });
}

#[test]
fn a_ten_second_stall_ends_in_a_named_fault_within_the_bound() {
    run_case(&Case {
        tag: "nst10",
        episodes: 6,
        fault: Fault::Proxy(&["stall 10 both"]),
        expect: Expect::NamedFault,
        bound: Duration::from_secs(60),
        allow_degraded: false,
    });
}

#[test]
fn a_reset_mid_episode_is_a_named_fault_and_accepted_with_allow_degraded() {
    run_case(&Case {
        tag: "nrst",
        episodes: 6,
        fault: Fault::Proxy(&["reset"]),
        expect: Expect::NamedFault,
        bound: Duration::from_secs(60),
        allow_degraded: true,
    });
}

#[test]
fn the_agent_hosts_bridge_killed_is_a_named_fault_within_the_bound() {
    run_case(&Case {
        tag: "nkb",
        episodes: 6,
        fault: Fault::KillAgentBridge,
        expect: Expect::NamedFault,
        bound: Duration::from_secs(60),
        allow_degraded: false,
    });
}

#[test]
fn the_sensor_host_killed_and_started_again_is_a_named_fault_within_the_bound() {
    run_case(&Case {
        tag: "nrs",
        episodes: 6,
        fault: Fault::RestartSensorHost,
        expect: Expect::NamedFault,
        bound: Duration::from_secs(60),
        allow_degraded: false,
    });
}
