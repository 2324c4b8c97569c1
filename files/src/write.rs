//! Files on disk, the rule of every `etp` command: nothing existing is
//! replaced without `--force`, nothing is replaced before the work that
//! replaces it succeeded (write beside, rename), and no output follows a
//! link planted by another user or goes into another user's folder
//! ([`folders::output_folder`], [`folders::output_file_folder`]).

use crate::folders::{self, OutputError};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// Why an output was not written. The text is what `etp` prints after
/// `error: ` (with the I/O cause after `: `).
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The output exists and `--force` was not given.
    #[error("{} already exists (use --force to overwrite)", .0.display())]
    Exists(PathBuf),
    /// A folder stands where the output file goes: `--force` would not
    /// replace it (a file is never renamed over a folder), so it is refused
    /// as what it is, with or without `--force`.
    #[error("{} is a folder; name the file to write (e.g. {})", .0.display(), .0.join("NAME").display())]
    IsFolder(PathBuf),
    /// The folder of an output file the user named is missing or not a
    /// folder (`option`: how the file was named, e.g. `--record`).
    #[error("{option} {}: {}", path.display(), why_folder(parent, *missing))]
    NoFolder {
        option: String,
        path: PathBuf,
        parent: PathBuf,
        /// Missing, rather than something that is not a folder.
        missing: bool,
    },
    /// The folder may not be written into (a link, another user's folder).
    #[error(transparent)]
    Folder(#[from] OutputError),
    /// Something that is not a regular file of ours stands where the
    /// temporary sibling goes.
    #[error(
        "refusing to write {}: something of user {owner} that is not a regular file of \
         ours is already there (a planted link?); remove it yourself",
        path.display()
    )]
    Planted { path: PathBuf, owner: u32 },
    /// The file system refused (`what`: the operation and its path).
    #[error("{what}")]
    Io {
        what: String,
        #[source]
        source: std::io::Error,
    },
}

fn why_folder(parent: &Path, missing: bool) -> String {
    if missing {
        format!(
            "the folder {} does not exist (create it first)",
            parent.display()
        )
    } else {
        format!("{} is not a folder", parent.display())
    }
}

/// An I/O error with the operation and path it happened on.
fn io(what: String) -> impl FnOnce(std::io::Error) -> WriteError {
    move |source| WriteError::Io { what, source }
}

/// THE overwrite rule of every command: an existing `path` is replaced only
/// with `--force`.
pub fn refuse_existing(path: &Path, force: bool) -> Result<(), WriteError> {
    if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
        return Err(WriteError::IsFolder(path.to_path_buf()));
    }
    if path.exists() && !force {
        return Err(WriteError::Exists(path.to_path_buf()));
    }
    Ok(())
}

/// The folder of an output file the user named (`option`: how, e.g.
/// `--record`) must exist: a mistyped path is refused by name, never
/// created silently. An empty parent is the working folder.
pub fn existing_folder_of(path: &Path, option: &str) -> Result<(), WriteError> {
    let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) else {
        return Ok(());
    };
    let refuse = |missing| WriteError::NoFolder {
        option: option.to_string(),
        path: path.to_path_buf(),
        parent: parent.to_path_buf(),
        missing,
    };
    match std::fs::metadata(parent) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(refuse(false)),
        Err(_) => Err(refuse(true)),
    }
}

/// THE rule of a folder a command writes its outputs into: created if
/// missing; a symbolic link, a folder of another user or one every user may
/// write is refused by name, never written into
/// ([`folders::output_folder`]).
pub fn output_folder(dir: &Path) -> Result<(), WriteError> {
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
pub fn create_exclusive(path: &Path) -> Result<std::fs::File, WriteError> {
    let open = || {
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
    };
    let creating = || format!("creating {}", path.display());
    match open() {
        Ok(f) => Ok(f),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            let m = std::fs::symlink_metadata(path).map_err(io(creating()))?;
            if !m.file_type().is_file() || m.uid() != folders::euid() {
                return Err(WriteError::Planted {
                    path: path.to_path_buf(),
                    owner: m.uid(),
                });
            }
            std::fs::remove_file(path)
                .map_err(io(format!("removing the leftover {}", path.display())))?;
            open().map_err(io(creating()))
        }
        Err(e) => Err(io(creating())(e)),
    }
}

