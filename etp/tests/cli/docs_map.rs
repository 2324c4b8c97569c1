//! The documentation stays a map, not a journal: ARCHITECTURE.md is at most
//! 250 lines and names only what exists (repository paths, types, tests),
//! and the README's command table keeps its cells short (the detail is in
//! `etp CMD --help` and docs/cli.md).

use std::path::{Path, PathBuf};

/// ARCHITECTURE.md's length limit, in lines.
const MAP_LINES: usize = 250;
/// The longest cell of the README's command table, in characters.
const CELL_CHARS: usize = 200;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// The text between backticks, in order (a code span may wrap a line: its
/// line break reads as a space).
fn code_spans(text: &str) -> Vec<String> {
    text.split('`')
        .skip(1)
        .step_by(2)
        .map(|s| s.split_whitespace().collect::<Vec<_>>().join(" "))
        .collect()
}

/// A code span that is a path in the repository: only path characters, and
/// a folder separator or a Markdown file name (`README.md`).
fn is_repo_path(span: &str) -> bool {
    !span.is_empty()
        && !span.starts_with(['-', '/', '.'])
        && span
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c))
        && (span.contains('/') || span.ends_with(".md"))
}

/// The type names of a code span: its `::` segments in UpperCamelCase.
fn type_names(span: &str) -> Vec<&str> {
    span.split("::")
        .filter(|s| {
            let mut c = s.chars();
            c.next().is_some_and(|c| c.is_ascii_uppercase())
                && c.next().is_some_and(|c| c.is_ascii_lowercase())
                && s.chars().all(|c| c.is_ascii_alphanumeric())
        })
        .collect()
}

/// The tests a text names: the code spans after the word `test` or `tests`,
/// one or several separated by commas or "and".
fn named_tests(text: &str) -> Vec<String> {
    let flat = text.split_whitespace().collect::<Vec<_>>().join(" ");
    let mut names = Vec::new();
    for (i, _) in flat.match_indices("test") {
        let word_start = i == 0 || !flat[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_');
        if !word_start {
            continue;
        }
        let mut rest = &flat[i + 4..];
        rest = rest.strip_prefix('s').unwrap_or(rest);
        while let Some(r) = rest.strip_prefix(" `") {
            let Some(end) = r.find('`') else { break };
            names.push(r[..end].to_string());
            rest = &r[end + 1..];
            rest = rest.strip_prefix(',').unwrap_or(rest);
            if let Some(r) = rest.strip_prefix(" and") {
                rest = r;
            }
        }
    }
    names
}

/// Every `.rs` file of the workspace (not `target/`, `third_party/`, `.git/`).
fn rust_sources() -> Vec<(PathBuf, String)> {
    let mut out = Vec::new();
    let mut dirs = vec![root()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).expect("readable folder").flatten() {
            let p = e.path();
            let name = e.file_name();
            if p.is_dir() {
                if !matches!(name.to_str(), Some("target" | "third_party" | ".git")) {
                    dirs.push(p);
                }
            } else if p.extension().is_some_and(|x| x == "rs") {
                let text = std::fs::read_to_string(&p).expect("readable source");
                out.push((p, text));
            }
        }
    }
    out
}

/// Whether `name` (or `module::name`) is a test function of the workspace:
/// `fn name(` under a test attribute, in a file or folder named `module`.
fn is_test(sources: &[(PathBuf, String)], named: &str) -> bool {
    let (module, name) = match named.rsplit_once("::") {
        Some((m, n)) => (Some(m.rsplit("::").next().unwrap_or(m)), n),
        None => (None, named),
    };
    let needle = format!("fn {name}(");
    sources.iter().any(|(path, text)| {
        let in_module = module.is_none_or(|m| {
            path.iter()
                .any(|c| c.to_str().is_some_and(|c| c.trim_end_matches(".rs") == m))
        });
        in_module
            && text.match_indices(&needle).any(|(at, _)| {
                let before: Vec<&str> = text[..at].lines().rev().take(6).collect();
                before.iter().any(|l| {
                    let l = l.trim();
                    l.starts_with("#[") && (l.contains("test]") || l.contains("test("))
                })
            })
    })
}

/// Whether a type of that name is declared in the workspace.
fn is_type(sources: &[(PathBuf, String)], name: &str) -> bool {
    ["struct", "enum", "trait", "type"].iter().any(|kw| {
        let decl = format!("{kw} {name}");
        sources.iter().any(|(_, text)| {
            text.match_indices(&decl).any(|(at, _)| {
                let next = text[at + decl.len()..].chars().next();
                !next.is_some_and(|c| c.is_alphanumeric() || c == '_')
            })
        })
    })
}

