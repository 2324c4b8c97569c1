//! The user's private folders: where a run keeps its iceoryx2 root (`iox2/`),
//! `etp run` its run folders (`run/`) and `etp sensor-host` its domains
//! (`sensor-host/`).
//!
//! Nothing of a run lives in a folder shared with other users: a shared,
//! world-writable `/tmp/etp-…` lets another user plant a symlink that our
//! stale-run cleanup would follow (deleting what it points at) or a folder we
//! would write into. The base is, in this order, `$ETP_RUNTIME_DIR`,
//! `$XDG_RUNTIME_DIR/etp`, or `/tmp/etp-<uid>`; it and each folder in it
//! are created with mode 0700 and then checked without following links
//! (`symlink_metadata`): a real folder, owned by this process's user, with
//! no access for group or others. Anything else is refused with an error
//! naming the path — never followed, never removed. Below a checked folder
//! only its owner can create entries, so nothing deeper can be planted.

use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

/// Environment variable that names the base folder explicitly.
pub const RUNTIME_DIR_ENV: &str = "ETP_RUNTIME_DIR";

/// Why a private folder cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum FolderError {
    #[error(
        "`{path}` is not a private folder of user {uid}: {why}; nothing there is followed or \
         removed — remove it yourself, or set {RUNTIME_DIR_ENV} to a folder of yours"
    )]
    NotPrivate {
        path: PathBuf,
        uid: u32,
        why: String,
    },
    #[error("creating `{path}`: {source}")]
    Create {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The effective user id of this process (the owner of `/proc/self`).
pub fn euid() -> u32 {
    std::fs::metadata("/proc/self").map_or(u32::MAX, |m| m.uid())
}

/// The base folder (not created or checked: [`private`] does that).
pub fn base() -> PathBuf {
    if let Some(d) = std::env::var_os(RUNTIME_DIR_ENV).filter(|d| !d.is_empty()) {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_RUNTIME_DIR").filter(|d| !d.is_empty()) {
        let d = PathBuf::from(d);
        // Only a runtime folder that is really ours (systemd's is 0700).
        if check(&d, euid()).is_ok() {
            return d.join("etp");
        }
    }
    PathBuf::from(format!("/tmp/etp-{}", euid()))
}

/// `base()/name`, the base and it created (mode 0700) if missing and both
/// checked (see the module doc).
pub fn private(name: &str) -> Result<PathBuf, FolderError> {
    let base = base();
    ensure(&base, euid())?;
    let dir = base.join(name);
    ensure(&dir, euid())?;
    Ok(dir)
}

/// Create `path` (mode 0700; its parent must exist) unless it exists, then
/// [`check`] it for user `uid`.
pub fn ensure(path: &Path, uid: u32) -> Result<(), FolderError> {
    match std::fs::DirBuilder::new().mode(0o700).create(path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(source) => {
            return Err(FolderError::Create {
                path: path.to_path_buf(),
                source,
            });
        }
    }
    check(path, uid)
}

/// Is `path` (not followed if a link) a folder owned by `uid` with no
/// access for group or others?
pub fn check(path: &Path, uid: u32) -> Result<(), FolderError> {
    let refuse = |why: String| FolderError::NotPrivate {
        path: path.to_path_buf(),
        uid,
        why,
    };
    let m = std::fs::symlink_metadata(path).map_err(|e| refuse(e.to_string()))?;
    if m.file_type().is_symlink() {
        return Err(refuse("it is a symbolic link".into()));
    }
    if !m.is_dir() {
        return Err(refuse("it is not a folder".into()));
    }
    if m.uid() != uid {
        return Err(refuse(format!("it is owned by user {}", m.uid())));
    }
    let mode = m.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        return Err(refuse(format!(
            "its mode is {mode:o} (group or others have access)"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("etp-folders-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("scratch");
        d
    }

    #[test]
    fn a_missing_folder_is_made_private_and_a_private_one_is_kept() {
        let d = scratch("make");
        let p = d.join("base");
        ensure(&p, euid()).expect("created");
        let m = std::fs::symlink_metadata(&p).expect("exists");
        assert_eq!(m.permissions().mode() & 0o777, 0o700);
        std::fs::write(p.join("kept"), b"x").expect("write");
        ensure(&p, euid()).expect("still ours");
        assert!(p.join("kept").exists());
        let _ = std::fs::remove_dir_all(&d);
    }

    /// A planted symlink (to a victim folder), a folder open to others and
    /// a folder of another user are refused by name; the victim is untouched.
    #[test]
    fn planted_links_open_folders_and_foreign_owners_are_refused() {
        let d = scratch("plant");
        let victim = d.join("victim");
        std::fs::create_dir(&victim).expect("victim");
        std::fs::write(victim.join("precious"), b"x").expect("write");
        let link = d.join("link");
        symlink(&victim, &link).expect("symlink");
        let e = ensure(&link, euid()).expect_err("a link is refused");
        assert!(e.to_string().contains("symbolic link"), "{e}");
        assert!(victim.join("precious").exists());
        let open = d.join("open");
        std::fs::create_dir(&open).expect("dir");
        std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o777)).expect("chmod");
        let e = ensure(&open, euid()).expect_err("mode 777 is refused");
        assert!(e.to_string().contains("mode is 777"), "{e}");
        let e = ensure(&victim, euid().wrapping_add(1)).expect_err("another owner is refused");
        assert!(e.to_string().contains("owned by user"), "{e}");
        let file = d.join("file");
        std::fs::write(&file, b"x").expect("write");
        assert!(ensure(&file, euid()).is_err());
        let _ = std::fs::remove_dir_all(&d);
    }
}
