//! The shape of the code (ARCHITECTURE.md, "Invariants"): clap is the
//! command lines' API, not the libraries'; no library function is longer
//! than a reader can hold.

use std::path::{Path, PathBuf};

/// The workspace root.
fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the workspace root")
}

/// The workspace's member folders.
fn members() -> Vec<String> {
    let workspace: toml::Table =
        toml::from_str(&std::fs::read_to_string(root().join("Cargo.toml")).expect("Cargo.toml"))
            .expect("the workspace manifest parses");
    workspace["workspace"]["members"]
        .as_array()
        .expect("workspace.members")
        .iter()
        .map(|m| m.as_str().expect("a member path").to_string())
        .collect()
}

/// The workspace members whose `Cargo.toml` names `clap` among its normal
/// dependencies.
fn members_declaring(dependency: &str) -> Vec<String> {
    let mut with = Vec::new();
    for m in members() {
        let manifest: toml::Table = toml::from_str(
            &std::fs::read_to_string(root().join(&m).join("Cargo.toml"))
                .expect("a member manifest"),
        )
        .expect("a member manifest parses");
        let declares = manifest
            .get("dependencies")
            .and_then(|d| d.as_table())
            .is_some_and(|d| d.contains_key(dependency));
        if declares {
            with.push(m);
        }
    }
    with
}

/// The members whose binaries are command lines: `etp` and the process
/// crates (a binary and the library `etp process` plays it from), the
/// bridge's two hosts included.
const COMMAND_LINES: [&str; 6] = [
    "etp",
    "agent",
    "sensor-node",
    "coordinator",
    "recorder",
    "bridge",
];

/// clap is the command line's, not the libraries' API (ARCHITECTURE.md): it
/// is a dependency of `etp` and of the process crates only, each of which
/// parses its own command line (the process shell takes the parser from
/// the process). Every other member takes typed requests.
#[test]
fn clap_is_a_dependency_of_the_command_lines_only() {
    let with_clap = members_declaring("clap");
    for m in &with_clap {
        assert!(
            COMMAND_LINES.contains(&m.as_str()),
            "the library crate {m} depends on clap: take a typed request and leave the \
             parsing to `etp` or the process main"
        );
    }
    for library in [
        "shared",
        "files",
        "synthesis",
        "runtime",
        "pipeline",
        "recording-tools",
        "figures",
        "live",
        "launcher",
        "python",
    ] {
        assert!(
            !with_clap.iter().any(|c| c == library),
            "{library}: {with_clap:?}"
        );
    }
}

/// Libraries return `thiserror` enums, so a caller (Python among them)
/// can tell one failure from another; `anyhow` is for the binaries'
/// mains. The Python package's native module is typed too: each library
/// error becomes the exception class of its kind.
#[test]
fn anyhow_is_a_dependency_of_the_binaries_only() {
    let with_anyhow = members_declaring("anyhow");
    for m in &with_anyhow {
        assert!(
            COMMAND_LINES.contains(&m.as_str()),
            "the library crate {m} depends on anyhow: return a thiserror enum"
        );
    }
    for typed in [
        "shared",
        "files",
        "synthesis",
        "figures",
        "live",
        "pipeline",
        "recording-tools",
        "runtime",
        "launcher",
        "python",
    ] {
        assert!(
            !with_anyhow.iter().any(|w| w == typed),
            "{typed}: {with_anyhow:?}"
        );
    }
}

/// Python builds typed requests, never a command line for Rust to parse:
/// no argv in the package, no clap parser in its native module.
#[test]
fn python_builds_no_argv_for_rust() {
    let root = root();
    let mut found = Vec::new();
    for (dir, words) in [
        ("python/etpareto", &["argv", "--"][..]),
        ("python/src", &["clap", "try_parse_from"][..]),
    ] {
        for entry in std::fs::read_dir(root.join(dir)).expect(dir) {
            let path = entry.expect("entry").path();
            let text = std::fs::read_to_string(&path).unwrap_or_default();
            for (n, line) in text.lines().enumerate() {
                // Python's and Rust's comments (and docstrings' prose) may name
                // a flag; code may not pass one.
                let code = line.split('#').next().unwrap_or("");
                let code = code_of(code);
                let in_string_flag = words.iter().any(|w| {
                    if *w == "--" {
                        code.contains("\"--") || code.contains("'--")
                    } else {
                        code.contains(w)
                    }
                });
                if in_string_flag && !line.trim_start().starts_with("///") {
                    found.push(format!("{}:{}: {}", path.display(), n + 1, line.trim()));
                }
            }
        }
    }
    assert!(found.is_empty(), "argv built in python/: {found:#?}");
}

