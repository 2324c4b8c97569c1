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

/// The command modules of `etp` (`etp/src/cmd/<command>.rs` and
/// `etp/src/cmd/<command>/…`) are leaves: none imports another. What two
/// commands share lives in a library crate or in a module of `etp` outside
/// `cmd/` (`predictions`, `report`, `input`, `output`, `processes`,
/// `simulation`, …). `cmd/mod.rs` only dispatches.
#[test]
fn etp_command_modules_import_no_other_command() {
    // None left: `demo` builds its MDP through `mdp_build` and runs its
    // processes through `multiprocess`, as `synthesize` and `run` do.
    const PENDING: [(&str, &str); 0] = [];
    let cmd = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../etp/src/cmd");
    let mut files = Vec::new();
    let mut dirs = vec![cmd.clone()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).expect("etp/src/cmd is readable") {
            let p = e.expect("a folder entry").path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                files.push(p);
            }
        }
    }
    assert!(
        files.len() > 20,
        "{} files under {}",
        files.len(),
        cmd.display()
    );
    let mut found = Vec::new();
    for path in &files {
        let rel = path.strip_prefix(&cmd).expect("under cmd");
        let parts: Vec<String> = rel
            .iter()
            .map(|c| c.to_string_lossy().trim_end_matches(".rs").to_string())
            .collect();
        if parts == ["mod"] {
            continue;
        }
        let own = parts[0].as_str();
        // `super::` of a top-level command file is `cmd`; of a file one
        // folder down, `super::super::` is.
        let top = parts.len() == 1 || (parts.len() == 2 && parts[1] == "mod");
        let up = if top { "super::" } else { "super::super::" };
        let text = std::fs::read_to_string(path).expect("readable source");
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            let mut targets = Vec::new();
            for prefix in ["crate::cmd::", up] {
                for (i, _) in code.match_indices(prefix) {
                    // `super::super::x` also contains `super::x`.
                    if prefix == "super::" && code[i + prefix.len()..].starts_with("super::") {
                        continue;
                    }
                    if prefix == "super::" && i >= 7 && code[..i].ends_with("super::") {
                        continue;
                    }
                    let rest = &code[i + prefix.len()..];
                    if let Some(group) = rest.strip_prefix('{') {
                        let group = group.split('}').next().unwrap_or("");
                        targets.extend(group.split(',').map(|t| {
                            t.split([':', ' '])
                                .find(|s| !s.is_empty())
                                .unwrap_or("")
                                .to_string()
                        }));
                    } else {
                        let name: String = rest
                            .chars()
                            .take_while(|c| c.is_alphanumeric() || *c == '_')
                            .collect();
                        targets.push(name);
                    }
                }
            }
            for t in targets {
                let is_module = t.chars().next().is_some_and(|c| c.is_ascii_lowercase());
                if is_module && t != own && !PENDING.contains(&(own, t.as_str())) {
                    found.push(format!("{}:{}: {own} → {t}", rel.display(), n + 1));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "command modules importing another command:\n{}",
        found.join("\n")
    );
}

/// The Python package calls the library crates (the pipeline's steps in
/// `etp-pipeline`), never the CLI's crate: what it offers is what a library
/// offers, and `etp`'s command line can change without breaking it.
#[test]
fn the_python_package_links_the_libraries_not_the_cli() {
    let deps = normal_dependencies("etpareto-py");
    for needed in ["etp-pipeline", "etp-synthesis", "etp-launcher", "pyo3"] {
        assert!(deps.iter().any(|d| d == needed), "etpareto-py: {deps:?}");
    }
    assert!(
        !deps.iter().any(|d| d == "etp"),
        "etpareto-py links the CLI crate etp: {deps:?}"
    );
    // Nor does the pipeline: the CLI depends on it, not the other way.
    let pipeline = normal_dependencies("etp-pipeline");
    assert!(
        !pipeline.iter().any(|d| d == "etp"),
        "etp-pipeline: {pipeline:?}"
    );
}
