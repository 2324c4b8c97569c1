//! Private run folders (`etp_files::folders`): what another local user
//! plants is refused, never followed or removed, and two users' runs share
//! no folder.

use super::serial;
use etp_tests::{bin_dir, unique_run_id};
use std::os::unix::fs::{MetadataExt, PermissionsExt, symlink};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const NOBODY: u32 = 65534;

/// `etp run` of a short constant-threshold run, as root (with `env`) or as
/// user nobody.
fn etp_run(run_id: &str, as_nobody: bool, env: &[(&str, &Path)]) -> Command {
    let etp = bin_dir().join("etp");
    let args = [
        "run",
        "--scenario",
        "open-2d",
        "--delta",
        "1.0518",
        "--episodes",
        "10",
        "--seed",
        "2",
        "--run-id",
        run_id,
        "--json",
    ];
    let mut c = if as_nobody {
        let mut c = Command::new("setpriv");
        c.args([
            "--reuid",
            &NOBODY.to_string(),
            "--regid",
            &NOBODY.to_string(),
            "--clear-groups",
            "--",
        ])
        .arg(&etp)
        .args(args)
        .env("HOME", "/tmp")
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove(etp_files::folders::RUNTIME_DIR_ENV);
        c
    } else {
        let mut c = Command::new(&etp);
        c.args(args);
        c
    };
    for (k, v) in env {
        c.env(k, v);
    }
    c.current_dir("/tmp");
    c
}

fn is_root() -> bool {
    etp_files::folders::euid() == 0
}

fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("etp-test-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch");
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The private folder given as a symlink to a victim folder, or as a folder
/// open to everyone: the run is refused by name before anything is
/// written, and the victim keeps every file.
#[test]
fn a_planted_link_or_an_open_folder_as_the_private_folder_is_refused_never_followed() {
    let _serial = serial();
    let d = scratch("plant");
    let victim = d.join("victim");
    std::fs::create_dir(&victim).expect("victim");
    std::fs::write(victim.join("precious"), b"keep me").expect("write");
    let link = d.join("base");
    symlink(&victim, &link).expect("symlink");
    let open = d.join("open");
    std::fs::create_dir(&open).expect("open");
    std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o777)).expect("chmod");
    for (base, why) in [(&link, "symbolic link"), (&open, "group or others")] {
        let id = unique_run_id("plant");
        let out = etp_run(&id, false, &[(etp_files::folders::RUNTIME_DIR_ENV, base)])
            .output()
            .expect("etp run");
        assert!(
            !out.status.success(),
            "a run in {} was not refused",
            base.display()
        );
        let err = stderr(&out);
        assert!(
            err.contains(why) && err.contains("not a private folder"),
            "{err}"
        );
    }
    let left: Vec<_> = std::fs::read_dir(&victim)
        .expect("victim")
        .filter_map(Result::ok)
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left, ["precious"], "the victim folder was written into");
    assert_eq!(
        std::fs::read(victim.join("precious")).expect("kept"),
        b"keep me"
    );
    assert_eq!(std::fs::read_dir(&open).expect("open").count(), 0);
    let _ = std::fs::remove_dir_all(&d);
}

/// Another local user (nobody) plants symlinks to its own victim folder at
/// the fixed paths earlier versions shared (`/tmp/etp-run`, `/tmp/etp-iox2`,
/// where free) and a folder of its own where root is told to run: root's run
/// in the planted folder is refused (nothing in it touched); root's and
/// nobody's runs side by side both succeed, each in a private folder of its
/// own, and nothing planted is followed or removed.
#[test]
fn another_users_plants_are_never_followed_and_two_users_run_side_by_side() {
    let _serial = serial();
    if !is_root() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI runs as root: a second uid is needed for this test"
        );
        eprintln!("skipped: a second uid needs root");
        return;
    }
    let as_nobody = |args: &[&str]| {
        let out = Command::new("setpriv")
            .args([
                "--reuid",
                "65534",
                "--regid",
                "65534",
                "--clear-groups",
                "--",
            ])
            .args(args)
            .output()
            .expect("setpriv");
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    };
    // nobody's victim folder and plants, all made by nobody in /tmp.
    let tag = format!("etp-test-nobody-{}", std::process::id());
    let victim = PathBuf::from(format!("/tmp/{tag}-victim"));
    let foreign = PathBuf::from(format!("/tmp/{tag}-folder"));
    let _ = std::fs::remove_dir_all(&victim);
    let _ = std::fs::remove_dir_all(&foreign);
    as_nobody(&["mkdir", "-m", "700", &victim.display().to_string()]);
    as_nobody(&["touch", &victim.join("precious").display().to_string()]);
    as_nobody(&["mkdir", "-m", "700", &foreign.display().to_string()]);
    as_nobody(&["touch", &foreign.join("mine").display().to_string()]);
    let mut planted = Vec::new();
    for old in ["/tmp/etp-run", "/tmp/etp-iox2"] {
        if std::fs::symlink_metadata(old).is_err() {
            as_nobody(&["ln", "-s", &victim.display().to_string(), old]);
            planted.push(PathBuf::from(old));
        }
    }
    // Root told to run in nobody's folder: refused, nothing touched.
    let out = etp_run(
        &unique_run_id("foreign"),
        false,
        &[(etp_files::folders::RUNTIME_DIR_ENV, &foreign)],
    )
    .output()
    .expect("etp run");
    assert!(!out.status.success(), "a run in another user's folder");
    assert!(
        stderr(&out).contains("owned by user 65534"),
        "{}",
        stderr(&out)
    );
    // Both users at once, each in its own private folder.
    let root_run = etp_run(&unique_run_id("root"), false, &[])
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove(etp_files::folders::RUNTIME_DIR_ENV)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("root's run");
    let nobody_run = etp_run(&unique_run_id("nobody"), true, &[])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("nobody's run");
    let (a, b) = (
        root_run.wait_with_output().expect("root's run"),
        nobody_run.wait_with_output().expect("nobody's run"),
    );
    assert!(a.status.success(), "root's run: {}", stderr(&a));
    assert!(b.status.success(), "nobody's run: {}", stderr(&b));
    for (uid, path) in [(0, "/tmp/etp-0"), (NOBODY, "/tmp/etp-65534")] {
        let m = std::fs::symlink_metadata(path).expect("private folder");
        assert!(m.is_dir() && m.uid() == uid, "{path}");
        assert_eq!(m.permissions().mode() & 0o777, 0o700, "{path}");
    }
    // Nothing planted was followed or removed.
    let names = |p: &Path| -> Vec<_> {
        std::fs::read_dir(p)
            .expect("folder")
            .filter_map(Result::ok)
            .map(|e| e.file_name())
            .collect()
    };
    assert_eq!(names(&victim), ["precious"]);
    assert_eq!(names(&foreign), ["mine"]);
    for p in &planted {
        let m = std::fs::symlink_metadata(p).expect("plant kept");
        assert!(
            m.file_type().is_symlink() && m.uid() == NOBODY,
            "{}",
            p.display()
        );
        let _ = std::fs::remove_file(p);
    }
    let _ = std::fs::remove_dir_all(&victim);
    let _ = std::fs::remove_dir_all(&foreign);
}

