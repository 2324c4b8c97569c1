//! Files on disk, the rule of every `etp` command: nothing existing is
//! replaced without `--force`, nothing is replaced before the work that
//! replaces it succeeded (write beside, rename), and no output follows a
//! link planted by another user or goes into another user's folder
//! (`etp_runtime::folders::output_folder`, `output_file_folder`).

use anyhow::{Context, Result, bail};
use etp_runtime::folders;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// THE overwrite rule of every command: an existing `path` is replaced only
/// with `--force`.
pub fn refuse_existing(path: &Path, force: bool) -> Result<()> {
    if path.exists() && !force {
        bail!(
            "{} already exists (use --force to overwrite)",
            path.display()
        );
    }
    Ok(())
}

/// The folder of an output file the user named (`option`: how, e.g.
/// `--record`) must exist: a mistyped path is refused by name, never
/// created silently. An empty parent is the working folder.
pub fn existing_folder_of(path: &Path, option: &str) -> Result<()> {
    let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) else {
        return Ok(());
    };
    match std::fs::metadata(parent) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => bail!(
            "{option} {}: {} is not a folder",
            path.display(),
            parent.display()
        ),
        Err(_) => bail!(
            "{option} {}: the folder {} does not exist (create it first)",
            path.display(),
            parent.display()
        ),
    }
}

/// THE rule of a folder a command writes its outputs into: created if
/// missing; a symbolic link, a folder of another user or one every user may
/// write is refused by name, never written into
/// (`etp_runtime::folders::output_folder`).
pub fn output_folder(dir: &Path) -> Result<()> {
    Ok(folders::output_folder(dir, folders::euid())?)
}

/// The temporary sibling `path` is written to before the rename (its
/// extension kept last, so writers that infer the format from it still do).
pub fn temp_sibling(path: &Path) -> PathBuf {
    let stem = path.file_stem().map_or_else(
        || "output".to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    match path.extension() {
        Some(ext) => path.with_file_name(format!("{stem}.tmp-etp.{}", ext.to_string_lossy())),
        None => path.with_file_name(format!("{stem}.tmp-etp")),
    }
}

/// Create `path` as a new, empty file of ours: `O_CREAT | O_EXCL`, which
/// never follows a link. A leftover regular file of ours (a killed earlier
/// write) is removed first; anything else there is refused by name.
pub fn create_exclusive(path: &Path) -> Result<std::fs::File> {
    let open = || {
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
    };
    match open() {
        Ok(f) => Ok(f),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            let m = std::fs::symlink_metadata(path)
                .with_context(|| format!("creating {}", path.display()))?;
            if !m.file_type().is_file() || m.uid() != folders::euid() {
                bail!(
                    "refusing to write {}: something of user {} that is not a regular file of \
                     ours is already there (a planted link?); remove it yourself",
                    path.display(),
                    m.uid()
                );
            }
            std::fs::remove_file(path)
                .with_context(|| format!("removing the leftover {}", path.display()))?;
            open().with_context(|| format!("creating {}", path.display()))
        }
        Err(e) => Err(e).with_context(|| format!("creating {}", path.display())),
    }
}

/// Produce `path` through `write(tmp)` on a temporary sibling that is then
/// renamed into place (and removed if `write` fails), so an interrupted or
/// failed write never leaves a half-written file under the final name. The
/// folder is checked (`folders::output_file_folder`) and the sibling created
/// exclusively before `write` opens it, so no planted link is followed.
pub fn write_via_temp<T>(path: &Path, write: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    folders::output_file_folder(path, folders::euid())?;
    let tmp = temp_sibling(path);
    drop(create_exclusive(&tmp)?);
    match write(&tmp) {
        Ok(v) => {
            std::fs::rename(&tmp, path)
                .with_context(|| format!("moving {} into place", path.display()))?;
            Ok(v)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Write `bytes` to `path`, refusing to replace an existing file unless `force`.
pub fn write_new(path: &Path, bytes: &[u8], force: bool) -> Result<()> {
    refuse_existing(path, force)?;
    write_via_temp(path, |tmp| {
        std::fs::write(tmp, bytes).with_context(|| format!("writing {}", tmp.display()))
    })
}
