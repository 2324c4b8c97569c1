//! Runs across hosts: network namespaces joined by veth pairs, each host with
//! its own mount namespace (private /dev/shm and /tmp, so shared memory
//! cannot cross), the agent host in one, sensor hosts in the others, Zenoh
//! between them. Needs root (CI is root): without it the tests skip, unless
//! `CI` is set, where they fail.

use super::{assert_ledgers_match, est, num, serial};
use etp_shared::episode::{CompiledScenario, LegMode};
use etp_shared::etkf::Threshold;
use etp_shared::rng::streams;
use etp_shared::scenario::Scenario;
use etp_synthesis::simulate::simulate;
use etp_tests::{bin_dir, kill};
use serde_json::Value;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

const DELTA: &str = "1.0518";

pub(super) fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("ip {args:?}: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {args:?}: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// Where a namespace's process sees the test's output folder.
pub(super) const NS_OUT: &str = "/dev/shm/.etp-out";

/// Network namespaces `<tag>a` (agent host) and one per sensor host, each
/// joined to the agent host by a veth pair 10.77.<k>.1 ↔ 10.77.<k>.2;
/// everything in them is killed and they are deleted on drop.
pub(super) struct Hosts {
    pub(super) agent: String,
    pub(super) sensors: Vec<String>,
}

impl Hosts {
    fn new(tag: &str, sensor_hosts: usize) -> Result<Self, String> {
        let p = std::process::id() % 100_000;
        let h = Self {
            agent: format!("etp{p}{tag}a"),
            sensors: (0..sensor_hosts)
                .map(|k| format!("etp{p}{tag}s{k}"))
                .collect(),
        };
        ip(&["netns", "add", &h.agent])?;
        ip(&["-n", &h.agent, "link", "set", "lo", "up"])?;
        for (k, ns) in h.sensors.iter().enumerate() {
            ip(&["netns", "add", ns])?;
            ip(&["-n", ns, "link", "set", "lo", "up"])?;
            let (va, vs) = h.veth(k);
            ip(&["link", "add", &va, "type", "veth", "peer", "name", &vs])?;
            ip(&["link", "set", &va, "netns", &h.agent])?;
            ip(&["link", "set", &vs, "netns", ns])?;
            let net = k + 1;
            ip(&[
                "-n",
                &h.agent,
                "addr",
                "add",
                &format!("10.77.{net}.1/24"),
                "dev",
                &va,
            ])?;
            ip(&[
                "-n",
                ns,
                "addr",
                "add",
                &format!("10.77.{net}.2/24"),
                "dev",
                &vs,
            ])?;
            ip(&["-n", &h.agent, "link", "set", &va, "up"])?;
            ip(&["-n", ns, "link", "set", &vs, "up"])?;
        }
        Ok(h)
    }

    /// The veth pair of sensor host k: (agent side, sensor side).
    pub(super) fn veth(&self, k: usize) -> (String, String) {
        let p = std::process::id() % 100_000;
        (format!("va{p}{k}"), format!("vs{p}{k}"))
    }

    pub(super) fn spawn(&self, ns: &str, args: &[&str]) -> Guard {
        self.spawn_in(ns, None, args)
    }

    /// [`Hosts::spawn`] with `out` visible inside as [`NS_OUT`].
    pub(super) fn spawn_out(&self, ns: &str, out: &std::path::Path, args: &[&str]) -> Guard {
        self.spawn_in(ns, Some(out), args)
    }

    /// Spawn `etp <args>` in namespace `ns` with private /dev/shm and /tmp.
    /// The binaries (and `out`, for files the test reads afterwards) may
    /// themselves live under /tmp (a clone there): they are bind-mounted to
    /// `/dev/shm/.etp-bin` and [`NS_OUT`] before /tmp is covered.
    fn spawn_in(&self, ns: &str, out: Option<&std::path::Path>, args: &[&str]) -> Guard {
        use std::os::unix::process::CommandExt;
        let bin = bin_dir();
        let out = out.map_or_else(|| bin.clone(), std::path::Path::to_path_buf);
        let script = format!(
            "set -e; mount -t tmpfs none /dev/shm; mkdir /dev/shm/.etp-bin {NS_OUT}; \
             mount --bind '{}' /dev/shm/.etp-bin; mount --bind '{}' {NS_OUT}; \
             mount -t tmpfs none /tmp; exec /dev/shm/.etp-bin/etp \"$@\"",
            bin.display(),
            out.display()
        );
        let mut c = Command::new("ip");
        c.args([
            "netns",
            "exec",
            ns,
            "unshare",
            "-m",
            "--propagation",
            "private",
            "sh",
            "-c",
        ])
        .arg(script)
        .arg("sh")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0);
        Guard(Some(c.spawn().expect("spawning in a namespace")))
    }

    pub(super) fn kill_all_in(ns: &str) {
        if let Ok(out) = Command::new("ip").args(["netns", "pids", ns]).output() {
            for pid in String::from_utf8_lossy(&out.stdout).split_whitespace() {
                kill("-KILL", pid);
            }
        }
    }
}

