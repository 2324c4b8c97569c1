//! `etp run --live [ADDR:PORT]`: the run served to Foxglove while it runs
//! (`etp-live`). The view is started before any process of the run, so a
//! refused address or a port in use fails the command before anything ran;
//! the agent feeds it through a socket in the run's folder without ever
//! waiting for it (`etp_runtime::live`), so the run's outputs are those of a
//! run without `--live`.

use super::RunRequest;
use super::interrupts::Interrupts;
use crate::error::{Error, Result};
use etp_live::LiveView;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The feed socket's name in the run's folder.
const FEED: &str = "live.sock";

/// `--live ADDR:PORT`: an IP address, or a host name resolved here
/// (`localhost` is the IPv4 loopback, as the default `127.0.0.1` is; of a
/// name with several addresses the first IPv4 one). The error clap prints
/// after the option's name.
pub fn parse_addr(s: &str) -> std::result::Result<std::net::SocketAddr, String> {
    use std::net::{SocketAddr, ToSocketAddrs};
    if let Ok(a) = s.parse::<SocketAddr>() {
        return Ok(a);
    }
    let (host, port) = s
        .rsplit_once(':')
        .ok_or_else(|| format!("`{s}` is not ADDR:PORT (e.g. localhost:8765)"))?;
    let port: u16 = port
        .parse()
        .map_err(|_| format!("`{port}` is not a port number (0..=65535)"))?;
    if host.eq_ignore_ascii_case("localhost") {
        return Ok(SocketAddr::from((std::net::Ipv4Addr::LOCALHOST, port)));
    }
    let all: Vec<SocketAddr> = (host, port)
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve `{host}`: {e}"))?
        .collect();
    all.iter()
        .find(|a| a.is_ipv4())
        .or(all.first())
        .copied()
        .ok_or_else(|| format!("`{host}` resolves to no address"))
}

/// A run file's `live` key, read as `--live` is ([`parse_addr`]).
pub fn deserialize_addr<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<Option<std::net::SocketAddr>, D::Error> {
    let text = <String as serde::Deserialize>::deserialize(d)?;
    parse_addr(&text)
        .map(Some)
        .map_err(serde::de::Error::custom)
}

/// `--live` refused before any work when its address is not loopback and
/// `--insecure` was not given.
pub fn check(a: &RunRequest) -> Result<()> {
    if let Some(live) = a.live {
        etp_live::check_address(live.addr, a.link.insecure)?;
    }
    Ok(())
}

/// The view of a run, started (bound) if `--live` was given.
pub struct Live {
    pub view: LiveView,
    pub feed: PathBuf,
}

/// Start the view: listen on `--live`'s address and on the feed socket in
/// `dir`; the errors name `--live` and the address.
pub fn start(a: &RunRequest, plan: &super::prepare::Plan, dir: &Path) -> Result<Option<Live>> {
    let Some(addr) = a.live.map(|l| l.addr) else {
        return Ok(None);
    };
    let feed = dir.join(FEED);
    let view = LiveView::start(
        addr,
        &plan.scenario,
        plan.sensor_energy_per_episode.clone(),
        &feed,
    )?;
    if !addr.ip().is_loopback() {
        eprintln!(
            "etp: warning: --insecure: the live view at {addr} is plain WebSocket, neither \
             authenticated nor encrypted"
        );
    }
    eprintln!(
        "etp: live view: Foxglove WebSocket at ws://{}:{} (Foxglove: Open connection → \
         Foxglove WebSocket; layout docs/foxglove-live-layout.json)",
        addr.ip(),
        view.port()
    );
    Ok(Some(Live { view, feed }))
}

/// `--live-wait`: hold the run until a Foxglove client subscribes. Ctrl-C or
/// SIGTERM while waiting ends the command with exit 130 before any process
/// started, and the caller cleans up as for any other refusal (the run's
/// folder is removed, no recording is claimed on disk).
pub fn wait(
    a: &RunRequest,
    live: &Live,
    rt: &tokio::runtime::Runtime,
    interrupts: &mut Interrupts,
) -> Result<()> {
    let Some(view) = a.live.filter(|l| l.wait_for_client) else {
        return Ok(());
    };
    let deadline = Instant::now() + Duration::from_secs_f64(a.deadline);
    rt.block_on(async {
        eprintln!("etp: --live-wait: the episodes start once a Foxglove client subscribes");
        loop {
            if live.view.wait_for_subscriber(Duration::ZERO) {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return Err(Error::NoLiveClient {
                    ip: view.addr.ip(),
                    port: live.view.port(),
                    deadline: a.deadline,
                });
            }
            let name = tokio::select! {
                name = interrupts.next() => name,
                () = tokio::time::sleep(Duration::from_millis(50)) => continue,
            };
            return Err(super::interrupts::before_any_episode(
                name,
                "during --live-wait",
            ));
        }
    })
}
