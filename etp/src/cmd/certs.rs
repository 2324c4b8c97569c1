//! `etp certs init DIR`: the key material of runs across hosts, made with
//! rcgen — a certificate authority and one key + certificate per host, for
//! Zenoh over TLS with mutual authentication (`etp run --tls DIR`,
//! `etp sensor-host --tls DIR --identity NAME`).
//!
//! DIR holds (every file mode 0600, the folder 0700):
//! * `ca.pem` — the CA every peer's certificate must chain to; `ca-key.pem`
//!   its key (only needed to issue more; keep it off the sensor hosts);
//! * `agent-host.pem` / `agent-host-key.pem` — the agent host's identity
//!   (certificate common name `agent-host`);
//! * `<host>.pem` / `<host>-key.pem` per sensor host (common name `<host>`);
//! * `hosts.json` — which sensors each sensor host may serve (empty: any
//!   remote sensor of the run); the agent host turns it into Zenoh access
//!   control rules and checks every claim against it.
//!
//! The same DIR copied to every host works; for a sensor host to hold only
//! its own identity, copy `ca.pem`, `<host>.pem`, `<host>-key.pem` and
//! `hosts.json`. An existing DIR is never overwritten without `--force`, and
//! then only once the new material is complete (written beside, renamed).

use anyhow::{Context, Result, bail};
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use std::collections::BTreeMap;
use std::io::Write;
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// Common name (and file stem) of the agent host's identity.
pub const AGENT_HOST: &str = "agent-host";

#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Clone, clap::Subcommand)]
pub enum Command {
    /// Create a CA and the keys of the agent host and the sensor hosts in DIR.
    Init(InitArgs),
}

#[derive(Debug, Clone, clap::Args)]
pub struct InitArgs {
    /// Folder to create (mode 0700; its files 0600).
    pub dir: PathBuf,
    /// A sensor host: `NAME` (may serve any remote sensor) or
    /// `NAME=s0,s1` (may serve only these). Repeat for several hosts.
    /// Names: a–z, 0–9 and -. [default: sensor-host-1]
    #[arg(long = "host", value_name = "NAME[=SENSORS]")]
    pub hosts: Vec<String>,
    /// Replace an existing DIR (the new one is complete before the old goes).
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: Args) -> Result<()> {
    match a.command {
        Command::Init(i) => init(&i),
    }
}

fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 40
        && s.bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
}

/// `NAME[=s0,s1]` → (name, sensors).
fn parse_host(spec: &str) -> Result<(String, Vec<String>)> {
    let (name, sensors) = match spec.split_once('=') {
        Some((n, s)) => (
            n,
            s.split(',')
                .filter(|x| !x.is_empty())
                .map(str::to_string)
                .collect(),
        ),
        None => (spec, Vec::new()),
    };
    if !valid_name(name) || name == AGENT_HOST {
        bail!(
            "--host `{spec}`: a host name is 1–40 characters of a–z, 0–9 and - (and not `{AGENT_HOST}`)"
        );
    }
    Ok((name.to_string(), sensors))
}

/// Write `bytes` to a new file of mode 0600 (never through a symlink).
fn write_private(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .custom_flags(libc::O_NOFOLLOW)
        .open(path)
        .with_context(|| format!("creating {}", path.display()))?;
    f.write_all(bytes)
        .and_then(|()| f.sync_all())
        .with_context(|| format!("writing {}", path.display()))
}

/// A leaf identity (server and client use: every link is mutual TLS).
fn leaf(name: &str, issuer: &Issuer<'_, KeyPair>) -> Result<(String, String)> {
    let mut p = CertificateParams::new(vec![name.to_string()])
        .with_context(|| format!("certificate of {name}"))?;
    p.distinguished_name.push(DnType::CommonName, name);
    p.distinguished_name
        .push(DnType::OrganizationName, "etpareto");
    p.key_usages = vec![
        KeyUsagePurpose::DigitalSignature,
        KeyUsagePurpose::KeyEncipherment,
    ];
    p.extended_key_usages = vec![
        ExtendedKeyUsagePurpose::ServerAuth,
        ExtendedKeyUsagePurpose::ClientAuth,
    ];
    let key = KeyPair::generate().context("generating a key")?;
    let cert = p
        .signed_by(&key, issuer)
        .with_context(|| format!("signing the certificate of {name}"))?;
    Ok((cert.pem(), key.serialize_pem()))
}

