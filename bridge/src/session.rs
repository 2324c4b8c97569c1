//! The Zenoh side shared by both ends: the session's configuration (scouting
//! off: only the endpoints given are ever contacted), the key expressions of
//! a run, and the run description a sensor host fetches when it joins.

use crate::BridgeError;
use etp_runtime::link_keys;
pub use etp_runtime::report::SessionInfo;
use etp_runtime::wire::ServiceId;
use etp_runtime::wire::stamp::LINK_PROTOCOL;
use std::time::Duration;

/// Key of the agent host's queryable answering [`SessionInfo`] (the joiner
/// does not know the run id yet).
pub const SESSION_KEY: &str = "etp/session";

/// Key of a message going down (agent host → the sensor host `host` that
/// was granted the message's sensor at join): `etp/<run>/down/<host>/<topic>`
/// (every service going down is per sensor, so its topic names the sensor).
/// The host is in the key so that access control lets only that host
/// subscribe to it: a peer that may not read a sensor's downlink never gets
/// its traffic, so it cannot hold that traffic up by not reading.
pub fn down_key(run: &str, host: &str, s: ServiceId) -> String {
    format!("etp/{run}/down/{host}/{}", s.topic())
}

/// Every downlink key of sensor `sensor` towards host `host` (what that host
/// subscribes to, and all that access control lets it subscribe to).
pub fn down_keys(run: &str, host: &str, sensor: usize) -> String {
    format!("etp/{run}/down/{host}/sensor/{sensor}/**")
}

/// The topic of the agent host's probe of a granted host that owes an
/// answer ([`probe_key`]); not a service: a sensor host drops it unread.
pub const PROBE_TOPIC: &str = "probe-reading";

/// Key of the probe towards host `host` about sensor `sensor`:
/// `etp/<run>/down/<host>/sensor/<sensor>/probe-reading`, among the keys
/// that host subscribes to ([`down_keys`]) and alone may. While the host
/// owes an answer (the sensor's last downlink message got none for
/// [`PROBE_AFTER`]), the agent host puts [`PROBE_BYTES`] on it every
/// 100 ms: a host that reads drops them; one that stopped reading fills
/// its queue, so the put waits and Zenoh closes it after
/// [`STALLED_PEER_CLOSE`] even when the run itself sends it nothing more
/// (the agent waits for the sensor's slot).
pub fn probe_key(run: &str, host: &str, sensor: usize) -> String {
    format!("etp/{run}/down/{host}/sensor/{sensor}/{PROBE_TOPIC}")
}

/// Whether a downlink key is a probe ([`probe_key`]).
pub fn is_probe_key(key: &str) -> bool {
    key.starts_with("etp/") && key.contains("/down/") && key.ends_with(&format!("/{PROBE_TOPIC}"))
}

/// How long a sensor's downlink message may go unanswered before the agent
/// host probes its host ([`probe_key`]). A sensor answers each downlink
/// message it acts on within a step (a slot, a ledger), so a reading host
/// is probed only while the agent waits for it.
pub const PROBE_AFTER: Duration = Duration::from_secs(1);

/// Bytes of one probe: 40 KiB/s while probing, so a host that stopped
/// reading fills Zenoh's queue and the kernel's buffers (some 150 KiB with
/// Linux's defaults: its socket's receive buffer does not grow while it
/// does not read) in seconds.
pub const PROBE_BYTES: usize = 4096;

/// Key of a message going up from `sensor`: `etp/<run>/up/<sensor>/<topic>`.
/// The sending sensor is in the key so that access control can grant a
/// sensor host exactly its sensors' keys (and admission checks the key
/// against the message's sender).
pub fn up_key(run: &str, sensor: usize, s: ServiceId) -> String {
    format!("etp/{run}/up/{sensor}/{}", s.topic())
}

/// Key of host `host`'s claim, at join, to serve remote sensor `sensor` (a
/// query answered by the agent host: granted to the first host only):
/// `etp/<run>/join/<sensor>/<host>`. With TLS, access control lets a host
/// query only the join keys with its own name, so the name is the
/// certificate's.
pub fn join_key(run: &str, sensor: usize, host: &str) -> String {
    format!("etp/{run}/join/{sensor}/{host}")
}

/// A claim's payload: the claimant's Zenoh id and the link protocol it
/// speaks, `<zid> link/<n>` ([`LINK_PROTOCOL`]).
pub fn claim_payload(zid: &str) -> String {
    format!("{zid} link/{LINK_PROTOCOL}")
}

