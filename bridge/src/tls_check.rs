//! Certificate failures named (issue 41): what each end of a TLS link can
//! see of a refused handshake, in words, on the side that sees it.
//!
//! * The agent host: the accept loop of our `zenoh-link-tls` reports each
//!   connection it refused (`zenoh_link_tls::on_refused`); [`record`] counts
//!   them by [`Cause`] and keeps the first few with their peer, so a sensor
//!   host that never joins is named ("from 10.77.1.2:40312: its certificate
//!   was issued by another CA") and the counts reach the run's report
//!   (the `handshakes` line).
//! * A sensor host: before Zenoh connects, [`check_agent_host`] makes one
//!   TLS handshake of its own with the agent host's address, trusting only
//!   the key folder's CA and demanding the agent host's name
//!   (`link_keys::AGENT_HOST`, the name `etp certs init` puts in its
//!   certificate). A certificate of another CA, an expired one or one of
//!   the wrong role ends the sensor host at once, by name; a refusal of
//!   its own certificate by the agent host (a TLS alert) ends it with a
//!   hint. Zenoh's own link then checks the chain again (the folder's CA
//!   only, no public roots: third_party/README.md).

use crate::BridgeError;
use etp_runtime::link_keys::{AGENT_HOST, Identity};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName, UnixTime};
use rustls::{CertificateError, Error as TlsError};
use std::collections::BTreeMap;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Why a TLS handshake failed, as one word (report keys) and a sentence.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cause {
    pub reason: &'static str,
    pub text: String,
}

/// A certificate's bound as an RFC 3339 UTC date (`2026-12-31T23:59:59Z`);
/// past the year 9999 (which RFC 3339 cannot write) the seconds since 1970.
pub fn utc(t: UnixTime) -> String {
    let secs = t.as_secs();
    if secs >= LAST_RFC3339_SECOND {
        return format!("{secs} s after 1970-01-01 UTC");
    }
    humantime::format_rfc3339_seconds(std::time::UNIX_EPOCH + Duration::from_secs(secs)).to_string()
}

/// The first second of the year 10000.
const LAST_RFC3339_SECOND: u64 = 253_402_300_800;

/// The cause of a rustls error, seen from the end that verified (or was
/// refused by) the other's certificate.
pub fn cause_of(e: &TlsError) -> Cause {
    let c = |reason, text: String| Cause { reason, text };
    match e {
        TlsError::InvalidCertificate(ce) => match ce {
            CertificateError::UnknownIssuer | CertificateError::BadSignature => c(
                "unknown-ca",
                "its certificate was issued by another CA (unknown issuer): it is not of this \
                 key folder"
                    .into(),
            ),
            CertificateError::ExpiredContext { not_after, .. } => c(
                "expired",
                format!("its certificate expired on {}", utc(*not_after)),
            ),
            CertificateError::Expired => c("expired", "its certificate has expired".into()),
            CertificateError::NotValidYetContext { not_before, .. } => c(
                "not-yet-valid",
                format!("its certificate is valid only from {}", utc(*not_before)),
            ),
            CertificateError::NotValidYet => {
                c("not-yet-valid", "its certificate is not valid yet".into())
            }
            CertificateError::InvalidPurpose | CertificateError::InvalidPurposeContext { .. } => c(
                "wrong-role",
                "its certificate is of the wrong role (a sensor host's where the agent host's \
                 is expected, or the reverse)"
                    .into(),
            ),
            CertificateError::NotValidForName | CertificateError::NotValidForNameContext { .. } => {
                c(
                    "wrong-name",
                    format!("its certificate is not the `{AGENT_HOST}`'s (another name)"),
                )
            }
            other => c("bad-certificate", format!("its certificate: {other:?}")),
        },
        TlsError::NoCertificatesPresented => {
            c("no-certificate", "it presented no certificate".into())
        }
        TlsError::AlertReceived(a) => c(
            "refused-by-peer",
            format!(
                "it refused this host's certificate (TLS alert {a:?}): check that both hosts' \
                 bundles come from the same `etp certs init` and that this host's certificate \
                 has not expired"
            ),
        ),
        other => c("not-tls", format!("not a TLS handshake of etp ({other})")),
    }
}