/// Every file a run creates is its user's alone (issue 41, item 6): while
/// a run is going (all its processes up: the recorder, coordinator, agent
/// and sensors have created their nodes and services), each of its
/// shared-memory files in /dev/shm and each file in its iceoryx2 root
/// folder has no access for group or others (iceoryx2's folders there are
/// 0750, inside the user's private folder, 0700). iceoryx2 0.10 creates the
/// node counter segment (`…global_mgmt`) with mode 666; the run makes it
/// 0600.
#[test]
fn no_file_of_a_run_is_open_to_other_users() {
    let _serial = serial();
    let run_id = unique_run_id("modes");
    let run = etp_runtime::wire::RunId::new(&run_id).expect("run id");
    let prefix = run.shm_prefix();
    // Long enough to be seen running; its end is waited for below.
    let mut child = Command::new(bin_dir().join("etp"))
        .args([
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "1.0518",
            "--episodes",
            "400",
        ])
        .args(["--seed", "2", "--run-id", &run_id, "--json"])
        .current_dir("/tmp")
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("etp run");
    let shm_files = || -> Vec<(String, u32)> {
        std::fs::read_dir("/dev/shm")
            .map(|it| {
                it.filter_map(Result::ok)
                    .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
                    .filter_map(|e| {
                        let m = std::fs::symlink_metadata(e.path()).ok()?;
                        Some((
                            e.file_name().to_string_lossy().into_owned(),
                            m.mode() & 0o777,
                        ))
                    })
                    .collect()
            })
            .unwrap_or_default()
    };
    // Up: the agent's and every sensor's services exist (the run's
    // processes create theirs before the coordinator's roll call ends).
    let start = std::time::Instant::now();
    let mut seen = Vec::new();
    while start.elapsed() < std::time::Duration::from_secs(120) {
        seen = shm_files();
        if seen.iter().any(|(n, _)| n.ends_with(".global_mgmt")) && seen.len() >= 100 {
            break;
        }
        if child.try_wait().ok().flatten().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let mut root_files = Vec::new();
    let base = etp_files::folders::base();
    etp_files::folders::check(&base, etp_files::folders::euid()).expect("private base");
    let mut stack = vec![run.root_dir()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d)
            .into_iter()
            .flatten()
            .filter_map(Result::ok)
        {
            let Ok(m) = std::fs::symlink_metadata(e.path()) else {
                continue;
            };
            if m.is_dir() {
                // iceoryx2 makes its folders 0750; no other user may enter
                // the user's private folder (0700, checked) that holds them.
                stack.push(e.path());
                assert_eq!(
                    m.mode() & 0o007,
                    0,
                    "{} is open to other users",
                    e.path().display()
                );
                continue;
            }
            root_files.push((e.path().display().to_string(), m.mode() & 0o777));
        }
    }
    let status = child.wait().expect("wait");
    assert!(status.success(), "the run failed (its stderr is above)");
    assert!(
        seen.iter().any(|(n, _)| n.ends_with(".global_mgmt")) && seen.len() >= 100,
        "the run's files were not seen while it ran ({} files)",
        seen.len()
    );
    let open: Vec<String> = seen
        .iter()
        .cloned()
        .chain(root_files)
        .filter(|(_, mode)| mode & 0o077 != 0)
        .map(|(n, mode)| format!("{n} {mode:o}"))
        .collect();
    assert!(
        open.is_empty(),
        "files of the run open to other users: {open:?}"
    );
}
