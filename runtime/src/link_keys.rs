//! The key folder of an authenticated, encrypted link (`etp certs init DIR`,
//! `--tls DIR` on `etp run` and `etp sensor-host`): where each file is, and
//! the checks made before a process hands it to Zenoh's TLS.
//!
//! `etp certs init DIR` writes one bundle per host: `DIR/agent-host/` (the
//! run's CA certificate, the agent host's key pair and `hosts.json`) and
//! `DIR/NAME/` per sensor host (the CA certificate and its own key pair);
//! each bundle goes to its host only. `--tls` takes a bundle, or `DIR`
//! itself (the host's bundle `DIR/NAME/` is then used). The CA's own
//! private key is never written: nobody can mint a certificate for this
//! folder later (run `etp certs init` again to replace every key at once).
//! The agent host's certificate is for TLS servers only and a sensor host's
//! for TLS clients only, so a sensor host cannot pose as the agent host; a
//! sensor host refuses to start while its folder holds another host's
//! private key ([`KeyFolderError::OtherHostsKey`]), so that one stolen
//! sensor host holds no key but its own.

use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// The CA every certificate of the folder chains to.
pub const CA_CERTIFICATE: &str = "ca.pem";
/// The agent host's identity (certificate common name and file stem).
pub const AGENT_HOST: &str = "agent-host";
/// The default sensor host name.
pub const DEFAULT_SENSOR_HOST: &str = "sensor-host";

/// Why a key folder cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum KeyFolderError {
    #[error("{0}: {1} (make the folder with `etp certs init DIR`)")]
    Missing(PathBuf, std::io::Error),
    #[error(
        "{0}: a private key readable by other users (mode {1:o}); `chmod 600` it, or make the folder again with `etp certs init`"
    )]
    KeyReadable(PathBuf, u32),
    #[error("{0}: not a regular file (a link or a folder is refused)")]
    NotAFile(PathBuf),
    #[error(
        "{0}: owned by user {1}, not by this user ({2}); key material is used only from the user's own files"
    )]
    Foreign(PathBuf, u32, u32),
    #[error("{0}: writable by other users (mode {1:o}); `chmod go-w` it")]
    Writable(PathBuf, u32),
    #[error(
        "{0}: the private key of another host, in the key folder of sensor host `{1}`: a sensor \
         host gets only its own bundle (`etp certs init` wrote `DIR/{1}/`); remove this file \
         from this host"
    )]
    OtherHostsKey(PathBuf, String),
    #[error("`{0}` is not a host name: use letters, digits and - (at most 48)")]
    BadName(String),
    #[error("{0}: {1}")]
    BadHosts(PathBuf, String),
    #[error("--tls needs a `tls/ADDR:PORT` endpoint, got `{0}`")]
    TlsNeedsTlsEndpoint(String),
    #[error("--insecure carries plain `tcp/ADDR:PORT` only, got `{0}`")]
    InsecureNeedsTcp(String),
    #[error(
        "the link to `{0}` would be unauthenticated and unencrypted: give --tls DIR (made by \
         `etp certs init DIR`) with a `tls/ADDR:PORT` endpoint, or --insecure for plain TCP on an \
         isolated test network"
    )]
    Unprotected(String),
}

/// The protection of a link: the key folder's identity `name` (TLS, both
/// ends authenticated by the folder's CA) for a `tls/` endpoint, or nothing
/// for a `tcp/` endpoint with `insecure`. Anything else is refused: plain
/// TCP is never chosen silently.
pub fn resolve(
    endpoint: &str,
    tls: Option<&Path>,
    name: &str,
    insecure: bool,
) -> Result<Option<Identity>, KeyFolderError> {
    let proto = endpoint.split('/').next().unwrap_or("");
    match (tls, insecure, proto) {
        (Some(dir), false, "tls") => identity(dir, name).map(Some),
        (Some(_), false, _) => Err(KeyFolderError::TlsNeedsTlsEndpoint(endpoint.into())),
        (_, true, "tcp") => Ok(None),
        (_, true, _) => Err(KeyFolderError::InsecureNeedsTcp(endpoint.into())),
        (None, false, _) => Err(KeyFolderError::Unprotected(endpoint.into())),
    }
}

/// Which sensors each sensor host of a key folder may serve (`hosts.json`,
/// written by `etp certs init --sensor-host NAME[=s0,s3]`): `None` = any
/// remote sensor of a run. The agent host's access control grants a host
/// only its sensors' keys.
pub const HOSTS: &str = "hosts.json";

