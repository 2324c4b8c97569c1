//! Outputs never follow planted links (issue 41, item 4): as root, a
//! symbolic link of user `nobody` planted where a command writes (to a
//! victim folder), a folder of `nobody` there, or a folder every user may
//! write without the sticky bit: every command that writes a folder or a
//! figure refuses by name and nothing lands in the victim.

use super::{etp, s};
use std::os::unix::fs::{PermissionsExt, chown, lchown, symlink};
use std::path::{Path, PathBuf};

const NOBODY: u32 = 65534;

fn is_root() -> bool {
    etp_files::folders::euid() == 0
}

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../recordings/fixtures/open-2d-4-episodes.mcap")
}

/// A world-writable folder with the sticky bit (like /tmp) and a victim
/// folder holding one file.
struct World {
    shared: PathBuf,
    victim: PathBuf,
}

impl World {
    fn new(tag: &str, mode: u32) -> Self {
        let root = std::env::temp_dir().join(format!("etp-outputs-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let shared = root.join("shared");
        let victim = root.join("victim");
        std::fs::create_dir_all(&shared).expect("shared");
        std::fs::create_dir_all(&victim).expect("victim");
        std::fs::set_permissions(&shared, std::fs::Permissions::from_mode(mode)).expect("chmod");
        std::fs::write(victim.join("precious"), b"x").expect("precious");
        Self { shared, victim }
    }

    /// `shared/name` → the victim, a link of user nobody.
    fn link(&self, name: &str) -> PathBuf {
        let p = self.shared.join(name);
        symlink(&self.victim, &p).expect("symlink");
        lchown(&p, Some(NOBODY), Some(NOBODY)).expect("lchown");
        p
    }

    /// `shared/name`, a folder of user nobody.
    fn foreign(&self, name: &str) -> PathBuf {
        let p = self.shared.join(name);
        std::fs::create_dir(&p).expect("dir");
        chown(&p, Some(NOBODY), Some(NOBODY)).expect("chown");
        p
    }

    fn victim_untouched(&self) {
        let names: Vec<String> = std::fs::read_dir(&self.victim)
            .expect("victim")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            names,
            vec!["precious".to_string()],
            "the victim was written into"
        );
    }
}

impl Drop for World {
    fn drop(&mut self) {
        if let Some(root) = self.shared.parent() {
            let _ = std::fs::remove_dir_all(root);
        }
    }
}

/// `etp args` fails and its error names `path` and says why.
fn refused(args: &[&str], path: &Path, why: &str) {
    let out = etp(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "etp {args:?} should be refused: {err}"
    );
    assert!(
        err.contains(&format!("`{}`", path.display())) || err.contains(&path.display().to_string()),
        "etp {args:?}: the error does not name {}: {err}",
        path.display()
    );
    assert!(
        err.contains(why),
        "etp {args:?}: the error lacks {why:?}: {err}"
    );
}

#[test]
fn export_synthesize_and_certs_refuse_a_planted_link_or_a_foreign_folder() {
    if !is_root() {
        eprintln!("skipped: needs root (chown to nobody)");
        return;
    }
    let w = World::new("dirs", 0o1777);
    let fx = fixture();
    let link = w.link("tables");
    refused(
        &["replay", "export", s(&fx), s(&link)],
        &link,
        "symbolic link",
    );
    let foreign = w.foreign("theirs");
    refused(
        &["replay", "export", s(&fx), s(&foreign)],
        &foreign,
        "owned by user 65534",
    );
    assert_eq!(std::fs::read_dir(&foreign).expect("dir").count(), 0);

    let syn = w.link("syn");
    refused(
        &[
            "synthesize",
            "open-2d",
            "--samples",
            "40",
            "--seed",
            "3",
            "-o",
            s(&syn),
        ],
        &syn,
        "symbolic link",
    );
    refused(
        &[
            "synthesize",
            "open-2d",
            "--samples",
            "40",
            "--seed",
            "3",
            "-o",
            s(&foreign),
        ],
        &foreign,
        "owned by user 65534",
    );

    // certs init: a folder of another user is not replaced even with
    // --force, and a link on the way to DIR is not followed.
    refused(
        &["certs", "init", s(&foreign), "--force"],
        &foreign,
        "owned by user 65534",
    );
    assert!(foreign.is_dir(), "the other user's folder was removed");
    let keys = link.join("keys");
    refused(
        &["certs", "init", s(&keys)],
        &link,
        "symbolic link of user 65534",
    );
    w.victim_untouched();

    // The same commands into a folder of ours do write.
    let ours = w.shared.join("ours");
    let ok = etp(&["replay", "export", s(&fx), s(&ours)]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(ours.join("tables.json").is_file());
}

#[test]
fn files_and_figures_are_not_written_through_a_planted_link() {
    if !is_root() {
        eprintln!("skipped: needs root (chown to nobody)");
        return;
    }
    let w = World::new("files", 0o1777);
    // replay plot writes beside its input: an input reached through
    // nobody's link gets no figure in the victim.
    std::fs::copy(fixture(), w.victim.join("precious.mcap")).expect("copy");
    std::fs::remove_file(w.victim.join("precious")).expect("rm");
    std::fs::rename(w.victim.join("precious.mcap"), w.victim.join("precious")).expect("mv");
    let link = w.link("rec");
    let through = link.join("precious");
    refused(
        &["replay", "plot", s(&through)],
        &link,
        "symbolic link of user 65534",
    );
    let copy = link.join("copy.mcap");
    refused(
        &["replay", "foxglove", s(&fixture()), s(&copy)],
        &link,
        "symbolic link of user 65534",
    );
    w.victim_untouched();
}

#[test]
fn a_folder_every_user_may_write_without_the_sticky_bit_is_refused() {
    if !is_root() {
        eprintln!("skipped: needs root");
        return;
    }
    let w = World::new("open", 0o777);
    let tables = w.shared.join("tables");
    refused(
        &["replay", "export", s(&fixture()), s(&tables)],
        &tables,
        "every user may write",
    );
    assert!(!tables.exists());
    let figure = w.shared.join("copy.mcap");
    refused(
        &["replay", "foxglove", s(&fixture()), s(&figure)],
        &figure,
        "every user may write",
    );
}