/// The Zenoh id of a claim's payload and the link protocol it names: an
/// etp whose link carried the payload alone sent the id alone (protocol
/// 1); `None` for a protocol that is not a number.
pub fn parse_claim(payload: &str) -> (&str, Option<u32>) {
    match payload.split_once(' ') {
        None => (payload, Some(1)),
        Some((zid, rest)) => (zid, rest.strip_prefix("link/").and_then(|n| n.parse().ok())),
    }
}

/// Why a sensor host and an agent host of different link protocols do not
/// join (`None`: they speak the same), in words both ends' logs can show.
pub fn other_protocol(agent_host: Option<u32>, sensor_host: Option<u32>) -> Option<String> {
    let n = |p: Option<u32>| p.map_or_else(|| "?".to_string(), |n| n.to_string());
    (agent_host != sensor_host).then(|| {
        format!(
            "the agent host speaks link protocol {}, the sensor host {} (since 2 every \
             message carries its sender's time): run the same etp release on every host",
            n(agent_host),
            n(sensor_host)
        )
    })
}

/// Every join key of a run (the agent host's queryable).
pub fn join_keys(run: &str) -> String {
    format!("etp/{run}/join/*/*")
}

/// The sensor and host a join key names (canonical digits, a host name of
/// `etp certs init`'s alphabet).
pub fn parse_join_key<'a>(run: &str, key: &'a str) -> Option<(usize, &'a str)> {
    let rest = key.strip_prefix(&format!("etp/{run}/join/"))?;
    let (sensor, host) = rest.split_once('/')?;
    link_keys::check_name(host).ok()?;
    Some((canonical_index(sensor)?, host))
}

/// A sensor index as a key spells it: digits only, no leading zero, at most
/// four (`+1` or `01` would name a sensor twice).
fn canonical_index(s: &str) -> Option<usize> {
    if s.is_empty()
        || s.len() > 4
        || !s.bytes().all(|b| b.is_ascii_digit())
        || (s.len() > 1 && s.starts_with('0'))
    {
        return None;
    }
    s.parse().ok()
}

/// Every data key of one direction.
pub fn data_keys(run: &str, down: bool) -> String {
    format!("etp/{run}/{}/**", if down { "down" } else { "up" })
}

/// A data key's parts: the sending sensor (up keys) and the topic.
pub fn parse_data_key(key: &str) -> Option<(Option<usize>, &str)> {
    let rest = key.strip_prefix("etp/")?;
    let (_, rest) = rest.split_once('/')?;
    let (dir, rest) = rest.split_once('/')?;
    match dir {
        "down" => {
            let (host, topic) = rest.split_once('/')?;
            link_keys::check_name(host).ok()?;
            Some((None, topic))
        }
        "up" => {
            let (sensor, topic) = rest.split_once('/')?;
            Some((Some(canonical_index(sensor)?), topic))
        }
        _ => None,
    }
}

/// The agent host's access control for the sensor hosts of the key folder
/// `dir` (`hosts.json`): each host's sensors among the run's remote ones
/// (a name the run does not have is no grant).
pub fn access_control_of(
    dir: &std::path::Path,
    info: &SessionInfo,
) -> Result<serde_json::Value, BridgeError> {
    let hosts = link_keys::hosts(dir).map_err(|e| BridgeError::Input(format!("--tls: {e}")))?;
    let grants: Vec<(String, Vec<usize>)> = hosts
        .iter()
        .map(|(name, sensors)| {
            let served = match sensors {
                None => info.remote.clone(),
                Some(list) => info
                    .remote
                    .iter()
                    .copied()
                    .filter(|&i| info.sensors.get(i).is_some_and(|n| list.contains(n)))
                    .collect(),
            };
            (name.clone(), served)
        })
        .collect();
    Ok(access_control(&info.run_id, &grants))
}

