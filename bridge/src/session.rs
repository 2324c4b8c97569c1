//! The Zenoh side shared by both ends: the session's configuration (scouting
//! off: only the endpoints given are ever contacted), the key expressions of
//! a run, and the run description a sensor host fetches when it joins.

use crate::BridgeError;
pub use etp_runtime::report::SessionInfo;
use etp_runtime::link_keys;
use etp_runtime::wire::ServiceId;
use std::time::Duration;

/// Key of the agent host's queryable answering [`SessionInfo`] (the joiner
/// does not know the run id yet).
pub const SESSION_KEY: &str = "etp/session";

/// Which way a service crosses: `down` = agent host → sensor host.
pub fn data_key(run: &str, s: ServiceId, down: bool) -> String {
    format!(
        "etp/{run}/{}/{}",
        if down { "down" } else { "up" },
        s.topic()
    )
}

/// Every data key of one direction.
pub fn data_keys(run: &str, down: bool) -> String {
    format!("etp/{run}/{}/**", if down { "down" } else { "up" })
}

/// The topic of a data key (`etp/<run>/<dir>/<topic>`).
pub fn topic_of_key(key: &str) -> Option<&str> {
    let rest = key.strip_prefix("etp/")?;
    let (_, rest) = rest.split_once('/')?;
    let (_, topic) = rest.split_once('/')?;
    Some(topic)
}

/// Liveliness token of a remote sensor, declared by its host once the
/// sensor process said hello.
pub fn sensor_alive_key(run: &str, index: usize) -> String {
    format!("etp/{run}/alive/sensor/{index}")
}

/// Liveliness token of the agent host.
pub fn agent_host_alive_key(run: &str) -> String {
    format!("etp/{run}/alive/agent-host")
}

/// Link lease: a silent link is declared dead after this long (keep-alives
/// every third of it), so a cut cable or a dead host is seen within it.
pub const DEFAULT_LEASE: Duration = Duration::from_millis(300);

/// How a link is protected: mutual TLS with the key folder's certificates
/// (the default), or nothing (`--insecure`, for isolated test networks).
#[derive(Debug, Clone, clap::Args)]
pub struct LinkArgs {
    /// Key folder of `etp certs init DIR`: the link is TLS with both ends
    /// authenticated by the folder's CA (endpoints `tls/ADDR:PORT`).
    #[arg(long, value_name = "DIR", conflicts_with = "insecure")]
    pub tls: Option<std::path::PathBuf>,
    /// This host's name in the key folder (a sensor host's `--sensor-host`
    /// of `etp certs init`).
    #[arg(long, value_name = "NAME", requires = "tls")]
    pub name: Option<String>,
    /// Plain TCP: no authentication, no encryption (isolated test networks only).
    #[arg(long)]
    pub insecure: bool,
}

/// Which end of the link: the agent host listens (TLS server), a sensor
/// host connects (TLS client).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    AgentHost,
    SensorHost,
}

impl LinkArgs {
    /// Check the endpoint against the protection asked for, and the key
    /// folder's files of this end (`etp_runtime::link_keys::resolve`).
    pub fn resolve(
        &self,
        endpoint: &str,
        end: End,
    ) -> Result<Option<link_keys::Identity>, BridgeError> {
        let name = match end {
            End::AgentHost => link_keys::AGENT_HOST,
            End::SensorHost => self
                .name
                .as_deref()
                .unwrap_or(link_keys::DEFAULT_SENSOR_HOST),
        };
        link_keys::resolve(endpoint, self.tls.as_deref(), name, self.insecure)
            .map_err(|e| BridgeError::Input(e.to_string()))
    }
}

/// The Zenoh configuration of one end: peer mode, no multicast or gossip
/// scouting, only the given endpoints, a short link lease and fast connect
/// retries; with an identity, TLS with mutual authentication (the listener
/// demands a client certificate chaining to the folder's CA; the connecting
/// end checks the listener's against the same CA).
pub fn config(
    listen: Option<&str>,
    connect: Option<&str>,
    lease: Duration,
    identity: Option<&link_keys::Identity>,
) -> Result<zenoh::Config, BridgeError> {
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: String| {
        c.insert_json5(k, &v)
            .map_err(|e| BridgeError::Zenoh(format!("config {k} = {v}: {e}")))
    };
    if let Some(id) = identity {
        let path = |p: &std::path::Path| {
            serde_json::to_string(&p.display().to_string()).unwrap_or_else(|_| "\"\"".into())
        };
        set(&mut c, "transport/link/tls/root_ca_certificate", path(&id.ca))?;
        if listen.is_some() {
            set(&mut c, "transport/link/tls/listen_certificate", path(&id.certificate))?;
            set(&mut c, "transport/link/tls/listen_private_key", path(&id.private_key))?;
            set(&mut c, "transport/link/tls/enable_mtls", "true".into())?;
        }
        if connect.is_some() {
            set(&mut c, "transport/link/tls/connect_certificate", path(&id.certificate))?;
            set(&mut c, "transport/link/tls/connect_private_key", path(&id.private_key))?;
            // Hosts are reached by address; the CA and the certificates' key
            // usage (server for the agent host only) authenticate the ends.
            set(&mut c, "transport/link/tls/verify_name_on_connect", "false".into())?;
            set(&mut c, "transport/link/tls/enable_mtls", "true".into())?;
        }
    }
    set(&mut c, "mode", "\"peer\"".into())?;
    set(&mut c, "scouting/multicast/enabled", "false".into())?;
    set(&mut c, "scouting/gossip/enabled", "false".into())?;
    let endpoints = |e: Option<&str>| {
        serde_json::to_string(&e.map(|x| vec![x.to_string()]).unwrap_or_default())
            .unwrap_or_else(|_| "[]".into())
    };
    set(&mut c, "listen/endpoints", endpoints(listen))?;
    set(&mut c, "connect/endpoints", endpoints(connect))?;
    set(
        &mut c,
        "connect/retry",
        "{period_init_ms: 100, period_max_ms: 500, period_increase_factor: 2}".into(),
    )?;
    set(
        &mut c,
        "transport/link/tx/lease",
        lease.as_millis().to_string(),
    )?;
    set(&mut c, "transport/link/tx/keep_alive", "3".into())?;
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_the_run_direction_and_topic() {
        let k = data_key("r1", ServiceId::Truth(3), true);
        assert_eq!(k, "etp/r1/down/sensor/3/truth");
        assert_eq!(topic_of_key(&k), Some("sensor/3/truth"));
        assert_eq!(topic_of_key("etp/r1/up/measurement"), Some("measurement"));
        assert_eq!(topic_of_key("nope"), None);
    }

    #[test]
    fn the_configuration_turns_scouting_off_and_names_the_endpoints() {
        let c = config(Some("tcp/127.0.0.1:7447"), None, DEFAULT_LEASE, None).expect("config");
        let text = format!("{c}");
        assert!(text.contains("tcp/127.0.0.1:7447"), "{text}");
        assert!(text.contains("\"lease\":300"), "{text}");
    }
}
