//! Run ids and the per-run iceoryx2 configuration: a run's id names its
//! services, shared-memory prefix and root folder, so two runs never see
//! each other.

use super::WireError;
use iceoryx2::config::Config;
use iceoryx2::prelude::*;
use std::path::PathBuf;

/// Folder of the user's private base (`etp_files::folders`) under which every
/// run keeps its iceoryx2 root (`<base>/iox2/<run-id>/`).
pub const ROOT_FOLDER: &str = "iox2";

/// A run id: 1–40 characters of `[a-z0-9-]`. It names the services
/// (`etp/<run-id>/…`), the shared-memory prefix and the root folder, so two
/// runs never see each other.
///
/// A run spanning hosts has one id everywhere (it is in every header), and
/// each host its own iceoryx2 domain; two hosts' domains on one machine
/// (`etp sensor-host` beside `etp run`) are kept apart by [`IPC_DOMAIN_ENV`],
/// which suffixes the prefix and root folder, never the id or its tag.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct RunId {
    id: String,
    domain: Option<String>,
}

/// Environment variable naming the iceoryx2 domain of this host's part of a
/// run (`[a-z0-9-]`, set by `etp sensor-host` for itself and its sensors).
pub const IPC_DOMAIN_ENV: &str = "ETP_IPC_DOMAIN";

fn valid_id(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 40
        && s.bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
}

impl RunId {
    /// The id `s` in this process's domain ([`IPC_DOMAIN_ENV`], if set).
    pub fn new(s: &str) -> Result<Self, WireError> {
        let domain = std::env::var(IPC_DOMAIN_ENV).ok().filter(|d| !d.is_empty());
        Self::in_domain(s, domain.as_deref())
    }

    /// The id `s` in iceoryx2 domain `domain` (`None`: the default one).
    pub fn in_domain(s: &str, domain: Option<&str>) -> Result<Self, WireError> {
        if !valid_id(s) {
            return Err(WireError::RunId(s.to_string()));
        }
        if let Some(d) = domain
            && !valid_id(d)
        {
            return Err(WireError::RunId(format!("{s} (domain `{d}`)")));
        }
        Ok(Self {
            id: s.to_string(),
            domain: domain.map(str::to_string),
        })
    }

    /// The run of a root folder name (`<id>` or `<id>.<domain>`).
    pub fn from_folder(name: &str) -> Result<Self, WireError> {
        match name.split_once('.') {
            Some((id, d)) => Self::in_domain(id, Some(d)),
            None => Self::in_domain(name, None),
        }
    }

    /// A fresh id from the clock and the process id.
    pub fn generate() -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        let mixed = etp_shared::rng::mix64(nanos ^ (u64::from(std::process::id()) << 32));
        Self {
            id: format!("r{:012x}", mixed & 0xFFFF_FFFF_FFFF),
            domain: std::env::var(IPC_DOMAIN_ENV).ok().filter(|d| valid_id(d)),
        }
    }

    pub fn as_str(&self) -> &str {
        &self.id
    }

    /// The 64-bit tag carried in every [`super::Header`] (of the id only:
    /// the same on every host of the run).
    pub fn tag(&self) -> u64 {
        self.id.bytes().fold(0x45_54_50_u64, |h, b| {
            etp_shared::rng::mix64(h ^ u64::from(b))
        })
    }

    fn local_name(&self) -> String {
        match &self.domain {
            Some(d) => format!("{}.{d}", self.id),
            None => self.id.clone(),
        }
    }

    /// Shared-memory file prefix (`_` and `.` cannot occur in an id, so no
    /// prefix of one run or domain is a prefix of another's).
    pub fn shm_prefix(&self) -> String {
        format!("etp_{}_", self.local_name())
    }

    /// The run's iceoryx2 root folder, in the user's private folder
    /// ([`config`] creates and checks that folder).
    pub fn root_dir(&self) -> PathBuf {
        etp_files::folders::base()
            .join(ROOT_FOLDER)
            .join(self.local_name())
    }
}

impl std::fmt::Display for RunId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.id)
    }
}

/// The iceoryx2 configuration of a run: its own prefix and root path, built in
/// code (no config file is read, whatever the working directory). The root
/// lies in the user's private folder, created and checked here (a planted
/// link or a folder of another user is refused, never followed).
pub fn config(run: &RunId) -> Result<Config, WireError> {
    etp_files::folders::private(ROOT_FOLDER).map_err(|e| WireError::Config(e.to_string()))?;
    let mut cfg = Config::default();
    cfg.global.prefix = FileName::new(run.shm_prefix().as_bytes())
        .map_err(|e| WireError::Config(format!("prefix: {e:?}")))?;
    let root = format!("{}/", run.root_dir().display());
    let path =
        Path::new(root.as_bytes()).map_err(|e| WireError::Config(format!("root {root}: {e:?}")))?;
    cfg.global.set_root_path(&path);
    Ok(cfg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::ServiceId;

    #[test]
    fn run_ids_are_checked_and_prefixes_do_not_nest() {
        assert!(RunId::new("t-1").is_ok());
        assert!(RunId::new("").is_err());
        assert!(RunId::new("A").is_err());
        assert!(RunId::new("a_b").is_err());
        let a = RunId::new("a").expect("valid");
        let ab = RunId::new("a-b").expect("valid");
        assert!(!ab.shm_prefix().starts_with(&a.shm_prefix()));
        assert_ne!(a.tag(), ab.tag());
        assert_eq!(ServiceId::Truth(3).name(&a), "etp/a/sensor/3/truth");
        assert!(RunId::new(RunId::generate().as_str()).is_ok());
    }
}
