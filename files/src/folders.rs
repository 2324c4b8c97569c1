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

/// Why a command may not write where it was told (an output folder, or the
/// folder of an output file).
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error(
        "refusing to write into `{path}`: {why}; outputs never follow a link or go into a \
         folder of another user — choose another path"
    )]
    Refused { path: PathBuf, why: String },
    #[error("creating `{path}`: {source}")]
    Create {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The existing ancestors of `path` may be followed and nothing on the way
/// can be swapped by another user: no ancestor is a symbolic link of another
/// user than `uid` or root, and neither an ancestor nor `path` lies in a
/// folder every user may write without the sticky bit (there anybody could
/// rename it and plant a link in its place after this check). Missing
/// ancestors are not checked: this process creates them.
pub fn check_ancestors(path: &Path, uid: u32) -> Result<(), OutputError> {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(|source| OutputError::Create {
                path: path.to_path_buf(),
                source,
            })?
            .join(path)
    };
    let refuse = |p: &Path, why: String| OutputError::Refused {
        path: p.to_path_buf(),
        why,
    };
    let mut prefix = PathBuf::new();
    let parts: Vec<_> = abs.components().collect();
    for (i, c) in parts.iter().enumerate() {
        let container = prefix.clone();
        prefix.push(c);
        if !container.as_os_str().is_empty() {
            let Ok(cm) = std::fs::metadata(&container) else {
                return Ok(()); // missing from here on: this process creates it
            };
            let mode = cm.permissions().mode();
            if mode & 0o002 != 0 && mode & 0o1000 == 0 {
                return Err(refuse(
                    &prefix,
                    format!(
                        "it lies in `{}`, which every user may write (mode {:o}, no sticky \
                         bit): another user could replace it after this check",
                        container.display(),
                        mode & 0o7777
                    ),
                ));
            }
        }
        if i + 1 == parts.len() {
            break; // `path` itself: its caller's rule
        }
        let Ok(m) = std::fs::symlink_metadata(&prefix) else {
            return Ok(());
        };
        if m.file_type().is_symlink() && m.uid() != uid && m.uid() != 0 {
            return Err(refuse(
                &prefix,
                format!("it is a symbolic link of user {}", m.uid()),
            ));
        }
    }
    Ok(())
}

/// Is `path` (not followed) a folder of user `uid` that not every user may
/// write? What an output folder must be.
fn check_output(path: &Path, uid: u32) -> Result<(), OutputError> {
    let refuse = |why: String| OutputError::Refused {
        path: path.to_path_buf(),
        why,
    };
    let m = std::fs::symlink_metadata(path).map_err(|e| refuse(e.to_string()))?;
    if m.file_type().is_symlink() {
        let to = std::fs::read_link(path).map_or_else(|_| "?".into(), |t| t.display().to_string());
        return Err(refuse(format!(
            "it is a symbolic link (to `{to}`, owned by user {})",
            m.uid()
        )));
    }
    if !m.is_dir() {
        return Err(refuse("it is not a folder".into()));
    }
    if m.uid() != uid {
        return Err(refuse(format!(
            "it is owned by user {}, not by user {uid}",
            m.uid()
        )));
    }
    let mode = m.permissions().mode() & 0o7777;
    if mode & 0o002 != 0 {
        return Err(refuse(format!(
            "its mode is {mode:o}: every user may write in it"
        )));
    }
    Ok(())
}

/// THE rule of every folder a command writes its outputs into (`etp replay
/// export DIR`, `synthesize -o DIR`, `fronts -o DIR`, …): its ancestors pass
/// [`check_ancestors`]; a missing folder is created (its missing parents
/// too; the last step with `mkdir`, which never follows a link); then it
/// must be, not followed, a real folder owned by user `uid` that not every
/// user may write. A planted link or another user's folder is refused by
/// name, never written into.
pub fn output_folder(path: &Path, uid: u32) -> Result<(), OutputError> {
    check_ancestors(path, uid)?;
    if std::fs::symlink_metadata(path).is_err() {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|source| OutputError::Create {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        match std::fs::DirBuilder::new().create(path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(source) => {
                return Err(OutputError::Create {
                    path: path.to_path_buf(),
                    source,
                });
            }
        }
    }
    check_output(path, uid)
}

/// The folder of an output file `path`: [`check_ancestors`] of the file
/// (so its folder is not another user's link and cannot be swapped), the
/// folder created if missing. The file itself is written beside and renamed
/// (a rename replaces a link, never follows it).
pub fn output_file_folder(path: &Path, uid: u32) -> Result<(), OutputError> {
    check_ancestors(path, uid)?;
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| OutputError::Create {
            path: parent.to_path_buf(),
            source,
        })?;
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