/// The cause of an I/O error of a handshake (rustls's inside, if any).
pub fn cause_of_io(e: &std::io::Error) -> Cause {
    match e.get_ref().and_then(|i| i.downcast_ref::<TlsError>()) {
        Some(t) => cause_of(t),
        None => Cause {
            reason: "broken",
            text: format!("the connection broke during the handshake ({e})"),
        },
    }
}

/// What the agent host's accept loop refused: counts by reason and the
/// first [`NAMED`] refusals with their peer.
#[derive(Debug, Default, Clone)]
pub struct Refusals {
    pub counts: BTreeMap<&'static str, u64>,
    pub named: Vec<String>,
}

/// Refusals named in the log and in a join error.
pub const NAMED: usize = 10;

static REFUSALS: Mutex<Option<Refusals>> = Mutex::new(None);

/// Count a refused connection (the accept loop's hook).
pub fn record(peer: SocketAddr, why: zenoh_link_tls::Refused<'_>) {
    let cause = match why {
        zenoh_link_tls::Refused::Handshake(e) => cause_of_io(e),
        zenoh_link_tls::Refused::Timeout => Cause {
            reason: "timeout",
            text: "its TLS handshake did not finish in time".into(),
        },
        zenoh_link_tls::Refused::TooManyFromSource => Cause {
            reason: "too-many-from-source",
            text: format!(
                "its address had {} TLS handshakes under way",
                zenoh_link_tls::PER_SOURCE_HANDSHAKES
            ),
        },
    };
    if let Ok(mut r) = REFUSALS.lock() {
        let r = r.get_or_insert_with(Refusals::default);
        *r.counts.entry(cause.reason).or_default() += 1;
        if r.named.len() < NAMED
            && !matches!(cause.reason, "not-tls" | "broken" | "too-many-from-source")
        {
            tracing::warn!("refused a TLS connection from {peer}: {}", cause.text);
            r.named.push(format!("from {peer}: {}", cause.text));
        }
    }
}

/// Install [`record`] as the accept loop's hook (before Zenoh listens).
pub fn watch_refusals() {
    zenoh_link_tls::on_refused(record);
}

/// The refusals so far.
pub fn refusals() -> Refusals {
    REFUSALS
        .lock()
        .map(|r| r.clone().unwrap_or_default())
        .unwrap_or_default()
}

fn certificates(path: &std::path::Path) -> Result<Vec<CertificateDer<'static>>, BridgeError> {
    CertificateDer::pem_file_iter(path)
        .and_then(|i| i.collect::<Result<Vec<_>, _>>())
        .map_err(|e| BridgeError::Input(format!("{}: {e}", path.display())))
}

/// The TLS client of [`check_agent_host`]: the folder's CA only, this
/// host's certificate, TLS 1.3.
fn client(id: &Identity) -> Result<Arc<rustls::ClientConfig>, BridgeError> {
    let mut roots = rustls::RootCertStore::empty();
    for c in certificates(&id.ca)? {
        roots
            .add(c)
            .map_err(|e| BridgeError::Input(format!("{}: {e}", id.ca.display())))?;
    }
    let key = PrivateKeyDer::from_pem_file(&id.private_key)
        .map_err(|e| BridgeError::Input(format!("{}: {e}", id.private_key.display())))?;
    let chain = certificates(&id.certificate)?;
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ClientConfig::builder_with_provider(provider)
        .with_protocol_versions(&[&rustls::version::TLS13])
        .and_then(|b| {
            b.with_root_certificates(roots)
                .with_client_auth_cert(chain, key)
        })
        .map_err(|e| BridgeError::Input(format!("{}: {e}", id.certificate.display())))?;
    Ok(Arc::new(config))
}

