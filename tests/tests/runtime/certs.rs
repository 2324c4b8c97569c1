//! Certificate failures are named on the side that sees them (issue 41,
//! items 2 and 5): a sensor host trusts only its bundle's CA and the agent
//! host's name, so a listener with a certificate of another CA, an expired
//! one or one of the wrong role is refused at once, by name; the agent host
//! names the sensor-host certificates it refused, and the sensor host gets
//! a hint. Certificates beyond `etp certs init` (expired ones) are made here
//! with rcgen, with the same parameters.

use super::remote::{Guard, Hosts, NS_OUT, PY_LISTENER, certs_init, hosts, scratch};
use super::serial;
use etp_tests::bin_dir;
use rcgen::{
    BasicConstraints, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa,
    Issuer, KeyPair, KeyUsagePurpose,
};
use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Stdio};

/// A folder like `etp certs init DIR --sensor-host b`'s, made with rcgen:
/// each certificate valid from `now + from` to `now + to` days.
fn bundles(dir: &Path, agent: (i64, i64), b: (i64, i64)) {
    let now = time::OffsetDateTime::now_utc();
    let ca_key = KeyPair::generate().expect("key");
    let mut ca = CertificateParams::new(Vec::<String>::new()).expect("params");
    ca.distinguished_name = DistinguishedName::new();
    ca.distinguished_name.push(DnType::CommonName, "etp run CA");
    ca.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    ca.not_before = now - time::Duration::days(30);
    ca.not_after = now + time::Duration::days(30);
    let ca_pem = ca.self_signed(&ca_key).expect("ca").pem();
    let issuer = Issuer::new(ca, ca_key);
    let _ = std::fs::remove_dir_all(dir);
    for (name, server, (from, to)) in [("agent-host", true, agent), ("b", false, b)] {
        let key = KeyPair::generate().expect("key");
        let mut p = CertificateParams::new(vec![name.to_string()]).expect("params");
        p.distinguished_name = DistinguishedName::new();
        p.distinguished_name
            .push(DnType::CommonName, format!("etp {name}"));
        p.is_ca = IsCa::ExplicitNoCa;
        p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        p.extended_key_usages = vec![if server {
            ExtendedKeyUsagePurpose::ServerAuth
        } else {
            ExtendedKeyUsagePurpose::ClientAuth
        }];
        p.not_before = now + time::Duration::days(from);
        p.not_after = now + time::Duration::days(to);
        let cert = p.signed_by(&key, &issuer).expect("sign");
        let d = dir.join(name);
        std::fs::create_dir_all(&d).expect("bundle");
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o700)).expect("chmod");
        std::fs::write(d.join("ca.pem"), &ca_pem).expect("ca");
        std::fs::write(d.join(format!("{name}.pem")), cert.pem()).expect("cert");
        let k = d.join(format!("{name}.key"));
        std::fs::write(&k, key.serialize_pem()).expect("key");
        std::fs::set_permissions(&k, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    }
    std::fs::write(dir.join("agent-host/hosts.json"), r#"{"b": null}"#).expect("hosts");
}

/// A real Zenoh listener (Python) posing as the agent host with host
/// `cert`'s key pair of bundle folder `keys`.
fn fake_agent_host(h: &Hosts, keys: &Path, cert: &str) -> Guard {
    use std::os::unix::process::CommandExt;
    let b = keys.join(cert);
    Guard(Some(
        Command::new("ip")
            .args(["netns", "exec", &h.agent])
            .arg(etp_tests::pyenv::python())
            .args(["-c", PY_LISTENER])
            .arg(b.join("ca.pem"))
            .arg(b.join(format!("{cert}.pem")))
            .arg(b.join(format!("{cert}.key")))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .process_group(0)
            .spawn()
            .expect("python zenoh listener"),
    ))
}

/// `etp sensor-host` as `b` with bundle `bundle` (a path under NS_OUT).
fn sensor_host(h: &Hosts, dir: &Path, bundle: &str) -> Guard {
    h.spawn_out(
        &h.sensors[0],
        dir,
        &[
            "sensor-host",
            "--connect",
            "tls/10.77.1.1:7447",
            "--tls",
            &format!("{NS_OUT}/{bundle}"),
            "--name",
            "b",
            "--join-timeout",
            "8",
        ],
    )
}

