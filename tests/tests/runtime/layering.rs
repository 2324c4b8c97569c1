//! The layering of ARCHITECTURE.md: the maths crates link neither iceoryx2
//! nor mcap (nor the runtime crate that wraps them).

use std::process::Command;

/// Every package `package` links in a normal (non-dev) build, by name.
fn normal_dependencies(package: &str) -> Vec<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    let out = Command::new(cargo)
        .args([
            "tree",
            "--offline",
            "-e",
            "normal",
            "--prefix",
            "none",
            "-p",
            package,
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "cargo tree -p {package}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect()
}

#[test]
fn maths_crates_link_neither_iceoryx2_nor_mcap() {
    for package in ["etp-shared", "etp-synthesis"] {
        let deps = normal_dependencies(package);
        assert!(deps.iter().any(|d| d == "nalgebra"), "{package}: {deps:?}");
        for banned in ["iceoryx2", "mcap", "etp-runtime", "tokio"] {
            assert!(
                !deps.iter().any(|d| d == banned),
                "{package} links {banned}: {deps:?}"
            );
        }
    }
    // And the runtime crate does link them (the walk sees transitive deps).
    let runtime = normal_dependencies("etp-runtime");
    assert!(runtime.iter().any(|d| d == "iceoryx2") && runtime.iter().any(|d| d == "mcap"));
}
