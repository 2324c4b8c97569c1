//! The Zenoh side shared by both ends: the session's configuration (scouting
//! off: only the endpoints given are ever contacted; mutual TLS unless
//! `--insecure`), the key expressions of a run, and the run description a
//! sensor host fetches when it joins.
//!
//! Keys: `etp/<run>/down/sensor/<i>/<topic>` (agent host → the host serving
//! sensor i), `etp/<run>/up/<host>/<topic>` (sensor host `<host>` → agent
//! host: the host's name is in the key, so access control can let a host
//! put on its own keys only), liveliness `etp/<run>/alive/sensor/<i>/<host>`
//! and `etp/<run>/alive/agent-host`.

use crate::BridgeError;
use etp_runtime::wire::ServiceId;
pub use etp_runtime::wire::report::SessionInfo;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Common name (and file stem) of the agent host's identity in a
/// `etp certs init` folder.
pub const AGENT_HOST: &str = "agent-host";

/// How a link is secured.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Security {
    /// Zenoh over TLS, mutual authentication: the key material of
    /// `etp certs init` in `dir`, presented as `identity` (`<identity>.pem`).
    Tls { dir: PathBuf, identity: String },
    /// Plain TCP: no authentication, no encryption, no access control
    /// (isolated test networks only).
    Insecure,
}

impl Security {
    /// `--tls DIR` or `--insecure` (exactly one).
    pub fn of_flags(
        tls: Option<&Path>,
        insecure: bool,
        identity: &str,
    ) -> Result<Self, BridgeError> {
        match (tls, insecure) {
            (Some(d), false) => Ok(Self::Tls {
                dir: d.to_path_buf(),
                identity: identity.to_string(),
            }),
            (None, true) => Ok(Self::Insecure),
            (Some(_), true) => Err(BridgeError::Input(
                "--tls and --insecure exclude each other".into(),
            )),
            (None, false) => Err(BridgeError::Input(
                "a link needs --tls DIR (key material of `etp certs init`) or, on an isolated test network, --insecure".into(),
            )),
        }
    }

    /// The endpoint's protocol must match: `tls/…` with TLS, `tcp/…` insecure.
    pub fn check_endpoint(&self, ep: &str) -> Result<(), BridgeError> {
        let want = match self {
            Self::Tls { .. } => "tls/",
            Self::Insecure => "tcp/",
        };
        if ep.starts_with(want) {
            Ok(())
        } else {
            Err(BridgeError::Input(format!(
                "endpoint `{ep}`: {} needs a `{want}ADDR:PORT` endpoint",
                if want == "tls/" {
                    "--tls"
                } else {
                    "--insecure"
                }
            )))
        }
    }
}

/// `hosts.json` of a key folder: sensor host → the sensors it may serve
/// (names; empty: any remote sensor).
pub fn read_hosts(dir: &Path) -> Result<BTreeMap<String, Vec<String>>, BridgeError> {
    let p = dir.join("hosts.json");
    let text = std::fs::read_to_string(&p)
        .map_err(|e| BridgeError::Input(format!("reading {}: {e}", p.display())))?;
    #[derive(serde::Deserialize)]
    struct Hosts {
        hosts: BTreeMap<String, Vec<String>>,
    }
    let h: Hosts = serde_json::from_str(&text)
        .map_err(|e| BridgeError::Input(format!("{}: {e}", p.display())))?;
    Ok(h.hosts)
}

/// Key of the agent host's queryable answering [`SessionInfo`] (the joiner
/// does not know the run id yet).
pub const SESSION_KEY: &str = "etp/session";

/// Which way a message crosses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Direction {
    /// Agent host → sensor host.
    Down,
    /// Sensor host `<name>` → agent host.
    Up(String),
}

/// The key a service's messages cross on.
pub fn data_key(run: &str, s: ServiceId, dir: &Direction) -> String {
    match dir {
        Direction::Down => format!("etp/{run}/down/{}", s.topic()),
        Direction::Up(host) => format!("etp/{run}/up/{host}/{}", s.topic()),
    }
}

/// Every up key of a run (all hosts).
pub fn up_keys(run: &str) -> String {
    format!("etp/{run}/up/*/**")
}

/// A data key's sending host (`None` for down keys) and topic; `None` for a
/// key that is not a data key of `run`.
pub fn parse_key<'k>(run: &str, key: &'k str) -> Option<(Option<&'k str>, &'k str)> {
    let rest = key
        .strip_prefix("etp/")?
        .strip_prefix(run)?
        .strip_prefix('/')?;
    if let Some(t) = rest.strip_prefix("down/") {
        return Some((None, t));
    }
    let (host, topic) = rest.strip_prefix("up/")?.split_once('/')?;
    Some((Some(host), topic))
}