/// Produce `path` through `write(tmp)` on a temporary sibling that is then
/// renamed into place (and removed if `write` fails), so an interrupted or
/// failed write never leaves a half-written file under the final name. The
/// folder is checked ([`folders::output_file_folder`]) and the sibling
/// created exclusively before `write` opens it, so no planted link is
/// followed. `write`'s own error type is kept (it only has to take a
/// [`WriteError`]).
pub fn write_via_temp<T, E: From<WriteError>>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<T, E>,
) -> Result<T, E> {
    folders::output_file_folder(path, folders::euid()).map_err(WriteError::from)?;
    let tmp = temp_sibling(path);
    drop(create_exclusive(&tmp)?);
    match write(&tmp) {
        Ok(v) => {
            std::fs::rename(&tmp, path)
                .map_err(io(format!("moving {} into place", path.display())))?;
            Ok(v)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Write `bytes` to `path`, refusing to replace an existing file unless `force`.
pub fn write_new(path: &Path, bytes: &[u8], force: bool) -> Result<(), WriteError> {
    refuse_existing(path, force)?;
    write_via_temp(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(io(format!("writing {}", tmp.display())))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("etp-files-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("a scratch folder");
        d
    }

    /// The texts `etp` prints for each refusal, with the I/O cause after
    /// `: ` as `{:#}` of anyhow shows a source.
    #[test]
    fn refusals_name_the_path_and_what_to_do() {
        let d = scratch("refusals");
        let f = d.join("a.json");
        std::fs::write(&f, b"{}").expect("write");
        let e = refuse_existing(&f, false).expect_err("exists");
        assert_eq!(
            e.to_string(),
            format!("{} already exists (use --force to overwrite)", f.display())
        );
        refuse_existing(&f, true).expect("--force");
        for force in [false, true] {
            let e = refuse_existing(&d, force).expect_err("a folder");
            assert_eq!(
                e.to_string(),
                format!(
                    "{} is a folder; name the file to write (e.g. {})",
                    d.display(),
                    d.join("NAME").display()
                )
            );
        }
        let e = existing_folder_of(&d.join("nope/x.mcap"), "--record").expect_err("missing");
        assert_eq!(
            e.to_string(),
            format!(
                "--record {}: the folder {} does not exist (create it first)",
                d.join("nope/x.mcap").display(),
                d.join("nope").display()
            )
        );
        let e = existing_folder_of(&f.join("x.mcap"), "-o").expect_err("a file");
        assert_eq!(
            e.to_string(),
            format!(
                "-o {}: {} is not a folder",
                f.join("x.mcap").display(),
                f.display()
            )
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    /// A failed write leaves neither the file nor its sibling; a good one
    /// replaces only with `force`.
    #[test]
    fn written_beside_and_renamed() {
        let d = scratch("beside");
        let f = d.join("front.json");
        write_new(&f, b"one", false).expect("first write");
        assert!(matches!(
            write_new(&f, b"two", false),
            Err(WriteError::Exists(_))
        ));
        write_new(&f, b"two", true).expect("forced");
        assert_eq!(std::fs::read(&f).expect("read"), b"two");
        let g = d.join("failed.json");
        let r: Result<(), WriteError> = write_via_temp(&g, |_| {
            Err(WriteError::Io {
                what: "drawing".into(),
                source: std::io::Error::other("no"),
            })
        });
        assert!(r.is_err());
        assert!(!g.exists() && !temp_sibling(&g).exists());
        let _ = std::fs::remove_dir_all(&d);
    }
}
