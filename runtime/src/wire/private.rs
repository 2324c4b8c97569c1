//! The per-user private folder every path of a run lives under.
//!
//! `/tmp` is shared by every user: a fixed folder there (`/tmp/etp-run`)
//! can be created first by another user, or be a symlink they planted, and
//! whatever etp then creates or deletes inside lands where they point. So
//! every run folder, iceoryx2 root and sensor-host folder lives under one
//! folder that belongs to the user alone:
//!
//! * `$XDG_RUNTIME_DIR/etp` when `$XDG_RUNTIME_DIR` is an absolute path to a
//!   real folder (not a symlink) owned by this user with mode 0700 (what
//!   systemd-logind gives every login session);
//! * else `$TMPDIR/etp-<uid>` (`/tmp/etp-<uid>`).
//!
//! The folder is created with `mkdir(…, 0700)` — which never follows a
//! symlink in its last component and fails if the name exists — and then
//! checked with `lstat`: it must be a real folder, owned by this user, with
//! no permission for group or others. Anything else (a symlink, a folder
//! owned by someone else, a loose mode) is refused with an error naming the
//! path; nothing is created inside. Once checked, the folder is safe to use
//! by name: `/tmp` is sticky (nobody else can rename or remove it) and
//! nobody else can write inside it, so nothing below it can be planted.

use super::WireError;
use std::os::unix::fs::{DirBuilderExt, MetadataExt};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// This process's effective user id.
pub fn uid() -> u32 {
    rustix::process::geteuid().as_raw()
}

/// Is `p` a real folder (not a symlink) owned by this user, mode `0?00`?
fn check_private(p: &Path) -> Result<(), String> {
    let m = std::fs::symlink_metadata(p).map_err(|e| format!("{}: {e}", p.display()))?;
    if m.file_type().is_symlink() {
        return Err(format!("{} is a symlink", p.display()));
    }
    if !m.is_dir() {
        return Err(format!("{} is not a folder", p.display()));
    }
    if m.uid() != uid() {
        return Err(format!(
            "{} belongs to uid {}, not to this user (uid {})",
            p.display(),
            m.uid(),
            uid()
        ));
    }
    if m.mode() & 0o077 != 0 {
        return Err(format!(
            "{} has mode {:o}: group or others may use it (want 700)",
            p.display(),
            m.mode() & 0o777
        ));
    }
    Ok(())
}

/// Create `p` with mode 0700 if missing (never through a symlink), then
/// check it is private.
pub fn ensure_private(p: &Path) -> Result<(), String> {
    match std::fs::DirBuilder::new().mode(0o700).create(p) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(format!("creating {}: {e}", p.display())),
    }
    check_private(p)
}

/// Where the private folder is (not yet checked: see [`base`]).
pub fn base_path() -> PathBuf {
    if let Some(x) = std::env::var_os("XDG_RUNTIME_DIR").map(PathBuf::from)
        && x.is_absolute()
        && check_private(&x).is_ok()
    {
        return x.join("etp");
    }
    std::env::temp_dir().join(format!("etp-{}", uid()))
}

/// The user's private folder, created and checked once per process.
pub fn base() -> Result<PathBuf, WireError> {
    static BASE: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    BASE.get_or_init(|| {
        let b = base_path();
        ensure_private(&b).map(|()| b)
    })
    .clone()
    .map_err(|e| WireError::Private(format!("{e} (etp keeps its run folders there; remove it or set XDG_RUNTIME_DIR to a folder of your own)")))
}

/// A checked private sub-folder of [`base`] (`run`, `iox2`, `sensor-host`).
pub fn sub(name: &str) -> Result<PathBuf, WireError> {
    let p = base()?.join(name);
    ensure_private(&p).map_err(WireError::Private)?;
    Ok(p)
}

/// Folder of the runs' private folders (`<base>/run`).
pub fn runs() -> Result<PathBuf, WireError> {
    sub("run")
}

/// Is the entry at `p` a real folder (never following a symlink) owned by
/// this user? Only such entries are ever removed by a stale-run sweep.
pub fn owned_folder(p: &Path) -> bool {
    std::fs::symlink_metadata(p)
        .is_ok_and(|m| m.file_type().is_dir() && !m.file_type().is_symlink() && m.uid() == uid())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("etp-private-unit-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir(&d).expect("scratch");
        d
    }

    #[test]
    fn a_fresh_folder_is_made_private_and_a_loose_one_refused() {
        let d = scratch("mode");
        let p = d.join("b");
        ensure_private(&p).expect("made");
        assert_eq!(
            std::fs::metadata(&p).expect("meta").permissions().mode() & 0o777,
            0o700
        );
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o777)).expect("chmod");
        let e = ensure_private(&p).expect_err("loose mode");
        assert!(e.contains("mode 777"), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_symlink_is_refused_and_never_followed() {
        let d = scratch("link");
        let victim = d.join("victim");
        std::fs::create_dir(&victim).expect("victim");
        std::fs::set_permissions(&victim, std::fs::Permissions::from_mode(0o700)).expect("chmod");
        let p = d.join("b");
        std::os::unix::fs::symlink(&victim, &p).expect("plant");
        let e = ensure_private(&p).expect_err("a symlink");
        assert!(e.contains("symlink"), "{e}");
        assert!(!owned_folder(&p));
        assert!(owned_folder(&victim));
        let _ = std::fs::remove_dir_all(&d);
    }
}