/// Liveliness token of a remote sensor, declared by its host `host` once
/// the sensor process said hello.
pub fn sensor_alive_key(run: &str, index: usize, host: &str) -> String {
    format!("etp/{run}/alive/sensor/{index}/{host}")
}

/// (sensor, host) of a sensor's liveliness key.
pub fn parse_alive_key(key: &str) -> Option<(usize, &str)> {
    let mut parts = key.rsplitn(3, '/');
    let host = parts.next()?;
    let index = parts.next()?.parse().ok()?;
    Some((index, host))
}

/// Liveliness token of the agent host.
pub fn agent_host_alive_key(run: &str) -> String {
    format!("etp/{run}/alive/agent-host")
}

/// Link lease: a silent link is declared dead after this long (keep-alives
/// every third of it), so a cut cable or a dead host is seen within it.
pub const DEFAULT_LEASE: Duration = Duration::from_millis(300);

/// How long a put may wait on a peer that does not read before its link is
/// closed.
pub const STALL_CLOSE: Duration = Duration::from_secs(2);

/// Access control of the agent host: only the sensor hosts of `hosts`
/// (certificate common names), each putting only on its own up keys,
/// subscribing only to the down keys of the sensors it may serve (`None`:
/// every remote sensor) and declaring only its own sensors' tokens; it may
/// ask for the run and watch the agent host's token. Everything else from
/// any peer is denied.
pub fn agent_host_access(run: &str, hosts: &BTreeMap<String, Vec<usize>>) -> serde_json::Value {
    let mut rules = vec![
        serde_json::json!({"id": "join", "permission": "allow", "flows": ["ingress"],
            "messages": ["query", "declare_liveliness_subscriber", "liveliness_query"],
            "key_exprs": [SESSION_KEY, agent_host_alive_key(run)]}),
        serde_json::json!({"id": "out", "permission": "allow", "flows": ["egress"],
            "messages": ["put", "delete", "reply", "declare_subscriber", "declare_queryable",
                "liveliness_token", "declare_liveliness_subscriber", "liveliness_query", "query"],
            "key_exprs": ["etp/**"]}),
    ];
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    for (h, sensors) in hosts {
        let down: Vec<String> = sensors
            .iter()
            .map(|i| format!("etp/{run}/down/sensor/{i}/**"))
            .collect();
        let alive: Vec<String> = sensors
            .iter()
            .map(|&i| sensor_alive_key(run, i, h))
            .collect();
        let mut own = vec!["join".to_string(), "out".to_string()];
        if !sensors.is_empty() {
            rules.push(serde_json::json!({"id": format!("{h}-up"), "permission": "allow",
                "flows": ["ingress"], "messages": ["put"], "key_exprs": [format!("etp/{run}/up/{h}/**")]}));
            rules.push(
                serde_json::json!({"id": format!("{h}-down"), "permission": "allow",
                "flows": ["ingress"], "messages": ["declare_subscriber"], "key_exprs": down}),
            );
            rules.push(
                serde_json::json!({"id": format!("{h}-alive"), "permission": "allow",
                "flows": ["ingress"], "messages": ["liveliness_token"], "key_exprs": alive}),
            );
            own.extend([format!("{h}-up"), format!("{h}-down"), format!("{h}-alive")]);
        }
        subjects.push(serde_json::json!({"id": h, "cert_common_names": [h]}));
        policies.push(serde_json::json!({"rules": own, "subjects": [h]}));
    }
    serde_json::json!({"enabled": true, "default_permission": "deny",
        "rules": rules, "subjects": subjects, "policies": policies})
}

/// Access control of a sensor host: only the agent host (by its
/// certificate's common name) is heard or served.
pub fn sensor_host_access() -> serde_json::Value {
    serde_json::json!({"enabled": true, "default_permission": "deny",
        "rules": [{"id": "all", "permission": "allow", "flows": ["ingress", "egress"],
            "messages": ["put", "delete", "reply", "declare_subscriber", "declare_queryable",
                "liveliness_token", "declare_liveliness_subscriber", "liveliness_query", "query"],
            "key_exprs": ["etp/**"]}],
        "subjects": [{"id": AGENT_HOST, "cert_common_names": [AGENT_HOST]}],
        "policies": [{"rules": ["all"], "subjects": [AGENT_HOST]}]})
}

