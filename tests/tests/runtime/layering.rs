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

/// The `.rs` files under `dir`, by path relative to it, with their text.
fn sources_under(dir: &std::path::Path) -> Vec<(std::path::PathBuf, String)> {
    let mut files = Vec::new();
    let mut dirs = vec![dir.to_path_buf()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).expect("a readable source folder") {
            let p = e.expect("a folder entry").path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                let text = std::fs::read_to_string(&p).expect("readable source");
                let rel = p.strip_prefix(dir).expect("under dir").to_path_buf();
                files.push((rel, text));
            }
        }
    }
    files.sort();
    files
}

/// The module a file is, as its path below the folder's root module
/// (`strategy/select.rs` → `strategy::select`; `strategy.rs`,
/// `replay/mod.rs` and the root's `mod.rs` name their folder).
fn module_of(rel: &std::path::Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|c| c.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

/// The code of a line: what precedes a `//` comment.
fn code_of(line: &str) -> &str {
    line.split("//").next().unwrap_or("")
}

/// The paths a `::`-path at the start of `s` names, `{…}` groups expanded
/// (`a::{b, c::d}` → `a::b`, `a::c::d`); segments only, `*` and `as`
/// renames dropped.
fn expand_path(s: &str) -> Vec<Vec<String>> {
    fn path(s: &str, i: &mut usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
        let b = s.as_bytes();
        let mut segs = prefix;
        loop {
            while *i < b.len() && b[*i].is_ascii_whitespace() {
                *i += 1;
            }
            if *i < b.len() && b[*i] == b'{' {
                *i += 1;
                loop {
                    path(s, i, segs.clone(), out);
                    while *i < b.len() && b[*i] != b',' && b[*i] != b'}' {
                        // ` as name`, `*`: nothing more of a module path.
                        *i += 1;
                    }
                    if *i >= b.len() || b[*i] == b'}' {
                        *i += 1;
                        return;
                    }
                    *i += 1;
                }
            }
            let start = *i;
            while *i < b.len() && (b[*i].is_ascii_alphanumeric() || b[*i] == b'_') {
                *i += 1;
            }
            if *i > start {
                segs.push(s[start..*i].to_string());
            }
            if *i > start && s[*i..].starts_with("::") {
                *i += 2;
                continue;
            }
            out.push(segs);
            return;
        }
    }
    let mut out = Vec::new();
    path(s, &mut 0, Vec::new(), &mut out);
    out
}

/// Module import cycles among the files of a module folder (`files`: path
/// relative to the folder, text). A file depends on the modules its
/// `crate::<root>::`, `super::` and `self::` paths name, except its own
/// ancestors: a parent declares its parts, and their `super::Args` reading
/// the arguments it defines is that ownership, not a cycle. An inline
/// `mod x { … }` (rustfmt's indentation) resolves its paths from inside
/// but counts as its file's. One line per cycle found, with the lines
/// behind each step.
fn import_cycles(root: &str, files: &[(std::path::PathBuf, String)]) -> Vec<String> {
    use std::collections::{BTreeMap, BTreeSet};
    let modules: BTreeSet<Vec<String>> = files.iter().map(|(rel, _)| module_of(rel)).collect();
    // edges[from][to] = where.
    let mut edges: BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>> = BTreeMap::new();
    let crate_root = format!("crate::{root}::");
    for (rel, text) in files {
        let node = module_of(rel);
        let lines: Vec<&str> = text.lines().collect();
        let code: String = lines.iter().map(|l| format!("{}\n", code_of(l))).collect();
        // The module each line is in (inline `mod x {` blocks included).
        let mut stack: Vec<(usize, String)> = Vec::new();
        let mut line_module = Vec::new();
        for line in &lines {
            let c = code_of(line);
            let indent = c.len() - c.trim_start().len();
            if !c.trim().is_empty() {
                while stack.last().is_some_and(|(d, _)| indent <= *d) {
                    stack.pop();
                }
            }
            let mut m = node.clone();
            m.extend(stack.iter().map(|(_, n)| n.clone()));
            line_module.push(m);
            let t = c.trim();
            let t = t.strip_prefix("pub ").unwrap_or(t);
            if let Some(name) = t.strip_prefix("mod ").and_then(|r| r.strip_suffix(" {")) {
                stack.push((indent, name.trim().to_string()));
            }
        }
        let line_starts: Vec<usize> = std::iter::once(0)
            .chain(code.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        for prefix in [crate_root.as_str(), "super::", "self::"] {
            for (i, _) in code.match_indices(prefix) {
                let before = code[..i].chars().next_back();
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                    continue; // `super::super::`'s second half, or `x_self::`.
                }
                let line = line_starts.partition_point(|&s| s <= i) - 1;
                let here = line_module.get(line).cloned().unwrap_or_default();
                for p in expand_path(&code[i..]) {
                    let mut target: Vec<String> = if prefix == crate_root {
                        Vec::new()
                    } else {
                        here.clone()
                    };
                    let skip = if prefix == crate_root { 2 } else { 0 };
                    let mut outside = false;
                    for seg in p.iter().skip(skip) {
                        match seg.as_str() {
                            "self" => {}
                            "super" => outside |= target.pop().is_none(),
                            s => target.push(s.to_string()),
                        }
                    }
                    if outside {
                        continue;
                    }
                    // The longest prefix that is a module of the folder.
                    while !target.is_empty() && !modules.contains(&target) {
                        target.pop();
                    }
                    if node.starts_with(&target) {
                        continue;
                    }
                    edges
                        .entry(node.clone())
                        .or_default()
                        .entry(target)
                        .or_insert_with(|| format!("{}:{}", rel.display(), line + 1));
                }
            }
        }
    }
    // Every cycle, found once: from its least module, through greater ones.
    type Edges = BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>>;
    fn walk(edges: &Edges, path: &mut Vec<Vec<String>>, root: &str, cycles: &mut Vec<String>) {
        let name = |m: &Vec<String>| {
            if m.is_empty() {
                root.to_string()
            } else {
                m.join("::")
            }
        };
        let (start, last) = (path[0].clone(), path[path.len() - 1].clone());
        for to in edges.get(&last).into_iter().flat_map(|e| e.keys()) {
            if *to == start {
                let steps: Vec<String> = path
                    .iter()
                    .zip(path.iter().skip(1).chain(std::iter::once(&start)))
                    .map(|(a, b)| format!("{} → {} ({})", name(a), name(b), edges[a][b]))
                    .collect();
                cycles.push(steps.join(", "));
            } else if *to > start && !path.contains(to) {
                path.push(to.clone());
                walk(edges, path, root, cycles);
                path.pop();
            }
        }
    }
    let mut cycles = Vec::new();
    for start in &modules {
        walk(&edges, &mut vec![start.clone()], root, &mut cycles);
    }
    cycles
}

/// The `pub use` items of a source file that relay another crate's: any
/// whose path starts neither at this crate (`crate::`, `self::`,
/// `super::`) nor at a module the file declares. One line each.
fn relays_of_other_crates(rel: &std::path::Path, text: &str) -> Vec<String> {
    let own: Vec<&str> = text
        .lines()
        .filter_map(|l| {
            let t = code_of(l).trim();
            let t = t.strip_prefix("pub ").unwrap_or(t);
            let t = t.strip_prefix("pub(crate) ").unwrap_or(t);
            t.strip_prefix("mod ")
        })
        .map(|r| r.trim_end_matches([';', '{', ' ']))
        .collect();
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let t = code_of(line).trim();
        // `pub use`, `pub(crate) use`, `pub(super) use`, …
        let Some(rest) = t.strip_prefix("pub") else {
            continue;
        };
        let rest = match rest.strip_prefix('(') {
            Some(r) => r.split_once(')').map_or("", |(_, r)| r),
            None => rest,
        };
        let Some(path) = rest.trim_start().strip_prefix("use ") else {
            continue;
        };
        let first: String = path
            .trim_start()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        if !["crate", "self", "super"].contains(&first.as_str()) && !own.contains(&first.as_str()) {
            found.push(format!("{}:{}: {t}", rel.display(), n + 1));
        }
    }
    found
}