/// The sensor hosts of a key folder and the sensors each may serve.
pub type Hosts = std::collections::BTreeMap<String, Option<Vec<String>>>;

/// A file of a key folder, checked before it is used: a regular file (not
/// followed through a link), owned by this user and writable by nobody else
/// (another user who could replace the CA, a key or `hosts.json` could let
/// anyone in).
fn checked_file(path: &Path) -> Result<std::fs::Metadata, KeyFolderError> {
    let m = std::fs::symlink_metadata(path).map_err(|e| KeyFolderError::Missing(path.into(), e))?;
    if !m.file_type().is_file() {
        return Err(KeyFolderError::NotAFile(path.into()));
    }
    let me = etp_files::folders::euid();
    if m.uid() != me {
        return Err(KeyFolderError::Foreign(path.into(), m.uid(), me));
    }
    if m.mode() & 0o022 != 0 {
        return Err(KeyFolderError::Writable(path.into(), m.mode() & 0o777));
    }
    Ok(m)
}

/// Read `hosts.json` of the agent host's bundle in `dir` ([`bundle`],
/// [`checked_file`]).
pub fn hosts(dir: &Path) -> Result<Hosts, KeyFolderError> {
    let path = bundle(dir, AGENT_HOST).join(HOSTS);
    checked_file(&path)?;
    let text =
        std::fs::read_to_string(&path).map_err(|e| KeyFolderError::Missing(path.clone(), e))?;
    let hosts: Hosts = serde_json::from_str(&text)
        .map_err(|e| KeyFolderError::BadHosts(path.clone(), e.to_string()))?;
    for name in hosts.keys() {
        check_name(name)?;
    }
    Ok(hosts)
}

/// A host's files in a key folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    pub ca: PathBuf,
    pub certificate: PathBuf,
    pub private_key: PathBuf,
}

/// A host name as it appears in file names and certificates.
pub fn check_name(name: &str) -> Result<(), KeyFolderError> {
    let ok = !name.is_empty()
        && name.len() <= 48
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
        && !name.starts_with('-');
    if ok {
        Ok(())
    } else {
        Err(KeyFolderError::BadName(name.to_string()))
    }
}

/// Host `name`'s bundle: `dir/name/` when that is a folder (`dir` is what
/// `etp certs init` made), else `dir` itself (the bundle was given).
pub fn bundle(dir: &Path, name: &str) -> PathBuf {
    let sub = dir.join(name);
    match std::fs::symlink_metadata(&sub) {
        Ok(m) if m.is_dir() => sub,
        _ => dir.to_path_buf(),
    }
}

/// A sensor host's key folder holds no private key but `name.key`: none
/// in `dir` nor in a folder in it (links are not followed).
fn only_own_key(dir: &Path, name: &str) -> Result<(), KeyFolderError> {
    let own = files_of(name).1;
    let keys_in = |d: &Path| -> Vec<PathBuf> {
        std::fs::read_dir(d)
            .map(|it| {
                it.filter_map(Result::ok)
                    .map(|e| e.path())
                    .filter(|p| p.extension().is_some_and(|x| x == "key"))
                    .collect()
            })
            .unwrap_or_default()
    };
    let mut found = keys_in(dir);
    if let Ok(it) = std::fs::read_dir(dir) {
        for e in it.filter_map(Result::ok) {
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                found.extend(keys_in(&e.path()));
            }
        }
    }
    match found
        .into_iter()
        .find(|p| p.file_name().is_none_or(|f| f.to_string_lossy() != own))
    {
        Some(p) => Err(KeyFolderError::OtherHostsKey(p, name.to_string())),
        None => Ok(()),
    }
}

/// The certificate and key file names of host `name`.
pub fn files_of(name: &str) -> (String, String) {
    (format!("{name}.pem"), format!("{name}.key"))
}

/// The common name in host `name`'s certificate.
pub fn common_name(name: &str) -> String {
    format!("etp {name}")
}

