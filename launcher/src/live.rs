//! `etp run --live [ADDR:PORT]`: the run served to Foxglove while it runs
//! (`etp-live`). The view is started before any process of the run, so a
//! refused address or a port in use fails the command before anything ran;
//! the agent feeds it through a socket in the run's folder without ever
//! waiting for it (`etp_runtime::live`), so the run's outputs are those of a
//! run without `--live`.

use super::Args;
use anyhow::{Result, bail};
use etp_live::LiveView;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The feed socket's name in the run's folder.
const FEED: &str = "live.sock";

/// `--live` refused before any work when its address is not loopback and
/// `--insecure` was not given.
pub fn check(a: &Args) -> Result<()> {
    if let Some(addr) = a.live {
        etp_live::check_address(addr, a.link.insecure)?;
    } else if a.live_wait {
        bail!("--live-wait needs --live");
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
pub fn start(a: &Args, plan: &super::prepare::Plan, dir: &Path) -> Result<Option<Live>> {
    let Some(addr) = a.live else {
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
    if a.live_wait {
        eprintln!("etp: --live-wait: the episodes start once a Foxglove client subscribes");
        if !view.wait_for_subscriber(Duration::from_secs_f64(a.deadline())) {
            bail!(
                "--live-wait: no Foxglove client subscribed at {addr} within --deadline ({} s)",
                a.deadline()
            );
        }
    }
    Ok(Some(Live { view, feed }))
}