/// No module import cycle among `etp`'s command modules: what two parts
/// of a command share lives in the command's own module (`strategy.rs`)
/// or in a library, so each part can be read and changed on its own.
#[test]
fn etp_command_modules_import_in_no_cycle() {
    let cmd = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../etp/src/cmd");
    let files = sources_under(&cmd);
    assert!(
        files.len() > 20,
        "{} files under {}",
        files.len(),
        cmd.display()
    );
    let cycles = import_cycles("cmd", &files);
    assert!(
        cycles.is_empty(),
        "import cycles in etp/src/cmd:\n{}",
        cycles.join("\n")
    );
}

/// `etp` relays no other crate's item (`pub use etp_pipeline::…`): a caller
/// imports an item from the crate that defines it, so each item has one
/// path and the crate that owns it is the one the path names.
#[test]
fn etp_relays_no_other_crates_item() {
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../etp/src");
    let files = sources_under(&src);
    assert!(
        files.len() > 30,
        "{} files under {}",
        files.len(),
        src.display()
    );
    let found: Vec<String> = files
        .iter()
        .flat_map(|(rel, text)| relays_of_other_crates(rel, text))
        .collect();
    assert!(
        found.is_empty(),
        "`pub use` of another crate's items in etp/src (import them from their crate):\n{}",
        found.join("\n")
    );
}

/// The two scans find what they are for, and only that.
#[test]
fn the_scans_find_a_cycle_and_a_relay() {
    let file = |p: &str, t: &str| (std::path::PathBuf::from(p), t.to_string());
    let cyclic = [
        file("mod.rs", "mod strategy;\n"),
        file(
            "strategy.rs",
            "mod certified;\nmod select;\npub struct Args;\n",
        ),
        file(
            "strategy/certified.rs",
            "use super::Args;\nuse super::select::Synthesis;\n",
        ),
        file(
            "strategy/select.rs",
            "use super::{\n    Args,\n    certified,\n};\n",
        ),
    ];
    let cycles = import_cycles("cmd", &cyclic);
    assert_eq!(
        cycles,
        [
            "strategy::certified → strategy::select (strategy/certified.rs:2), \
             strategy::select → strategy::certified (strategy/select.rs:1)"
        ],
        "{cycles:#?}"
    );
    let acyclic = [
        file("mod.rs", "mod strategy;\n"),
        file(
            "strategy.rs",
            "mod certified;\nmod select;\npub struct Args;\n",
        ),
        file("strategy/certified.rs", "use super::Args;\n"),
        file(
            "strategy/select.rs",
            "use super::{Args, certified};\n\n#[cfg(test)]\nmod tests {\n    use super::*;\n    use super::super::Args;\n}\n",
        ),
    ];
    assert_eq!(import_cycles("cmd", &acyclic), Vec::<String>::new());
    let text = "mod job;\npub use job::Job;\npub use crate::x::Y;\npub(crate) use etp_pipeline::output;\n// pub use etp_x::z;\nuse etp_y::w;\n";
    assert_eq!(
        relays_of_other_crates(std::path::Path::new("a.rs"), text),
        ["a.rs:4: pub(crate) use etp_pipeline::output;"]
    );
}
