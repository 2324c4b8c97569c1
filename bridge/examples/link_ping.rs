//! The round trip of the bridge's link alone, with the bridge's Zenoh
//! configuration (`session::config`: the same TLS, lease and congestion
//! control): what bounds a remote run's steps per second, since each step
//! of a run with remote sensors waits for one round trip over the link
//! (docs/performance.md, "Runs across hosts").
//!
//! ```text
//! link_ping pong ENDPOINT [KEYS] 0 [relay]  # the listening end: echoes each ping
//! link_ping ping ENDPOINT [KEYS] N [relay] # connects, N round trips, prints µs
//! ```
//!
//! With a `tls/` endpoint, `KEYS` is this end's bundle of
//! `etp certs init DIR --sensor-host b` (`DIR/agent-host` for the pong end,
//! `DIR/b` for the ping end); a `tcp/` endpoint takes none (plain TCP). `relay`: the pong end hands each ping to a thread that
//! puts the pong (as the bridge hands a sample from Zenoh's callback to the
//! thread that owns the iceoryx2 ports), one more thread hand-off each way.

use etp_bridge::session::config;
use etp_runtime::link_keys;
use std::time::{Duration, Instant};
use zenoh::Wait;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let role = args.first().map(String::as_str).unwrap_or("");
    let endpoint = args
        .get(1)
        .ok_or_else(|| anyhow::anyhow!("usage: link_ping ping|pong ENDPOINT [KEYS] [N] [relay]"))?;
    let tls = endpoint.starts_with("tls/");
    let rest = &args[2.min(args.len())..];
    let (keys, rest) = if tls {
        (
            rest.first().map(std::path::PathBuf::from),
            &rest[1.min(rest.len())..],
        )
    } else {
        (None, rest)
    };
    let n: usize = rest.first().and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let relay = rest.iter().any(|s| s == "relay");
    let name = if role == "pong" {
        link_keys::AGENT_HOST
    } else {
        "b"
    };
    let identity = link_keys::resolve(endpoint, keys.as_deref(), name, !tls)?;
    let (listen, connect) = if role == "pong" {
        (Some(endpoint.as_str()), None)
    } else {
        (None, Some(endpoint.as_str()))
    };
    let session = zenoh::open(config(
        listen,
        connect,
        Duration::from_millis(300),
        identity.as_ref(),
        None,
    )?)
    .wait()
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let publisher = |key: &'static str| {
        session
            .declare_publisher(key)
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .express(true)
            .wait()
            .map_err(|e| anyhow::anyhow!("{e}"))
    };
    if role == "pong" {
        let pong = publisher("etp/ping/pong")?;
        let (tx, rx) = std::sync::mpsc::channel::<Vec<u8>>();
        let _sub = if relay {
            let s = session
                .declare_subscriber("etp/ping/ping")
                .callback(move |s| {
                    let _ = tx.send(s.payload().to_bytes().into_owned());
                })
                .wait()
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            while let Ok(b) = rx.recv() {
                pong.put(b).wait().map_err(|e| anyhow::anyhow!("{e}"))?;
            }
            s
        } else {
            let s = session
                .declare_subscriber("etp/ping/ping")
                .callback(move |s| {
                    let _ = pong.put(s.payload().clone()).wait();
                })
                .wait()
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            std::thread::sleep(Duration::from_secs(3600));
            s
        };
        drop(_sub);
        return Ok(());
    }
    let ping = publisher("etp/ping/ping")?;
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    let _sub = session
        .declare_subscriber("etp/ping/pong")
        .callback(move |_| {
            let _ = tx.send(());
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // Until the pong end answers.
    loop {
        ping.put(vec![0u8; 64])
            .wait()
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        if rx.recv_timeout(Duration::from_millis(200)).is_ok() {
            break;
        }
    }
    while rx.try_recv().is_ok() {}
    let mut took = Vec::with_capacity(n);
    for _ in 0..n {
        let t = Instant::now();
        ping.put(vec![0u8; 64])
            .wait()
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        rx.recv_timeout(Duration::from_secs(5))?;
        took.push(t.elapsed().as_secs_f64() * 1e6);
    }
    took.sort_by(f64::total_cmp);
    let q = |p: f64| took[((took.len() - 1) as f64 * p) as usize];
    let mean = took.iter().sum::<f64>() / took.len() as f64;
    println!(
        "{} round trips{}: median {:.0} µs, p10 {:.0}, p90 {:.0}, mean {:.0} ({:.0} round trips/s)",
        n,
        if relay { " (relay)" } else { "" },
        q(0.5),
        q(0.1),
        q(0.9),
        mean,
        1e6 / mean
    );
    Ok(())
}
