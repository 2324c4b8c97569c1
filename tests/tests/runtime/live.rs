//! `etp run --live`: a real WebSocket client (tungstenite, subprotocol
//! `foxglove.sdk.v1`: what the Foxglove SDK 0.30 server negotiates — it
//! answers a client offering only the older name `foxglove.websocket.v1`
//! with HTTP 400) connects to the run's Foxglove server, checks
//! the advertised channels (topics and schemas), subscribes to all of them
//! and receives the scene and per-step messages during the run; the run's
//! exit code and counts are those of the same run without `--live`.
//!
//! Robust on a loaded machine without timing assertions: `--live-wait`
//! holds the episodes until the client has subscribed (it changes when the
//! run starts, not what it computes: the comparison with the plain run
//! checks that), the agent's first slot frame is always sent, and the
//! server takes port 0 (a free port, read from stderr).

use super::{DELTA, serial};
use etp_tests::{EtpRun, no_leftovers, processes_of_run, unique_run_id};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::time::Duration;
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

const SUBPROTOCOL: &str = "foxglove.sdk.v1";

/// The run's arguments, shared by the live and the plain run.
fn args(episodes: &str) -> Vec<&str> {
    vec![
        "--scenario",
        "winding-2d",
        "--delta",
        DELTA,
        "--episodes",
        episodes,
        "--seed",
        "5",
        "--episode-details",
    ]
}

/// Read the run's stderr on a thread until its end (the thread's result);
/// wait (at most 120 s, a guard) for the first line containing `marker` and
/// return it.
fn watch_stderr(
    run: &mut EtpRun,
    marker: &'static str,
) -> (String, std::thread::JoinHandle<String>) {
    let stderr = run
        .child
        .as_mut()
        .and_then(|c| c.stderr.take())
        .expect("stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if line.contains(marker) {
                let _ = tx.send(line.clone());
            }
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let line = rx
        .recv_timeout(Duration::from_secs(120))
        .unwrap_or_else(|_| panic!("etp run printed no line with {marker:?}"));
    (line, reader)
}

/// What the client saw: channels by id (topic, schema name, encoding),
/// and the messages received per topic.
#[derive(Default)]
struct Seen {
    channels: BTreeMap<u64, (String, String, String)>,
    messages: BTreeMap<String, Vec<Vec<u8>>>,
}

fn connect(port: u16) -> WebSocket<TcpStream> {
    let stream = TcpStream::connect(("127.0.0.1", port)).expect("connecting to the live view");
    // A guard, not a timing assertion: the server closes when the run ends.
    stream
        .set_read_timeout(Some(Duration::from_secs(120)))
        .expect("read timeout");
    let mut req = format!("ws://127.0.0.1:{port}")
        .into_client_request()
        .expect("request");
    req.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        SUBPROTOCOL.parse().expect("header value"),
    );
    let (ws, resp) = tungstenite::client::client(req, stream).expect("WebSocket handshake");
    assert_eq!(
        resp.headers()
            .get("sec-websocket-protocol")
            .and_then(|v| v.to_str().ok()),
        Some(SUBPROTOCOL)
    );
    ws
}

/// Read until every expected channel is advertised, subscribe to all, then
/// read until the server closes (the end of the run).
fn watch(mut ws: WebSocket<TcpStream>, expected_channels: usize) -> Seen {
    let mut seen = Seen::default();
    let mut subscribed = false;
    loop {
        let msg = match ws.read() {
            Ok(m) => m,
            // The run ended: the server went away.
            Err(_) => break,
        };
        match msg {
            Message::Text(t) => {
                let v: Value = serde_json::from_str(t.as_str()).expect("JSON control message");
                if v["op"] == "advertise" {
                    for c in v["channels"].as_array().expect("channels") {
                        seen.channels.insert(
                            c["id"].as_u64().expect("id"),
                            (
                                c["topic"].as_str().expect("topic").to_string(),
                                c["schemaName"].as_str().unwrap_or("").to_string(),
                                c["encoding"].as_str().unwrap_or("").to_string(),
                            ),
                        );
                    }
                }
                if !subscribed && seen.channels.len() >= expected_channels {
                    // Subscription id = channel id.
                    let subs: Vec<Value> = seen
                        .channels
                        .keys()
                        .map(|id| json!({"id": id, "channelId": id}))
                        .collect();
                    let s = json!({"op": "subscribe", "subscriptions": subs}).to_string();
                    ws.send(Message::text(s)).expect("subscribing");
                    subscribed = true;
                }
            }
            // Message data: opcode 1, subscription id (u32 LE), log time
            // (u64 LE), payload.
            Message::Binary(b) if b.first() == Some(&1) && b.len() >= 13 => {
                let mut id = [0u8; 4];
                id.copy_from_slice(&b[1..5]);
                let id = u64::from(u32::from_le_bytes(id));
                let topic = seen.channels.get(&id).map_or("?", |c| c.0.as_str());
                seen.messages
                    .entry(topic.to_string())
                    .or_default()
                    .push(b[13..].to_vec());
            }
            Message::Close(_) => break,
            _ => {}
        }
    }
    seen
}

