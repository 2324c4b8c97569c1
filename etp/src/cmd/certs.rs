//! `etp certs init DIR [--sensor-host NAME …]`: the key material of an
//! authenticated, encrypted run across hosts (`--tls DIR` on `etp run` and
//! `etp sensor-host`), made with rcgen. The folder layout and its checks are
//! `etp_runtime::link_keys`.
//!
//! A fresh CA signs one certificate for the agent host (TLS server only) and
//! one per sensor host (TLS client only); the CA's private key is dropped
//! once they are signed, so nobody can add a certificate to this folder
//! later. DIR holds one bundle per host, each to be copied to its host
//! only: `DIR/agent-host/` (CA certificate, the agent host's key pair,
//! `hosts.json`) and `DIR/NAME/` per sensor host (CA certificate, its own
//! key pair). The folder is made beside its final name and renamed into
//! place: an existing folder is replaced only with `--force`, and only once
//! the new one is complete.

use anyhow::{Context, Result, bail};
use etp_runtime::link_keys::{
    self, AGENT_HOST, CA_CERTIFICATE, DEFAULT_SENSOR_HOST, check_name, common_name, files_of,
};
use rcgen::{
    BasicConstraints, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa,
    Issuer, KeyPair, KeyUsagePurpose,
};
use std::io::Write;
use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: Sub,
}

#[derive(Debug, clap::Subcommand)]
pub enum Sub {
    /// Make DIR: a CA, the agent host's key pair and one per sensor host,
    /// one bundle per host (DIR/agent-host/, DIR/NAME/): copy each bundle to
    /// its host only.
    Init(InitArgs),
}

#[derive(Debug, clap::Args)]
pub struct InitArgs {
    /// The folder to make (mode 0700; private keys 0600).
    pub dir: PathBuf,
    /// A sensor host: its name (files NAME.pem/NAME.key; `etp sensor-host
    /// --tls DIR --name NAME`) and, after `=`, the only sensors it may serve
    /// (`b=s1,s3`; without: any remote sensor). Repeat for several
    /// [default: sensor-host].
    #[arg(long = "sensor-host", value_name = "NAME[=SENSORS]")]
    pub sensor_hosts: Vec<String>,
    /// Days the certificates are valid (1 to 3650).
    #[arg(long, default_value_t = 365, value_parser = crate::values::whole::<u32>(1, Some(3650)))]
    pub days: u32,
    /// Replace an existing DIR (once the new one is complete).
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> Result<()> {
    match a.command {
        Sub::Init(i) => init(i),
    }
}

fn init(a: InitArgs) -> Result<()> {
    let mut given = a.sensor_hosts.clone();
    if given.is_empty() {
        given.push(DEFAULT_SENSOR_HOST.to_string());
    }
    let mut map = link_keys::Hosts::new();
    for g in &given {
        let (name, sensors) = match g.split_once('=') {
            Some((n, list)) => {
                let list: Vec<String> = list
                    .split(',')
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .map(str::to_string)
                    .collect();
                if list.is_empty() {
                    bail!("--sensor-host `{g}`: no sensor after `=`");
                }
                (n, Some(list))
            }
            None => (g.as_str(), None),
        };
        check_name(name).context("--sensor-host")?;
        if name == AGENT_HOST {
            bail!("--sensor-host: `{AGENT_HOST}` is the agent host's name");
        }
        if map.insert(name.to_string(), sensors).is_some() {
            bail!("--sensor-host: `{name}` is given twice");
        }
    }
    let hosts: Vec<String> = map.keys().cloned().collect();
    let me = etp_files::folders::euid();
    etp_files::folders::check_ancestors(&a.dir, me)?;
    if let Ok(m) = std::fs::symlink_metadata(&a.dir) {
        if !a.force {
            bail!(
                "{} already exists (use --force to replace it)",
                a.dir.display()
            );
        }
        // Even with --force: a planted link or another user's folder is
        // never moved or removed (output folders' rule).
        use std::os::unix::fs::MetadataExt;
        if m.file_type().is_symlink() || !m.is_dir() || m.uid() != me {
            bail!(
                "refusing to replace {}: it is {}, not a folder of user {me}; remove it yourself",
                a.dir.display(),
                if m.file_type().is_symlink() {
                    "a symbolic link".to_string()
                } else if !m.is_dir() {
                    "not a folder".to_string()
                } else {
                    format!("owned by user {}", m.uid())
                }
            );
        }
    }
    let mut files = material(&hosts, a.days).context("making the certificates")?;
    files.push((
        format!("{AGENT_HOST}/{}", link_keys::HOSTS),
        serde_json::to_string_pretty(&map)?,
        false,
    ));
    let parent = a
        .dir
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).with_context(|| format!("creating {}", parent.display()))?;
    let name = a
        .dir
        .file_name()
        .and_then(|n| n.to_str())
        .context("DIR has no folder name")?;
    let fresh = parent.join(format!(".{name}.new-{}", std::process::id()));
    let written = write_folder(&fresh, &files);
    if let Err(e) = written {
        let _ = std::fs::remove_dir_all(&fresh);
        return Err(e);
    }
    // Rename into place; an old folder is moved aside first and removed
    // only after the new one is in place.
    let old = parent.join(format!(".{name}.old-{}", std::process::id()));
    let had_old = std::fs::symlink_metadata(&a.dir).is_ok();
    if had_old {
        std::fs::rename(&a.dir, &old)
            .with_context(|| format!("moving the old {} aside", a.dir.display()))?;
    }
    if let Err(e) = std::fs::rename(&fresh, &a.dir) {
        if had_old {
            let _ = std::fs::rename(&old, &a.dir);
        }
        let _ = std::fs::remove_dir_all(&fresh);
        return Err(e).with_context(|| format!("renaming into {}", a.dir.display()));
    }
    if had_old {
        // Checked above: a folder of ours (no link is ever followed).
        std::fs::remove_dir_all(&old)
            .with_context(|| format!("removing the old folder {}", old.display()))?;
    }
    let names: Vec<&str> = files.iter().map(|(n, _, _)| n.as_str()).collect();
    let bundles: Vec<(String, String)> = std::iter::once(AGENT_HOST.to_string())
        .chain(hosts.iter().cloned())
        .map(|h| (h.clone(), a.dir.join(&h).display().to_string()))
        .collect();
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "dir": a.dir.display().to_string(),
                "agent_host": AGENT_HOST,
                "sensor_hosts": map,
                "bundles": bundles.iter().cloned().collect::<std::collections::BTreeMap<_, _>>(),
                "files": names,
                "days": a.days,
            }))?
        );
    } else {
        println!(
            "wrote {}: one bundle per host, copy each to its host only:",
            a.dir.display()
        );
        for (h, path) in &bundles {
            if h == AGENT_HOST {
                println!("  {path}/ → the agent host (`etp run … --tls {path}`)");
            } else {
                println!(
                    "  {path}/ → sensor host {h} (`etp sensor-host … --tls {path} --name {h}`)"
                );
            }
        }
    }
    Ok(())
}