#[test]
fn a_fake_agent_host_of_another_ca_or_expired_is_refused_by_the_sensor_host_by_name() {
    let _serial = serial();
    let Some(h) = hosts("fa", 1) else { return };
    let dir = scratch("fa");
    certs_init(&dir.join("keys"), &["b"]);
    certs_init(&dir.join("other"), &["b"]);
    bundles(&dir.join("expired"), (-20, -10), (-1, 10));
    for (keys, needle) in [
        ("other", "issued by another CA"),
        ("expired", "expired on "),
    ] {
        let listener = fake_agent_host(&h, &dir.join(keys), "agent-host");
        let bundle = if keys == "expired" {
            "expired/b"
        } else {
            "keys/b"
        };
        let (code, _, err) = sensor_host(&h, &dir, bundle).finish();
        assert_eq!(code, Some(1), "{keys}: {err}");
        assert!(
            err.contains("refused the agent host at 10.77.1.1:7447") && err.contains(needle),
            "{keys}: the sensor host does not name {needle:?}: {err}"
        );
        drop(listener);
    }
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The agent host (`etp run --listen`) names the sensor-host certificate
/// it refused (expired on DATE) in its join error, and the sensor host gets
/// a hint; with another CA the sensor host names it (it sees the agent
/// host's certificate first) and the agent host gets the hint.
#[test]
fn the_agent_host_names_a_refused_sensor_host_certificate_and_the_sensor_host_gets_a_hint() {
    let _serial = serial();
    let Some(h) = hosts("an", 1) else { return };
    let dir = scratch("an");
    certs_init(&dir.join("keys"), &["b"]);
    certs_init(&dir.join("other"), &["b"]);
    bundles(&dir.join("stale"), (-1, 10), (-20, -10));
    for (agent_keys, b_keys, agent_says, sensor_says) in [
        // The sensor host sees the agent host's certificate first and ends
        // the handshake before sending its own: the agent host can only say
        // that its certificate was refused.
        (
            "keys",
            "other/b",
            "it refused this host's certificate",
            "issued by another CA",
        ),
        (
            "stale",
            "stale/b",
            "expired on ",
            "refused this host's certificate",
        ),
    ] {
        let run = h.spawn_out(
            &h.agent,
            &dir,
            &[
                "run",
                "--scenario",
                "open-2d",
                "--delta",
                "1.0518",
                "--episodes",
                "5",
                "--seed",
                "2",
                "--listen",
                "tls/0.0.0.0:7447",
                "--tls",
                &format!("{NS_OUT}/{agent_keys}"),
                "--remote",
                "s1",
                "--join-timeout",
                "10",
            ],
        );
        let (code, _, err) = sensor_host(&h, &dir, b_keys).finish();
        assert_eq!(code, Some(1), "{b_keys}: {err}");
        assert!(
            err.contains(sensor_says),
            "sensor host with {b_keys}: {err}"
        );
        let (code, _, err) = run.finish();
        assert_ne!(code, Some(0), "{agent_keys}: {err}");
        assert!(
            err.contains("refused TLS connections: from 10.77.1.2:") && err.contains(agent_says),
            "agent host with {agent_keys}: {err}"
        );
    }
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `etp certs init` writes one bundle per host; a sensor host given the
/// whole folder (holding the agent host's private key) refuses to start,
/// naming that key; given its own bundle it gets as far as connecting.
#[test]
fn a_sensor_host_refuses_a_folder_with_another_hosts_private_key() {
    let dir = scratch("bundle");
    let keys = dir.join("keys");
    certs_init(&keys, &["b", "c"]);
    for (host, files) in [
        (
            "agent-host",
            vec!["ca.pem", "agent-host.pem", "agent-host.key", "hosts.json"],
        ),
        ("b", vec!["ca.pem", "b.key", "b.pem"]),
        ("c", vec!["ca.pem", "c.key", "c.pem"]),
    ] {
        let mut have: Vec<String> = std::fs::read_dir(keys.join(host))
            .expect(host)
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        have.sort();
        let mut want: Vec<String> = files.iter().map(|s| s.to_string()).collect();
        want.sort();
        assert_eq!(have, want, "bundle {host}");
    }
    let sensor_host = |tls: &Path| {
        Command::new(bin_dir().join("etp"))
            .args(["sensor-host", "--connect", "tls/127.0.0.1:9", "--tls"])
            .arg(tls)
            .args(["--name", "b", "--join-timeout", "1"])
            .output()
            .expect("etp sensor-host")
    };
    let out = sensor_host(&keys);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        (err.contains("agent-host.key") || err.contains("c.key"))
            && err.contains("private key of another host"),
        "{err}"
    );
    let out = sensor_host(&keys.join("b"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("private key of another host"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A flood of junk connections to the agent host's TLS port (10 threads,
/// a bogus 12-byte TLS record each, then closed; no certificate) does not keep the real sensor host out
/// (issue 41, item 1): upstream slept 100 ms after every failed handshake
/// in one accept loop, so the sensor host never joined within 60 s. On
/// loopback, the flood going on for the whole run, the sensor host (started
/// once the flood is under way) joins, the run is exact, and the refused
/// connections reach the report (`link.handshakes_refused`).
#[test]
fn a_flood_of_junk_connections_does_not_keep_the_sensor_host_out() {
    use std::io::Write;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    let _serial = serial();
    let dir = scratch("flood");
    let keys = dir.join("keys");
    certs_init(&keys, &["b"]);
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port();
    let endpoint = format!("tls/127.0.0.1:{port}");
    let etp = bin_dir().join("etp");
    let mut run = Command::new(&etp)
        .args([
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "1.0518",
            "--episodes",
            "20",
        ])
        .args(["--seed", "2", "--listen", &endpoint, "--tls"])
        .arg(&keys)
        .args(["--remote", "s1", "--join-timeout", "30", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("etp run");
    let stop = Arc::new(AtomicBool::new(false));
    let sent = Arc::new(AtomicU64::new(0));
    let flood: Vec<_> = (0..10)
        .map(|_| {
            let (stop, sent) = (stop.clone(), sent.clone());
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    let to = std::net::SocketAddr::from(([127, 0, 0, 1], port));
                    match std::net::TcpStream::connect_timeout(
                        &to,
                        std::time::Duration::from_secs(1),
                    ) {
                        Ok(mut s) => {
                            let _ = s.write_all(b"\x16\x03\x01\xff\xffgarbage");
                            sent.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(_) => std::thread::sleep(std::time::Duration::from_millis(10)),
                    }
                }
            })
        })
        .collect();
    // The sensor host starts once the flood is under way.
    while sent.load(Ordering::Relaxed) < 200 {
        assert!(
            run.try_wait().ok().flatten().is_none(),
            "etp run ended before the flood got going"
        );
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let sensor = Command::new(&etp)
        .args(["sensor-host", "--connect", &endpoint, "--tls"])
        .arg(keys.join("b"))
        .args(["--name", "b", "--join-timeout", "30"])
        .output()
        .expect("etp sensor-host");
    let out = run.wait_with_output().expect("etp run");
    stop.store(true, Ordering::Relaxed);
    for t in flood {
        let _ = t.join();
    }
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        sensor.status.success(),
        "sensor host: {}",
        String::from_utf8_lossy(&sensor.stderr)
    );
    assert!(out.status.success(), "etp run: {err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("report");
    assert_eq!(v["episodes"], 20, "{v}");
    assert_eq!(v["degraded"], 0, "{v}");
    assert_eq!(v["link"]["refused"], serde_json::json!({}), "{v}");
    let refused: u64 = v["link"]["handshakes_refused"]
        .as_object()
        .map(|m| m.values().filter_map(serde_json::Value::as_u64).sum())
        .unwrap_or(0);
    assert!(
        refused >= 1,
        "the junk connections are not in the report: {v}"
    );
    eprintln!(
        "flood: {} junk connections; {refused} refused at the handshake",
        sent.load(Ordering::Relaxed)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