impl Drop for Hosts {
    fn drop(&mut self) {
        for ns in self.sensors.iter().chain(std::iter::once(&self.agent)) {
            Self::kill_all_in(ns);
        }
        std::thread::sleep(Duration::from_millis(100));
        for ns in self.sensors.iter().chain(std::iter::once(&self.agent)) {
            let _ = ip(&["netns", "del", ns]);
        }
    }
}

/// A child in its own process group, killed with its group on drop.
pub(super) struct Guard(pub(super) Option<Child>);

impl Guard {
    pub(super) fn finish(mut self) -> (Option<i32>, String, String) {
        let c = self.0.take().expect("child");
        let out = c.wait_with_output().expect("waiting");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }
}

impl Drop for Guard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            kill("-KILL", &format!("-{}", c.id()));
            let _ = c.wait();
        }
    }
}

/// Namespaces, or `None` to skip (not root, not in CI).
pub(super) fn hosts(tag: &str, n: usize) -> Option<Hosts> {
    assert!(
        bin_dir().join("etp-bridge").is_file(),
        "etp-bridge missing: cargo test --workspace builds it"
    );
    match Hosts::new(tag, n) {
        Ok(h) => Some(h),
        Err(e) if std::env::var_os("CI").is_some() => {
            panic!("CI is set but network namespaces cannot be made: {e}")
        }
        Err(e) => {
            eprintln!("skipped: network namespaces need root ({e})");
            None
        }
    }
}

/// `etp certs init DIR --host …` (fresh DIR).
pub(super) fn certs_init(dir: &std::path::Path, hosts: &[&str]) {
    let _ = std::fs::remove_dir_all(dir);
    let mut c = Command::new(bin_dir().join("etp"));
    c.arg("certs").arg("init").arg(dir);
    for h in hosts {
        c.args(["--host", h]);
    }
    let out = c.output().expect("etp certs init");
    assert!(out.status.success(), "etp certs init: {out:?}");
}

pub(super) fn unix_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