/// The files of host `name` in `dir`, checked: each a regular file (not
/// followed through a link) of this user's that nobody else may write, the
/// private key readable by its owner only.
pub fn identity(dir: &Path, name: &str) -> Result<Identity, KeyFolderError> {
    check_name(name)?;
    if name != AGENT_HOST {
        only_own_key(dir, name)?;
    }
    let dir = &bundle(dir, name);
    let (cert, key) = files_of(name);
    let id = Identity {
        ca: dir.join(CA_CERTIFICATE),
        certificate: dir.join(cert),
        private_key: dir.join(key),
    };
    for p in [&id.ca, &id.certificate] {
        checked_file(p)?;
    }
    let m = checked_file(&id.private_key)?;
    if m.mode() & 0o077 != 0 {
        return Err(KeyFolderError::KeyReadable(
            id.private_key.clone(),
            m.mode() & 0o777,
        ));
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn an_identity_needs_its_three_files_and_a_private_key() {
        let dir = std::env::temp_dir().join(format!("etp-link-keys-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        assert!(matches!(
            identity(&dir, "h1"),
            Err(KeyFolderError::Missing(..))
        ));
        for f in ["ca.pem", "h1.pem", "h1.key"] {
            std::fs::write(dir.join(f), "x").expect("write");
        }
        let key = dir.join("h1.key");
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o644)).expect("chmod");
        let e = identity(&dir, "h1").expect_err("readable key");
        assert!(e.to_string().contains("chmod 600"), "{e}");
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
        let id = identity(&dir, "h1").expect("usable");
        assert_eq!(id.private_key, key);
        std::fs::remove_file(&key).expect("rm");
        std::os::unix::fs::symlink(dir.join("h1.pem"), &key).expect("link");
        assert!(matches!(
            identity(&dir, "h1"),
            Err(KeyFolderError::NotAFile(_))
        ));
        assert!(identity(&dir, "../x").is_err());
        std::fs::remove_file(&key).expect("rm");
        std::fs::write(&key, "x").expect("write");
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
        // A CA another user could replace is never trusted.
        let ca = dir.join("ca.pem");
        std::fs::set_permissions(&ca, std::fs::Permissions::from_mode(0o666)).expect("chmod");
        assert!(matches!(
            identity(&dir, "h1"),
            Err(KeyFolderError::Writable(..))
        ));
        std::fs::set_permissions(&ca, std::fs::Permissions::from_mode(0o644)).expect("chmod");
        identity(&dir, "h1").expect("usable again");
        if etp_files::folders::euid() == 0 {
            // As root (CI), a CA of user nobody's is refused.
            std::os::unix::fs::chown(&ca, Some(65534), None).expect("chown");
            assert!(matches!(
                identity(&dir, "h1"),
                Err(KeyFolderError::Foreign(_, 65534, 0))
            ));
        }
        // The endpoint and the protection asked for must agree.
        assert!(resolve("tcp/1.2.3.4:7447", None, "h1", false).is_err());
        assert!(resolve("tls/1.2.3.4:7447", None, "h1", false).is_err());
        assert!(resolve("tcp/1.2.3.4:7447", Some(&dir), "h1", false).is_err());
        assert!(resolve("tls/1.2.3.4:7447", None, "h1", true).is_err());
        assert_eq!(
            resolve("tcp/1.2.3.4:7447", None, "h1", true).expect("insecure"),
            None
        );
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    /// A sensor host whose folder (or a bundle in it) holds another host's
    /// private key is refused by name; the agent host's bundle is found in
    /// the folder `etp certs init` made.
    #[test]
    fn a_sensor_host_holding_another_hosts_key_is_refused() {
        let dir = std::env::temp_dir().join(format!("etp-link-bundles-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for (host, files) in [
            ("agent-host", ["agent-host.pem", "agent-host.key"]),
            ("b", ["b.pem", "b.key"]),
        ] {
            let d = dir.join(host);
            std::fs::create_dir_all(&d).expect("dir");
            for f in files.into_iter().chain(["ca.pem"]) {
                std::fs::write(d.join(f), "x").expect("write");
                let mode = if f.ends_with(".key") { 0o600 } else { 0o644 };
                std::fs::set_permissions(d.join(f), std::fs::Permissions::from_mode(mode))
                    .expect("chmod");
            }
        }
        // The whole folder on a sensor host: refused, naming the agent host's key.
        let e = identity(&dir, "b").expect_err("another host's key");
        assert!(
            matches!(&e, KeyFolderError::OtherHostsKey(p, n) if p.ends_with("agent-host/agent-host.key") && n == "b"),
            "{e}"
        );
        // Its own bundle: used.
        let id = identity(&dir.join("b"), "b").expect("own bundle");
        assert_eq!(id.private_key, dir.join("b/b.key"));
        // The agent host finds its bundle in the folder.
        let id = identity(&dir, AGENT_HOST).expect("agent bundle");
        assert_eq!(id.ca, dir.join("agent-host/ca.pem"));
        // A stray key dropped into the sensor host's bundle: refused.
        std::fs::write(dir.join("b/c.key"), "x").expect("write");
        assert!(matches!(
            identity(&dir.join("b"), "b"),
            Err(KeyFolderError::OtherHostsKey(..))
        ));
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}