/// One handshake with `addr`: `Ok(None)` done, `Ok(Some(cause))` refused
/// (by us or by the peer), `Err` the connection failed (try again).
fn handshake(
    config: &Arc<rustls::ClientConfig>,
    addr: SocketAddr,
) -> std::io::Result<Option<Cause>> {
    let mut tcp = TcpStream::connect_timeout(&addr, Duration::from_secs(1))?;
    tcp.set_read_timeout(Some(Duration::from_secs(5)))?;
    tcp.set_write_timeout(Some(Duration::from_secs(5)))?;
    let name = ServerName::try_from(AGENT_HOST)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
    let mut conn = rustls::ClientConnection::new(config.clone(), name)
        .map_err(|e| std::io::Error::other(e.to_string()))?;
    while conn.is_handshaking() {
        match conn.complete_io(&mut tcp) {
            Ok(_) => {}
            Err(e) => {
                return match e.get_ref().and_then(|i| i.downcast_ref::<TlsError>()) {
                    Some(t) => Ok(Some(cause_of(t))),
                    None => Err(e),
                };
            }
        }
    }
    // TLS 1.3: the agent host checks this host's certificate after the
    // client's Finished; a refusal comes back as an alert. Say goodbye and
    // read until the agent host closes (accepted) or alerts (refused).
    conn.send_close_notify();
    while conn.wants_write() {
        conn.write_tls(&mut tcp)?;
    }
    loop {
        match conn.read_tls(&mut tcp) {
            Ok(0) | Err(_) => return Ok(None),
            Ok(_) => match conn.process_new_packets() {
                Err(t) => return Ok(Some(cause_of(&t))),
                Ok(st) if st.peer_has_closed() => return Ok(None),
                Ok(_) => {}
            },
        }
    }
}

/// Before Zenoh connects: is the host at `endpoint` (`tls/ADDR:PORT`) the
/// agent host of this key folder, and does it accept this host? Retried
/// while the address does not answer (the agent host may start later),
/// until `timeout`; a refused certificate ends it at once, by name.
pub fn check_agent_host(
    endpoint: &str,
    id: &Identity,
    timeout: Duration,
) -> Result<(), BridgeError> {
    let address = endpoint
        .strip_prefix("tls/")
        .unwrap_or(endpoint)
        .split(['#', '?'])
        .next()
        .unwrap_or("");
    let config = client(id)?;
    let started = Instant::now();
    loop {
        let addrs: Vec<SocketAddr> = address
            .to_socket_addrs()
            .map_err(|e| BridgeError::Input(format!("--connect {endpoint}: {e}")))?
            .collect();
        for addr in addrs {
            match handshake(&config, addr) {
                Ok(None) => return Ok(()),
                Ok(Some(cause)) => {
                    return Err(BridgeError::Join(format!(
                        "refused the agent host at {addr} ({endpoint}): {} [{}]",
                        cause.text, cause.reason
                    )));
                }
                Err(e) => tracing::debug!("TLS check of {addr}: {e}"),
            }
        }
        if started.elapsed() >= timeout {
            // Nobody answered: the join's own error says so.
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_utc_calendar_dates() {
        assert_eq!(
            utc(UnixTime::since_unix_epoch(Duration::ZERO)),
            "1970-01-01T00:00:00Z"
        );
        assert_eq!(
            utc(UnixTime::since_unix_epoch(Duration::from_secs(
                951_782_400 + 3_723
            ))),
            "2000-02-29T01:02:03Z"
        );
        assert_eq!(
            utc(UnixTime::since_unix_epoch(Duration::from_secs(
                1_798_761_599
            ))),
            "2026-12-31T23:59:59Z"
        );
        assert_eq!(
            utc(UnixTime::since_unix_epoch(Duration::from_secs(u64::MAX))),
            format!("{} s after 1970-01-01 UTC", u64::MAX)
        );
    }

    #[test]
    fn causes_are_named() {
        let e = TlsError::InvalidCertificate(CertificateError::UnknownIssuer);
        assert_eq!(cause_of(&e).reason, "unknown-ca");
        let e = TlsError::InvalidCertificate(CertificateError::ExpiredContext {
            time: UnixTime::since_unix_epoch(Duration::from_secs(1_000_000_000)),
            not_after: UnixTime::since_unix_epoch(Duration::from_secs(951_782_400)),
        });
        let c = cause_of(&e);
        assert_eq!(c.reason, "expired");
        assert!(c.text.contains("expired on 2000-02-29"), "{}", c.text);
        let e = TlsError::InvalidCertificate(CertificateError::InvalidPurpose);
        assert_eq!(cause_of(&e).reason, "wrong-role");
    }
}