fn json_of(seen: &Seen, topic: &str) -> Vec<Value> {
    seen.messages
        .get(topic)
        .map(|v| {
            v.iter()
                .map(|b| serde_json::from_slice(b).expect("a JSON message"))
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn a_foxglove_client_sees_the_scene_and_the_steps_and_the_run_is_unchanged() {
    let _serial = serial();
    let id = unique_run_id("live");
    // s2's link turns lossy at episode 5 (the run's model is the ideal
    // link): the monitor flags it, and the view shows the flag.
    let schedule = std::env::temp_dir().join(format!("{id}-schedule.toml"));
    std::fs::write(
        &schedule,
        "[[change]]\nsensor = \"s2\"\nepisode = 5\nloss = 0.3\n",
    )
    .expect("schedule file");
    let schedule_arg = schedule.display().to_string();
    let mut live_args = args("30");
    live_args.extend(["--channel-schedule", &schedule_arg]);
    live_args.extend(["--live", "127.0.0.1:0", "--live-wait"]);
    let mut run = EtpRun::spawn(&id, &live_args);
    // The port, from the line `etp: live view: … ws://127.0.0.1:PORT …`.
    let (line, reader) = watch_stderr(&mut run, "ws://127.0.0.1:");
    let port = line
        .split("ws://127.0.0.1:")
        .nth(1)
        .map(|rest| {
            rest.chars()
                .take_while(char::is_ascii_digit)
                .collect::<String>()
        })
        .and_then(|p| p.parse::<u16>().ok())
        .expect("etp run printed the live view's address");
    let sensors = 7;
    let expected: Vec<(String, &str)> = [
        ("/scene", "foxglove.SceneUpdate"),
        ("/agent", "foxglove.SceneUpdate"),
        ("/outcome", "foxglove.Log"),
        ("/status", "etp.live.Status"),
        ("/outcomes", "etp.live.Outcomes"),
        ("/energy", "etp.live.Energy"),
        ("/rates", "etp.live.Rates"),
        ("/drift", "etp.live.Drift"),
    ]
    .into_iter()
    .map(|(t, s)| (t.to_string(), s))
    .chain((0..sensors).map(|i| (format!("/sensor/s{i}"), "etp.live.Sensor")))
    .collect();
    let seen = watch(connect(port), expected.len());
    let (code, out, _) = run.finish_code();
    let err = reader.join().expect("stderr reader");
    assert_eq!(code, Some(0), "etp run --live failed: {err}");

    // The advertised channels: topics, schemas, encodings.
    let advertised: BTreeMap<&str, (&str, &str)> = seen
        .channels
        .values()
        .map(|(t, s, e)| (t.as_str(), (s.as_str(), e.as_str())))
        .collect();
    assert_eq!(advertised.len(), expected.len(), "{advertised:?}");
    for (topic, schema) in &expected {
        let (s, e) = advertised
            .get(topic.as_str())
            .unwrap_or_else(|| panic!("{topic} not advertised: {advertised:?}"));
        assert_eq!(s, schema, "{topic}");
        let encoding = if schema.starts_with("foxglove.") {
            "protobuf"
        } else {
            "json"
        };
        assert_eq!(*e, encoding, "{topic}");
    }

    // The scene (sent when the client subscribed) and per-step messages.
    let count = |t: &str| seen.messages.get(t).map_or(0, Vec::len);
    let counts: BTreeMap<&str, usize> = seen
        .messages
        .iter()
        .map(|(t, m)| (t.as_str(), m.len()))
        .collect();
    eprintln!("live view: messages received per topic: {counts:?}");
    assert!(count("/scene") >= 1, "no scene: {:?}", seen.messages.keys());
    assert!(count("/agent") >= 1, "no /agent frame");
    let status = json_of(&seen, "/status");
    assert!(!status.is_empty(), "no /status frame");
    for s in &status {
        assert!(s["episode"].as_u64().is_some_and(|e| e < 30), "{s}");
        assert!(
            s["sensor"].as_str().is_some_and(|n| n.starts_with('s')),
            "{s}"
        );
        assert_eq!(s["delta"].as_f64(), DELTA.parse().ok(), "{s}");
    }
    // The numbers only grow, and never exceed the run's.
    let energy = json_of(&seen, "/energy");
    assert!(!energy.is_empty(), "no /energy message");
    let e: Vec<f64> = energy
        .iter()
        .map(|v| v["energy"].as_f64().expect("energy"))
        .collect();
    assert!(e.windows(2).all(|w| w[0] <= w[1]), "{e:?}");

    // The run is the one without a view.
    let v: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("JSON ({e}): {out}"));
    let plain_id = unique_run_id("live-plain");
    let mut plain_args = args("30");
    plain_args.extend(["--channel-schedule", &schedule_arg]);
    let (plain_code, plain_out, plain_err) = EtpRun::spawn(&plain_id, &plain_args).finish_code();
    let _ = std::fs::remove_file(&schedule);
    assert_eq!(plain_code, Some(0), "{plain_err}");
    let p: Value = serde_json::from_str(&plain_out).expect("JSON");
    for k in [
        "episodes",
        "steps",
        "transmissions",
        "received",
        "p_target",
        "p_collision",
        "energy_mean",
        "sensors",
        "episode_results",
        "drift",
    ] {
        assert_eq!(v[k], p[k], "`{k}` differs with --live");
    }
    // The monitor's flags: on /drift once each, in the run's order, as
    // `drift[]` says them (every frame after a flag carries it, so only a
    // flag of the last moments can miss the view), and a warning line each.
    let run_flags = v["drift"].as_array().expect("drift[]");
    assert!(
        run_flags
            .iter()
            .any(|f| f["sensor"] == "s2" && f["quantity"] == "loss"),
        "s2's loss was not flagged: {run_flags:?}"
    );
    let view_flags = json_of(&seen, "/drift");
    assert!(!view_flags.is_empty(), "no /drift message");
    assert_eq!(
        view_flags[..],
        run_flags[..view_flags.len().min(run_flags.len())],
        "the view's flags are not the run's"
    );
    assert_eq!(view_flags.len().min(run_flags.len()), view_flags.len());
    let warnings = seen.messages.get("/outcome").map_or(0, |m| {
        m.iter()
            .filter(|b| String::from_utf8_lossy(b).contains("channel drift: s2 loss"))
            .count()
    });
    assert_eq!(
        warnings, 1,
        "one warning line for s2's loss flag on /outcome"
    );
    // What the view counted agrees with the report where it saw the end.
    let outcomes = json_of(&seen, "/outcomes");
    if let Some(last) = outcomes.last() {
        assert!(
            last["episodes"].as_u64() <= v["episodes"].as_u64(),
            "{last}"
        );
    }
    if let Some(max) = e.last() {
        let total: f64 = v["sensors"]
            .as_array()
            .expect("sensors")
            .iter()
            .map(|s| s["transmissions"].as_f64().expect("transmissions"))
            .sum();
        assert!(*max <= total, "the view's energy {max} > the run's {total}");
    }
    for run in [&id, &plain_id] {
        assert!(processes_of_run(run).is_empty());
        no_leftovers(run).expect("clean /dev/shm and root folder");
    }
}

#[test]
fn live_refuses_a_public_address_without_insecure_and_a_port_in_use() {
    let _serial = serial();
    let id = unique_run_id("live-refused");
    let mut a = args("2");
    a.extend(["--live", "0.0.0.0:0"]);
    let (code, out, err) = EtpRun::spawn(&id, &a).finish_code();
    assert_eq!(code, Some(1), "{out}");
    assert!(
        err.contains("--live 0.0.0.0:0") && err.contains("--insecure"),
        "{err}"
    );
    let busy = std::net::TcpListener::bind("127.0.0.1:0").expect("a port");
    let port = busy.local_addr().expect("address").port();
    let addr = format!("127.0.0.1:{port}");
    let id = unique_run_id("live-busy");
    let mut a = args("2");
    a.extend(["--live", &addr]);
    let (code, out, err) = EtpRun::spawn(&id, &a).finish_code();
    assert_eq!(code, Some(1), "{out}");
    assert!(err.contains(&format!("--live {addr}")), "{err}");
    assert!(out.is_empty(), "no report: {out}");
    assert!(processes_of_run(&id).is_empty());
}

/// Ctrl-C while `--live-wait` waits for a client: exit 130, nothing ran, no
/// report, nothing of the run left (its folder, its iceoryx2 files).
#[test]
fn ctrl_c_during_live_wait_ends_the_command_cleanly() {
    let _serial = serial();
    let id = unique_run_id("live-wait-int");
    let mut a = args("2");
    a.extend(["--live", "127.0.0.1:0", "--live-wait"]);
    let mut run = EtpRun::spawn(&id, &a);
    let (_, reader) = watch_stderr(&mut run, "--live-wait: the episodes start");
    let pid = run.pid().to_string();
    let sent = std::process::Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .expect("kill");
    assert!(sent.success());
    let (code, out, _) = run.finish_code();
    let err = reader.join().expect("stderr reader");
    assert_eq!(code, Some(130), "{err}");
    assert!(
        err.contains("interrupted (SIGINT) during --live-wait"),
        "{err}"
    );
    assert!(out.is_empty(), "no report: {out}");
    assert!(processes_of_run(&id).is_empty());
    no_leftovers(&id).expect("nothing of the run left");
}