/// The Zenoh configuration of one end: peer mode, no multicast or gossip
/// scouting, only the given endpoints, a short link lease and fast connect
/// retries.
pub fn config(
    listen: Option<&str>,
    connect: Option<&str>,
    lease: Duration,
    security: &Security,
    access: Option<serde_json::Value>,
) -> Result<zenoh::Config, BridgeError> {
    for ep in listen.iter().chain(connect.iter()) {
        security.check_endpoint(ep)?;
    }
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: String| {
        c.insert_json5(k, &v)
            .map_err(|e| BridgeError::Zenoh(format!("config {k} = {v}: {e}")))
    };
    if let Security::Tls { dir, identity } = security {
        let file = |name: &str| -> Result<String, BridgeError> {
            let p = dir.join(name);
            if !p.is_file() {
                return Err(BridgeError::Input(format!(
                    "{} missing (make the key material with `etp certs init {}`)",
                    p.display(),
                    dir.display()
                )));
            }
            serde_json::to_string(&p.display().to_string())
                .map_err(|e| BridgeError::Input(e.to_string()))
        };
        let cert = file(&format!("{identity}.pem"))?;
        let key = file(&format!("{identity}-key.pem"))?;
        set(
            &mut c,
            "transport/link/tls/root_ca_certificate",
            file("ca.pem")?,
        )?;
        set(
            &mut c,
            "transport/link/tls/listen_certificate",
            cert.clone(),
        )?;
        set(&mut c, "transport/link/tls/listen_private_key", key.clone())?;
        set(&mut c, "transport/link/tls/connect_certificate", cert)?;
        set(&mut c, "transport/link/tls/connect_private_key", key)?;
        // Every peer must present a certificate chaining to the run's CA.
        set(&mut c, "transport/link/tls/enable_mtls", "true".into())?;
        // Labs address hosts by IP, which the certificates do not name; the
        // peer's identity is checked by access control on its common name.
        set(
            &mut c,
            "transport/link/tls/verify_name_on_connect",
            "false".into(),
        )?;
    }
    if let Some(acl) = access {
        set(&mut c, "access_control", acl.to_string())?;
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
    // A peer that stops reading blocks a put at most this long before its
    // link is closed (it is then a dead link): a stalled peer cannot stall
    // the run.
    set(
        &mut c,
        "transport/link/tx/queue/congestion_control/block/wait_before_close",
        STALL_CLOSE.as_micros().to_string(),
    )?;
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_the_run_direction_host_and_topic() {
        let k = data_key("r1", ServiceId::Truth(3), &Direction::Down);
        assert_eq!(k, "etp/r1/down/sensor/3/truth");
        assert_eq!(parse_key("r1", &k), Some((None, "sensor/3/truth")));
        let k = data_key("r1", ServiceId::Measurement, &Direction::Up("h-2".into()));
        assert_eq!(parse_key("r1", &k), Some((Some("h-2"), "measurement")));
        assert_eq!(parse_key("r2", &k), None);
        assert_eq!(parse_key("r1", "nope"), None);
        assert_eq!(
            parse_alive_key(&sensor_alive_key("r1", 4, "h")),
            Some((4, "h"))
        );
    }

    #[test]
    fn the_configuration_turns_scouting_off_and_names_the_endpoints() {
        let c = config(
            Some("tcp/127.0.0.1:7447"),
            None,
            DEFAULT_LEASE,
            &Security::Insecure,
            None,
        )
        .expect("config");
        let text = format!("{c}");
        assert!(text.contains("tcp/127.0.0.1:7447"), "{text}");
        assert!(text.contains("\"lease\":300"), "{text}");
        let tls = Security::Tls {
            dir: "/nonexistent".into(),
            identity: "x".into(),
        };
        assert!(config(Some("tcp/127.0.0.1:1"), None, DEFAULT_LEASE, &tls, None).is_err());
        assert!(
            config(
                Some("tls/127.0.0.1:1"),
                None,
                DEFAULT_LEASE,
                &Security::Insecure,
                None
            )
            .is_err()
        );
    }

    #[test]
    fn access_control_parses_as_zenoh_configuration() {
        let hosts = BTreeMap::from([("h1".to_string(), vec![0, 2]), ("h2".to_string(), vec![])]);
        let mut c = zenoh::Config::default();
        c.insert_json5(
            "access_control",
            &agent_host_access("r1", &hosts).to_string(),
        )
        .expect("agent host acl");
        c.insert_json5("access_control", &sensor_host_access().to_string())
            .expect("sensor host acl");
    }
}