/// Create every file in `dir` (a fresh folder).
fn fill(dir: &Path, hosts: &BTreeMap<String, Vec<String>>) -> Result<()> {
    let mut ca = CertificateParams::new(Vec::<String>::new()).context("CA parameters")?;
    ca.distinguished_name
        .push(DnType::CommonName, "etpareto run CA");
    ca.distinguished_name
        .push(DnType::OrganizationName, "etpareto");
    ca.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    let ca_key = KeyPair::generate().context("generating the CA key")?;
    let ca_cert = ca.self_signed(&ca_key).context("self-signing the CA")?;
    write_private(&dir.join("ca.pem"), ca_cert.pem().as_bytes())?;
    write_private(&dir.join("ca-key.pem"), ca_key.serialize_pem().as_bytes())?;
    let issuer = Issuer::new(ca, ca_key);
    for name in std::iter::once(AGENT_HOST).chain(hosts.keys().map(String::as_str)) {
        let (cert, key) = leaf(name, &issuer)?;
        write_private(&dir.join(format!("{name}.pem")), cert.as_bytes())?;
        write_private(&dir.join(format!("{name}-key.pem")), key.as_bytes())?;
    }
    let json = serde_json::to_string_pretty(&serde_json::json!({ "hosts": hosts }))?;
    write_private(&dir.join("hosts.json"), json.as_bytes())?;
    Ok(())
}

fn init(a: &InitArgs) -> Result<()> {
    let specs = if a.hosts.is_empty() {
        vec!["sensor-host-1".to_string()]
    } else {
        a.hosts.clone()
    };
    let mut hosts = BTreeMap::new();
    for s in &specs {
        let (name, sensors) = parse_host(s)?;
        if hosts.insert(name.clone(), sensors).is_some() {
            bail!("--host `{name}` named twice");
        }
    }
    let exists = std::fs::symlink_metadata(&a.dir).is_ok();
    if exists && !a.force {
        bail!(
            "{} exists: refusing to overwrite key material (use --force to replace it)",
            a.dir.display()
        );
    }
    let name = a
        .dir
        .file_name()
        .with_context(|| format!("{}: not a folder name", a.dir.display()))?
        .to_string_lossy()
        .to_string();
    let parent = match a.dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let fresh = parent.join(format!(".{name}.new-{}", std::process::id()));
    std::fs::DirBuilder::new()
        .mode(0o700)
        .create(&fresh)
        .with_context(|| format!("creating {}", fresh.display()))?;
    if let Err(e) = fill(&fresh, &hosts) {
        let _ = std::fs::remove_dir_all(&fresh);
        return Err(e);
    }
    if exists {
        let old = parent.join(format!(".{name}.old-{}", std::process::id()));
        std::fs::rename(&a.dir, &old)
            .with_context(|| format!("moving the old {} aside", a.dir.display()))?;
        std::fs::rename(&fresh, &a.dir)
            .with_context(|| format!("renaming {} to {}", fresh.display(), a.dir.display()))?;
        let _ = std::fs::remove_dir_all(&old);
    } else {
        std::fs::rename(&fresh, &a.dir)
            .with_context(|| format!("renaming {} to {}", fresh.display(), a.dir.display()))?;
    }
    println!(
        "key material in {} (mode 0700, files 0600):",
        a.dir.display()
    );
    println!(
        "  agent host:  etp run --tls {} --listen tls/ADDR:PORT …",
        a.dir.display()
    );
    for (h, s) in &hosts {
        println!(
            "  sensor host: etp sensor-host --tls {} --identity {h} --connect tls/ADDR:PORT  (serves {}; needs ca.pem, {h}.pem, {h}-key.pem, hosts.json)",
            a.dir.display(),
            if s.is_empty() {
                "any remote sensor".to_string()
            } else {
                s.join(",")
            }
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn init_writes_private_files_and_refuses_to_overwrite() {
        let base = std::env::temp_dir().join(format!("etp-certs-unit-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        std::fs::create_dir_all(&base).expect("base");
        let dir = base.join("certs");
        let args = InitArgs {
            dir: dir.clone(),
            hosts: vec!["a=s0,s1".into(), "b".into()],
            force: false,
        };
        init(&args).expect("init");
        for f in [
            "ca.pem",
            "ca-key.pem",
            "agent-host.pem",
            "a-key.pem",
            "b.pem",
            "hosts.json",
        ] {
            let m = std::fs::metadata(dir.join(f)).expect(f);
            assert_eq!(m.permissions().mode() & 0o777, 0o600, "{f}");
        }
        let ca = std::fs::read_to_string(dir.join("ca.pem")).expect("ca");
        let e = init(&args).expect_err("exists");
        assert!(e.to_string().contains("--force"), "{e}");
        init(&InitArgs {
            force: true,
            ..args
        })
        .expect("forced");
        assert_ne!(std::fs::read_to_string(dir.join("ca.pem")).expect("ca"), ca);
        let hosts: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("hosts.json")).expect("hosts"))
                .expect("json");
        assert_eq!(hosts["hosts"]["a"], serde_json::json!(["s0", "s1"]));
        assert!(parse_host("Bad_Name").is_err());
        let _ = std::fs::remove_dir_all(&base);
    }
}