/// The agent host's access control (Zenoh's `access_control`, by the
/// certificate's common name `etp <h>` of host `h`): anything not granted is
/// denied. Every sensor host may ask for the run (`etp/session`) and follow
/// the agent host's liveliness; host `h` may, for each sensor `i` of
/// `hosts[h]`, claim it in its own name (query `etp/<run>/join/<i>/<h>`),
/// put on `etp/<run>/up/<i>/**`, subscribe to `etp/<run>/down/<h>/sensor/<i>/**`
/// and declare the token `etp/<run>/alive/sensor/<i>` — nothing of another
/// sensor, no downlink key of another host (the agent host puts a sensor's
/// downlink only on the keys of the host it granted the sensor to), and no
/// wider key expression (a subscription to `etp/**` is denied). What the
/// agent host itself sends out is allowed (its puts reach only the
/// subscriptions granted).
pub fn access_control(run: &str, hosts: &[(String, Vec<usize>)]) -> serde_json::Value {
    use serde_json::json;
    let mut rules = vec![
        json!({"id": "session", "flows": ["ingress"], "messages": ["query"],
               "key_exprs": [SESSION_KEY], "permission": "allow"}),
        json!({"id": "session-reply", "flows": ["egress"],
               "messages": ["declare_queryable", "reply"],
               "key_exprs": [SESSION_KEY], "permission": "allow"}),
        json!({"id": "agent-host-alive", "flows": ["ingress"],
               "messages": ["declare_liveliness_subscriber", "liveliness_query"],
               "key_exprs": [agent_host_alive_key(run)], "permission": "allow"}),
        json!({"id": "agent-host-out", "flows": ["egress"],
               "messages": ["put", "declare_subscriber", "declare_queryable", "liveliness_token",
                            "declare_liveliness_subscriber", "liveliness_query", "reply"],
               "key_exprs": [format!("etp/{run}/**")], "permission": "allow"}),
    ];
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    for (name, sensors) in hosts {
        let cn = link_keys::common_name(name);
        let id = format!("host {cn}");
        let mut host_rules = vec![
            "session".to_string(),
            "session-reply".into(),
            "agent-host-alive".into(),
            "agent-host-out".into(),
        ];
        if !sensors.is_empty() {
            let keys =
                |f: &dyn Fn(usize) -> String| sensors.iter().map(|&i| f(i)).collect::<Vec<_>>();
            for (what, message, key_exprs) in [
                ("join", "query", keys(&|i| join_key(run, i, name))),
                ("up", "put", keys(&|i| format!("etp/{run}/up/{i}/**"))),
                (
                    "down",
                    "declare_subscriber",
                    keys(&|i| down_keys(run, name, i)),
                ),
                (
                    "alive",
                    "liveliness_token",
                    keys(&|i| sensor_alive_key(run, i)),
                ),
            ] {
                let rule = format!("{id}: {what}");
                rules.push(
                    json!({"id": rule, "flows": ["ingress"], "messages": [message],
                                  "key_exprs": key_exprs, "permission": "allow"}),
                );
                host_rules.push(rule);
            }
        }
        subjects.push(json!({"id": id, "cert_common_names": [cn]}));
        policies.push(json!({"rules": host_rules, "subjects": [id]}));
    }
    json!({"enabled": true, "default_permission": "deny", "rules": rules,
           "subjects": subjects, "policies": policies})
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

/// How long a put waits for a peer whose queue stays full (it stopped
/// reading: a stalled or hostile subscriber) before Zenoh closes that peer's
/// transport (`transport/link/tx/queue/congestion_control/block/
/// wait_before_close`). Zenoh's default, set here so that the bound is ours.
pub const STALLED_PEER_CLOSE: Duration = Duration::from_secs(5);

/// What both ends of a link take: how long to wait for the other end, the
/// lease, and the link's protection.
#[derive(Debug, Clone, clap::Args)]
pub struct HostArgs {
    /// Seconds to wait for the other end: every remote sensor to join (agent
    /// host), the agent host to answer (sensor host).
    #[arg(long, default_value_t = 60.0)]
    pub join_timeout: f64,
    /// Link lease, ms: a silent link is dead after this long.
    #[arg(long, default_value_t = DEFAULT_LEASE.as_millis() as u64)]
    pub lease_ms: u64,
    #[command(flatten)]
    pub link: LinkArgs,
}

impl HostArgs {
    /// `--join-timeout` as a duration (a negative one is no wait).
    pub fn join_wait(&self) -> Duration {
        Duration::from_secs_f64(self.join_timeout.max(0.0))
    }

    /// `--lease-ms` as a duration.
    pub fn lease(&self) -> Duration {
        Duration::from_millis(self.lease_ms)
    }
}

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
    access_control: Option<&serde_json::Value>,
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
        set(
            &mut c,
            "transport/link/tls/root_ca_certificate",
            path(&id.ca),
        )?;
        if listen.is_some() {
            set(
                &mut c,
                "transport/link/tls/listen_certificate",
                path(&id.certificate),
            )?;
            set(
                &mut c,
                "transport/link/tls/listen_private_key",
                path(&id.private_key),
            )?;
            set(&mut c, "transport/link/tls/enable_mtls", "true".into())?;
        }
        if connect.is_some() {
            set(
                &mut c,
                "transport/link/tls/connect_certificate",
                path(&id.certificate),
            )?;
            set(
                &mut c,
                "transport/link/tls/connect_private_key",
                path(&id.private_key),
            )?;
            // Hosts are reached by address; the CA and the certificates' key
            // usage (server for the agent host only) authenticate the ends.
            set(
                &mut c,
                "transport/link/tls/verify_name_on_connect",
                "false".into(),
            )?;
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
    set(
        &mut c,
        "transport/link/tx/queue/congestion_control/block/wait_before_close",
        STALLED_PEER_CLOSE.as_micros().to_string(),
    )?;
    if let Some(acl) = access_control {
        set(&mut c, "access_control", acl.to_string())?;
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_claim_names_its_link_protocol_and_an_old_one_is_refused_in_words() {
        let p = claim_payload("a1b2");
        assert_eq!(parse_claim(&p), ("a1b2", Some(LINK_PROTOCOL)));
        // An etp whose link carried the payload alone sent its id alone.
        assert_eq!(parse_claim("a1b2"), ("a1b2", Some(1)));
        assert_eq!(parse_claim("a1b2 link/x"), ("a1b2", None));
        assert_eq!(
            other_protocol(Some(LINK_PROTOCOL), Some(LINK_PROTOCOL)),
            None
        );
        let why = other_protocol(Some(LINK_PROTOCOL), Some(1)).expect("refused");
        assert!(
            why.contains("link protocol 2, the sensor host 1") && why.contains("same etp release"),
            "{why}"
        );
        assert!(other_protocol(Some(2), None).is_some());
        // A description from an agent host before the field: protocol 1.
        let old = r#"{"run_id":"r","scenario_toml":"","seed":1,"sensors":[],"remote":[]}"#;
        let info: SessionInfo = serde_json::from_str(old).expect("an older description");
        assert_eq!(info.link_protocol, 1);
    }

    #[test]
    fn keys_name_the_run_direction_sender_and_topic() {
        let k = down_key("r1", "b", ServiceId::Truth(3));
        assert_eq!(k, "etp/r1/down/b/sensor/3/truth");
        assert_eq!(parse_data_key(&k), Some((None, "sensor/3/truth")));
        // A down key without a host names no topic of a service.
        assert_ne!(
            parse_data_key("etp/r1/down/sensor/3/truth"),
            Some((None, "sensor/3/truth"))
        );
        let k = up_key("r1", 12, ServiceId::Measurement);
        assert_eq!(k, "etp/r1/up/12/measurement");
        assert_eq!(parse_data_key(&k), Some((Some(12), "measurement")));
        assert_eq!(
            parse_join_key("r1", &join_key("r1", 7, "sensor-host")),
            Some((7, "sensor-host"))
        );
        for bad in [
            "etp/r1/join/07/b",
            "etp/r1/join/7",
            "etp/r1/join/",
            "etp/r2/join/1/b",
            "etp/r1/join/1/x/y",
            "etp/r1/join/1/-x",
            "etp/r1/join/1/",
        ] {
            assert_eq!(parse_join_key("r1", bad), None, "{bad}");
        }
        for bad in [
            "nope",
            "etp/r1/up/measurement",
            "etp/r1/up/01/measurement",
            "etp/r1/up/+1/measurement",
            "etp/r1/up/99999/measurement",
            "etp/r1/sideways/x",
        ] {
            assert_eq!(parse_data_key(bad), None, "{bad}");
        }
    }

    #[test]
    fn access_control_grants_each_host_only_its_sensors_keys() {
        let acl = access_control("r1", &[("b".into(), vec![1, 3]), ("c".into(), vec![])]);
        assert_eq!(acl["default_permission"], "deny");
        let text = acl.to_string();
        for k in [
            "etp/r1/up/1/**",
            "etp/r1/up/3/**",
            "etp/r1/down/b/sensor/3/**",
            "etp/r1/alive/sensor/1",
            "etp/r1/join/3/b",
            "etp b",
        ] {
            assert!(text.contains(k), "{k}: {text}");
        }
        for k in ["etp/r1/up/**", "etp/r1/down/sensor/", "etp/r1/down/c/"] {
            assert!(!text.contains(k), "{k}: {text}");
        }
        // A host with no sensor of this run gets the session only.
        let c = &acl["policies"][1]["rules"];
        assert_eq!(c.as_array().map(Vec::len), Some(4), "{c}");
        // Zenoh accepts it.
        let mut cfg = zenoh::Config::default();
        cfg.insert_json5("access_control", &acl.to_string())
            .expect("a valid ACL");
    }

    #[test]
    fn the_configuration_turns_scouting_off_and_names_the_endpoints() {
        let c =
            config(Some("tcp/127.0.0.1:7447"), None, DEFAULT_LEASE, None, None).expect("config");
        let text = format!("{c}");
        assert!(text.contains("tcp/127.0.0.1:7447"), "{text}");
        assert!(text.contains("\"lease\":300"), "{text}");
    }
}