/// (file name, contents, private) of the whole folder.
type Files = Vec<(String, String, bool)>;

fn material(hosts: &[String], days: u32) -> Result<Files> {
    let now = time::OffsetDateTime::now_utc();
    let validity = |p: &mut CertificateParams| {
        // An hour back: a host whose clock is a little behind still accepts.
        p.not_before = now - time::Duration::hours(1);
        p.not_after = now + time::Duration::days(i64::from(days));
    };
    let ca_key = KeyPair::generate()?;
    let mut ca = CertificateParams::new(Vec::<String>::new())?;
    ca.distinguished_name = DistinguishedName::new();
    ca.distinguished_name.push(DnType::CommonName, "etp run CA");
    ca.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    validity(&mut ca);
    let ca_cert = ca.self_signed(&ca_key)?;
    let issuer = Issuer::new(ca, ca_key);
    let mut out: Files = Vec::new();
    let mut leaf = |name: &str, server: bool| -> Result<()> {
        let key = KeyPair::generate()?;
        // The agent host is reached by address (name checks are off on the
        // link; the CA and the key usage decide), so its SAN is its name.
        let mut p = CertificateParams::new(vec![name.to_string()])?;
        p.distinguished_name = DistinguishedName::new();
        p.distinguished_name
            .push(DnType::CommonName, common_name(name));
        p.is_ca = IsCa::ExplicitNoCa;
        p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        p.extended_key_usages = vec![if server {
            ExtendedKeyUsagePurpose::ServerAuth
        } else {
            ExtendedKeyUsagePurpose::ClientAuth
        }];
        validity(&mut p);
        let cert = p.signed_by(&key, &issuer)?;
        let (c, k) = files_of(name);
        out.push((format!("{name}/{CA_CERTIFICATE}"), ca_cert.pem(), false));
        out.push((format!("{name}/{c}"), cert.pem(), false));
        out.push((format!("{name}/{k}"), key.serialize_pem(), true));
        Ok(())
    };
    leaf(AGENT_HOST, true)?;
    for h in hosts {
        leaf(h, false)?;
    }
    Ok(out)
}

fn write_folder(dir: &Path, files: &Files) -> Result<()> {
    std::fs::create_dir(dir).with_context(|| format!("creating {}", dir.display()))?;
    std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700))?;
    for (name, text, private) in files {
        let path = dir.join(name);
        if let Some(bundle) = path.parent().filter(|b| !b.exists()) {
            std::fs::create_dir(bundle)
                .with_context(|| format!("creating {}", bundle.display()))?;
            std::fs::set_permissions(bundle, std::fs::Permissions::from_mode(0o700))?;
        }
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(if *private { 0o600 } else { 0o644 })
            .custom_flags(libc::O_NOFOLLOW)
            .open(&path)
            .with_context(|| format!("creating {}", path.display()))?;
        f.write_all(text.as_bytes())
            .and_then(|()| f.sync_all())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
