//! Private run folders (issue 26, finding 5): another local user plants
//! symlinks and folders at every path etp uses under a shared, sticky,
//! world-writable temporary folder; root's run neither follows nor deletes
//! them, and the two users' runs succeed side by side. Needs root (to act
//! as user `nobody`); skipped without, unless `CI` is set.

use super::serial;
use etp_tests::bin_dir;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const NOBODY: u32 = 65534;

/// `etp run` of a short constant-δ run with TMPDIR=`tmp`, as `uid`.
fn etp_run(tmp: &Path, uid: u32, tag: &str) -> Command {
    let mut c = if uid == 0 {
        Command::new(bin_dir().join("etp"))
    } else {
        let mut c = Command::new("setpriv");
        c.args([
            &format!("--reuid={uid}"),
            &format!("--regid={uid}"),
            "--clear-groups",
        ])
        .arg(bin_dir().join("etp"));
        c
    };
    c.args([
        "run",
        "--scenario",
        "open-2d",
        "--delta",
        "1.0518",
        "--episodes",
        "30",
        "--seed",
        "2",
        "--run-id",
        &format!("{tag}{}", std::process::id()),
    ])
    .env("TMPDIR", tmp)
    .env_remove("XDG_RUNTIME_DIR")
    .current_dir(tmp)
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    c
}

/// Run `sh -c script` as `nobody`.
fn as_nobody(script: &str) -> Output {
    Command::new("setpriv")
        .args([
            &format!("--reuid={NOBODY}"),
            &format!("--regid={NOBODY}"),
            "--clear-groups",
            "sh",
            "-c",
            script,
        ])
        .output()
        .expect("setpriv")
}

fn text(o: &Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn victim_intact(v: &Path) {
    assert!(
        v.join("keep").is_file(),
        "the victim folder {} lost its file",
        v.display()
    );
    let names: Vec<_> = std::fs::read_dir(v)
        .expect("victim")
        .filter_map(Result::ok)
        .map(|e| e.file_name())
        .collect();
    assert_eq!(
        names.len(),
        1,
        "something was created in the victim: {names:?}"
    );
}

#[test]
fn another_user_cannot_redirect_or_delete_through_planted_paths_and_both_run() {
    let _serial = serial();
    let root = etp_runtime::wire::private::uid();
    if root != 0 {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but the test is not root"
        );
        eprintln!("skipped: acting as another user needs root");
        return;
    }
    // A shared temporary folder like /tmp: sticky and world-writable, in a
    // path `nobody` can reach.
    let t = PathBuf::from(format!("/tmp/etp-private-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&t);
    std::fs::create_dir(&t).expect("shared tmp");
    std::fs::set_permissions(&t, std::fs::Permissions::from_mode(0o1777)).expect("chmod");
    let victim = t.join("victim");
    std::fs::create_dir(&victim).expect("victim");
    std::fs::write(victim.join("keep"), "root's data").expect("keep");
    let check_nobody_can_run = as_nobody(&format!("test -x '{}'", bin_dir().join("etp").display()));
    assert!(
        check_nobody_can_run.status.success(),
        "user nobody cannot execute {} (the test needs world-readable binaries)",
        bin_dir().display()
    );

    // 1. Symlinks at every fixed name etp ever used, and at root's private
    //    folder's name.
    let ours = t.join("etp-0");
    let planted = ["etp-run", "etp-iox2", "etp-sensor-host", "etp-0"];
    let script: String = planted
        .iter()
        .map(|p| format!("ln -s '{}' '{}/{p}'; ", victim.display(), t.display()))
        .collect();
    let o = as_nobody(&script);
    assert!(o.status.success(), "planting: {}", text(&o));
    let o = etp_run(&t, 0, "pa").output().expect("etp run");
    assert!(!o.status.success(), "root ran through a planted symlink");
    let msg = text(&o);
    assert!(
        msg.contains(&ours.display().to_string()) && msg.contains("symlink"),
        "the error names the planted path: {msg}"
    );
    victim_intact(&victim);

    // 2. A folder of nobody's at root's private folder's name, with
    //    symlinks inside where etp would put its files.
    std::fs::remove_file(&ours).expect("unplant");
    let script = format!(
        "mkdir -m 777 '{o}' '{o}/run' '{o}/iox2' && ln -s '{v}' '{o}/run/.guard' && ln -s '{v}' '{o}/iox2/x'",
        o = ours.display(),
        v = victim.display()
    );
    let o = as_nobody(&script);
    assert!(o.status.success(), "planting: {}", text(&o));
    let o = etp_run(&t, 0, "pb").output().expect("etp run");
    assert!(!o.status.success(), "root ran in a folder of nobody's");
    assert!(
        text(&o).contains(&format!("belongs to uid {NOBODY}")),
        "{}",
        text(&o)
    );
    victim_intact(&victim);
    std::fs::remove_dir_all(&ours).expect("unplant");

    // 3. Both users run side by side (the old fixed names still planted).
    let mine = etp_run(&t, 0, "pc").spawn().expect("root's run");
    let theirs = etp_run(&t, NOBODY, "pc").spawn().expect("nobody's run");
    let (mine, theirs) = (
        mine.wait_with_output().expect("root's run"),
        theirs.wait_with_output().expect("nobody's run"),
    );
    assert!(mine.status.success(), "root: {}", text(&mine));
    assert!(theirs.status.success(), "nobody: {}", text(&theirs));
    victim_intact(&victim);
    // Root's folder is root's alone, mode 0700; nobody cannot plant inside.
    let m = std::fs::symlink_metadata(&ours).expect("root's private folder");
    assert!(m.is_dir());
    assert_eq!(m.permissions().mode() & 0o777, 0o700);
    let o = as_nobody(&format!(
        "ln -s '{}' '{}/run/x'",
        victim.display(),
        ours.display()
    ));
    assert!(!o.status.success(), "nobody planted inside root's folder");
    // Stale-run cleanup by root never touches nobody's folders.
    let nobody_base = t.join(format!("etp-{NOBODY}"));
    assert!(nobody_base.is_dir(), "nobody's private folder");
    let _ = std::fs::remove_dir_all(&t);
}