/// The code of a line: what precedes a `//` comment.
fn code_of(line: &str) -> &str {
    line.split("//").next().unwrap_or("")
}

/// Longest a library function may be, in lines from its `fn` to its closing
/// brace.
const MAX_FUNCTION_LINES: usize = 150;

/// The functions of a rustfmt-formatted file with their length in lines:
/// from a line opening `fn NAME` to the first line after it that closes at
/// the same indentation. Test modules (`tests.rs`, `*_tests.rs`, `tests/`)
/// are not library code.
fn function_lengths(text: &str) -> Vec<(String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let mut rest = trimmed;
        for prefix in [
            "pub(crate) ",
            "pub(super) ",
            "pub ",
            "const ",
            "async ",
            "unsafe ",
        ] {
            rest = rest.strip_prefix(prefix).unwrap_or(rest);
        }
        let Some(sig) = rest.strip_prefix("fn ") else {
            continue;
        };
        let name: String = sig
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        // The signature runs to the line that opens the body; a declaration
        // without a body (a trait's) ends with `;` first; a one-line
        // function closes on its own line.
        let close = format!("{indent}}}");
        let Some(open) = lines[i..].iter().position(|l| {
            let t = code_of(l).trim_end();
            t.ends_with('{') || t.ends_with(';') || t.ends_with('}')
        }) else {
            continue;
        };
        let opening = code_of(lines[i + open]).trim_end();
        if !opening.ends_with('{') {
            if opening.ends_with('}') {
                out.push((name, open + 1));
            }
            continue;
        }
        if let Some(n) = lines[i + open + 1..]
            .iter()
            .position(|l| l.starts_with(&close))
        {
            out.push((name, open + n + 2));
        }
    }
    out
}

/// Every function of the workspace's library code (all members but the
/// `etp` command line and the tests) longer than [`MAX_FUNCTION_LINES`], as
/// `path::name` with its length.
fn long_library_functions() -> Vec<(String, usize)> {
    let mut long = Vec::new();
    for m in members() {
        if m == "etp" || m == "tests" {
            continue;
        }
        let src = root().join(&m).join("src");
        let mut dirs: Vec<PathBuf> = vec![src.clone()];
        while let Some(d) = dirs.pop() {
            for e in std::fs::read_dir(&d).expect("a readable source folder") {
                let p = e.expect("a folder entry").path();
                let name = p
                    .file_name()
                    .map(|n| n.to_string_lossy().to_string())
                    .unwrap_or_default();
                if p.is_dir() {
                    if name != "tests" {
                        dirs.push(p);
                    }
                } else if name.ends_with(".rs")
                    && name != "tests.rs"
                    && !name.ends_with("_tests.rs")
                {
                    let text = std::fs::read_to_string(&p).expect("readable source");
                    let rel = p
                        .strip_prefix(root())
                        .expect("under the root")
                        .to_string_lossy()
                        .to_string();
                    for (f, n) in function_lengths(&text) {
                        if n > MAX_FUNCTION_LINES {
                            long.push((format!("{rel}::{f}"), n));
                        }
                    }
                }
            }
        }
    }
    long.sort();
    long
}

/// No library function over 150 lines: a long one is split along the phases
/// its comments name.
#[test]
fn no_library_function_is_longer_than_150_lines() {
    let long = long_library_functions();
    let unexpected: Vec<String> = long
        .iter()
        .map(|(f, n)| format!("{f}: {n} lines"))
        .collect();
    assert!(
        unexpected.is_empty(),
        "library functions over {MAX_FUNCTION_LINES} lines: split each along its phases:\n{}",
        unexpected.join("\n")
    );
}

/// The scan measures what it claims: a multi-line signature, a body with
/// statements and nested braces, a trait declaration without a body, a
/// comment holding a brace and a one-line function.
#[test]
fn the_function_scan_counts_from_fn_to_its_closing_brace() {
    let text = "pub fn a(\n    x: u8,\n) -> u8 {\n    let y = x;\n    if y > 0 {\n        y\n    } else {\n        0\n    }\n}\n\ntrait T {\n    fn b(&self);\n    fn c(&self) {\n        let z = 1; // {\n    }\n    fn d(&self) -> u8 { 1 }\n}\n";
    assert_eq!(
        function_lengths(text),
        vec![
            ("a".to_string(), 10),
            ("c".to_string(), 3),
            ("d".to_string(), 1)
        ]
    );
}