#[test]
fn the_architecture_map_names_only_what_exists() {
    let text = read("ARCHITECTURE.md");
    let lines = text.lines().count();
    assert!(
        lines <= MAP_LINES,
        "ARCHITECTURE.md has {lines} lines (at most {MAP_LINES}): move detail into the crates' docs"
    );
    let spans = code_spans(&text);
    let missing_paths: Vec<&String> = spans
        .iter()
        .filter(|s| is_repo_path(s) && !root().join(s).exists())
        .collect();
    let sources = rust_sources();
    assert!(sources.len() > 100, "{} Rust files", sources.len());
    let mut types: Vec<&str> = spans.iter().flat_map(|s| type_names(s)).collect();
    types.sort();
    types.dedup();
    let missing_types: Vec<&str> = types
        .iter()
        .copied()
        .filter(|t| !is_type(&sources, t))
        .collect();
    let tests = named_tests(&text);
    assert!(tests.len() >= 20, "{} tests named: {tests:?}", tests.len());
    let missing_tests: Vec<&String> = tests.iter().filter(|t| !is_test(&sources, t)).collect();
    assert!(
        missing_paths.is_empty() && missing_types.is_empty() && missing_tests.is_empty(),
        "ARCHITECTURE.md names what does not exist:\npaths {missing_paths:?}\ntypes {missing_types:?}\ntests {missing_tests:?}"
    );
}

#[test]
fn the_checks_of_the_map_see_what_they_should() {
    assert!(is_repo_path("runtime/src/wire/catalogue.rs") && is_repo_path("README.md"));
    assert!(!is_repo_path("etp/<run-id>/x") && !is_repo_path("mdp.bin") && !is_repo_path("--json"));
    assert_eq!(type_names("Mdp::check"), ["Mdp"]);
    assert!(type_names("SYNTHESIS").is_empty() && type_names("stream_rng").is_empty());
    assert_eq!(
        named_tests("tests `a`,\n  `b` and `c`; the test `d` (test `m::e`). Its tests run."),
        ["a", "b", "c", "d", "m::e"]
    );
    let sources = rust_sources();
    assert!(is_test(
        &sources,
        "the_architecture_map_names_only_what_exists"
    ));
    assert!(is_test(
        &sources,
        "docs_map::the_architecture_map_names_only_what_exists"
    ));
    assert!(!is_test(
        &sources,
        "readme::the_architecture_map_names_only_what_exists"
    ));
    assert!(!is_test(&sources, "rust_sources"));
    assert!(is_type(&sources, "Scenario") && !is_type(&sources, "Scenari"));
    assert!(Path::new(&root()).join("ARCHITECTURE.md").is_file());
}

/// The cells of the first Markdown table after `heading`, split on the
/// unescaped `|`.
fn table_cells(text: &str, heading: &str) -> Vec<String> {
    let after = &text[text.find(heading).unwrap_or_else(|| panic!("{heading}"))..];
    let rows = after
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'));
    let mut cells = Vec::new();
    for row in rows {
        let mut cell = String::new();
        let mut prev = ' ';
        for c in row.trim().trim_matches('|').chars() {
            if c == '|' && prev != '\\' {
                cells.push(std::mem::take(&mut cell).trim().to_string());
            } else {
                cell.push(c);
            }
            prev = c;
        }
        cells.push(cell.trim().to_string());
    }
    cells
}

#[test]
fn the_readme_command_table_has_short_cells_and_each_command_a_section_in_docs_cli() {
    let readme = read("README.md");
    let cells = table_cells(&readme, "## Commands");
    assert!(cells.len() > 40, "{} cells", cells.len());
    let long: Vec<String> = cells
        .iter()
        .filter(|c| c.chars().count() > CELL_CHARS)
        .map(|c| format!("{} characters: {c}", c.chars().count()))
        .collect();
    assert!(
        long.is_empty(),
        "README command-table cells over {CELL_CHARS} characters (move the detail to `etp CMD --help` and docs/cli.md):\n{}",
        long.join("\n")
    );
    // Every command of the table has its section in docs/cli.md.
    let cli = read("docs/cli.md");
    let headings: Vec<&str> = cli.lines().filter(|l| l.starts_with("## ")).collect();
    for cell in cells.iter().step_by(2).skip(2) {
        let Some(cmd) = cell
            .strip_prefix("`etp ")
            .and_then(|c| c.split([' ', '`', '\\']).next())
        else {
            continue;
        };
        assert!(
            headings.iter().any(|h| h.contains(&format!("etp {cmd}"))),
            "docs/cli.md has no section for etp {cmd}: {headings:?}"
        );
    }
}
