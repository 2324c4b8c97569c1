//! Files on disk, the rule of every `etp` command: nothing existing is
//! replaced without `--force`, and nothing is replaced before the work that
//! replaces it succeeded (write beside, rename).

use anyhow::{Context, Result, bail};
use std::path::Path;

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

/// Produce `path` through `write(tmp)` on a temporary sibling that is then
/// renamed into place (and removed if `write` fails), so an interrupted or
/// failed write never leaves a half-written file under the final name.
pub fn write_via_temp<T>(path: &Path, write: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let tmp = path.with_extension("tmp-etp");
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