#[test]
fn a_run_across_three_hosts_counts_exactly_and_verifies() {
    let _serial = serial();
    let Some(h) = hosts("ok", 2) else { return };
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("remote-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch");
    let rec = dir.join("across.mcap");
    let _ = std::fs::remove_file(&rec);
    // Mutual TLS with access control: host b may serve s1 and s3, host c s4.
    certs_init(&dir.join("certs"), &["b=s1,s3", "c=s4"]);
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
            "60",
            "--seed",
            "9",
            "--listen",
            "tls/0.0.0.0:7447",
            "--tls",
            &format!("{NS_OUT}/certs"),
            "--remote",
            "s1,s3,s4",
            "--record",
            &format!("{NS_OUT}/across.mcap"),
            "--episode-details",
            "--json",
            "--join-timeout",
            "30",
        ],
    );
    let certs = format!("{NS_OUT}/certs");
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
            "--sensor",
            "s1",
            "--sensor",
            "s3",
            "--json",
        ],
    );
    let c = h.spawn_out(
        &h.sensors[1],
        &dir,
        &[
            "sensor-host",
            "--connect",
            "tls/10.77.2.1:7447",
            "--tls",
            &certs,
            "--identity",
            "c",
            "--sensor",
            "s4",
            "--json",
        ],
    );
    let (code, out, err) = run.finish();
    let hosts: Vec<_> = [("B", b), ("C", c)]
        .into_iter()
        .map(|(host, g)| (host, g.finish()))
        .collect();
    let all = hosts
        .iter()
        .map(|(host, (code, out, err))| format!("sensor host {host} ({code:?}): {err}\n{out}"))
        .collect::<Vec<_>>()
        .join("\n");
    assert_eq!(code, Some(0), "etp run: {err}\n{all}");
    for (_, (code, ..)) in &hosts {
        assert_eq!(*code, Some(0), "{all}");
    }
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(num(&v, "episodes"), 60.0);
    assert_eq!(num(&v, "degraded"), 0.0);
    assert_ledgers_match(&v, false);
    // The three-way count across hosts: the remote sensors' ledgers (made on
    // their hosts) equal what the agent received and what the link carried.
    for s in v["sensors"].as_array().expect("sensors") {
        let name = s["name"].as_str().expect("name");
        let remote = ["s1", "s3", "s4"].contains(&name);
        assert_eq!(s["remote"].as_bool().unwrap_or(false), remote, "{s}");
        if remote {
            assert_eq!(
                s["traffic_carried"], s["traffic"],
                "{name}: carried vs counted"
            );
            assert_eq!(
                s["traffic_carried"]["up_radio"]["messages"].as_u64(),
                s["transmissions"].as_u64(),
                "{name}"
            );
        }
    }
    assert!(
        v["downlink"]["saved_fraction"].as_f64() > Some(0.9),
        "{}",
        v["downlink"]
    );
    // Outcomes agree with the in-process simulation of the same δ.
    let s = Scenario::builtin("open-2d").expect("built-in");
    let cs = CompiledScenario::<2>::new(&s);
    let t = Threshold::new(DELTA.parse().expect("δ"));
    let policy = move |_: usize, _: &_, _: &mut _| LegMode::<2>::EventTriggered(t);
    let sim = simulate(&cs, &policy, 3000, 5, streams::VALIDATE, &|_| {}).summary();
    for (k, inproc) in [("p_target", sim.p_target), ("p_collision", sim.p_collision)] {
        let ipc = est(&v, k);
        assert!(
            (ipc.value - inproc.value).abs() <= ipc.ci95 + inproc.ci95,
            "{k}: across hosts {:.4} ± {:.4} vs in-process {:.4} ± {:.4}",
            ipc.value,
            ipc.ci95,
            inproc.value,
            inproc.ci95
        );
    }
    // The agent host's recording verifies bit for bit (replicas included).
    let out = Command::new(bin_dir().join("etp"))
        .args(["replay", &rec.display().to_string(), "--verify", "--json"])
        .output()
        .expect("replay");
    assert!(out.status.success(), "{out:?}");
    let r: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(r["verify"]["episodes_checked"].as_u64(), Some(60), "{r}");
    // Recorded on the agent host == the sensors' ledgers == agent received.
    let ledgers: u64 = v["sensors"]
        .as_array()
        .expect("sensors")
        .iter()
        .filter_map(|s| s["transmissions"].as_u64())
        .sum();
    assert!(ledgers > 0, "{v}");
    // `measurements`: messages on the recorded channel; `transmissions`: the
    // recorded ledgers; `received`: the agent's counts in the outcomes.
    assert_eq!(r["measurements"].as_u64(), Some(ledgers), "{r}");
    assert_eq!(r["transmissions"].as_u64(), Some(ledgers), "{r}");
    assert_eq!(r["received"].as_u64(), Some(ledgers), "{r}");
    assert_eq!(r["verify"]["mismatch_count"].as_u64(), Some(0), "{r}");
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_killed_sensor_host_and_a_cut_link_are_detected_within_500_ms_and_the_run_goes_on() {
    let _serial = serial();
    let Some(h) = hosts("ft", 2) else { return };
    let run = h.spawn(
        &h.agent,
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            DELTA,
            "--episodes",
            "200",
            "--seed",
            "4",
            "--listen",
            "tcp/0.0.0.0:7447",
            "--insecure",
            "--remote",
            "s1,s4",
            "--allow-degraded",
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
            "tcp/10.77.1.1:7447",
            "--insecure",
            "--sensor",
            "s1",
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
            "--sensor",
            "s4",
            "--json",
        ],
    );
    // Let the run start (join, then a few episodes).
    std::thread::sleep(Duration::from_secs(4));
    let killed_at = unix_ns();
    Hosts::kill_all_in(&h.sensors[1]);
    drop(c);
    std::thread::sleep(Duration::from_secs(2));
    let (va, _) = h.veth(0);
    let cut_at = unix_ns();
    ip(&["-n", &h.agent, "link", "set", &va, "down"]).expect("link down");
    let cut = Instant::now();
    // The cut-off sensor host ends by itself (it lost the agent host).
    let (_, _, berr) = b.finish();
    assert!(
        cut.elapsed() < Duration::from_secs(10),
        "sensor host B hung: {berr}"
    );
    let (code, out, err) = run.finish();
    assert_eq!(code, Some(0), "etp run: {err}");
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(num(&v, "episodes"), 200.0, "the run went on");
    assert!(num(&v, "degraded") >= 1.0, "{}", v["faults"]);
    let lost = v["link"]["lost"].as_array().expect("lost");
    let at = |name: &str| {
        lost.iter()
            .find(|l| l[0] == name)
            .and_then(|l| l[1].as_u64())
            .unwrap_or_else(|| panic!("{name} never reported lost: {lost:?}"))
    };
    let kill_ms = at("s4").saturating_sub(killed_at) as f64 / 1e6;
    let cut_ms = at("s1").saturating_sub(cut_at) as f64 / 1e6;
    eprintln!("host killed: lost after {kill_ms:.0} ms; link cut: lost after {cut_ms:.0} ms");
    assert!(kill_ms < 500.0, "killed host seen after {kill_ms:.0} ms");
    assert!(cut_ms < 500.0, "cut link seen after {cut_ms:.0} ms");
    // No implicit update on a dead link: the faults name the lost sensors,
    // and every episode that was not degraded still balances exactly.
    let faulted: Vec<&str> = v["faults"]
        .as_array()
        .expect("faults")
        .iter()
        .filter_map(|f| f["sensor"].as_str())
        .collect();
    assert!(
        faulted.contains(&"s4") && faulted.contains(&"s1"),
        "{faulted:?}"
    );
    assert_ledgers_match(&v, true);
}
