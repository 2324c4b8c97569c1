//! Docs that run: every command shown in a Markdown file of the repository
//! is run by a test or, where it cannot run on one machine, at least named
//! correctly.
//!
//! * Commands are shown in fenced ```` ```sh ```` blocks; a command of `etp`
//!   in any other block (an indented one, ```` ```bash ````, …) fails
//!   [`every_etp_command_of_the_docs_names_real_subcommands_and_flags`]: it
//!   would escape the run.
//! * The README's `sh` blocks run in `readme.rs`
//!   (`every_command_of_the_readme_runs`, with its own list of commands run
//!   elsewhere); every other Markdown file's run here, in
//!   [`every_command_of_the_other_markdown_files_runs`]: each file's blocks
//!   in order, verbatim, as shell scripts in a scratch folder of their own
//!   (`etp` on the PATH, `python3` the pinned venv's, `--run-id copy` a run
//!   id of the test's own). A new file (`docs/*.md`, any folder's
//!   `README.md`) is covered without a change here.
//! * A block that cannot run in a test (several hosts, a nightly toolchain,
//!   the network) is fenced ```` ```sh no-run ````, and the text before it
//!   says why; keep them rare. Its `etp` commands are still checked: the
//!   subcommands and every `--flag` must be in `etp … --help`, as must those
//!   of every inline `` `etp …` `` of the prose — a refused flag cannot stay
//!   in the docs.

use super::Scratch;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Markdown files not held to this (each with the reason): none, every
/// Markdown file of the repository runs or is checked.
const NOT_COVERED: &[(&str, &str)] = &[];

/// Folders never searched for Markdown: build output, VCS data, vendored code.
const SKIPPED_DIRS: &[&str] = &["target", "third_party", "node_modules"];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .expect("repository root")
}

/// Every Markdown file of the repository (relative paths, sorted), but
/// [`NOT_COVERED`].
pub(super) fn markdown_files() -> Vec<PathBuf> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let path = e.path();
            let name = e.file_name().to_string_lossy().to_string();
            let rel = path
                .strip_prefix(root)
                .expect("under the root")
                .to_path_buf();
            if name.starts_with('.') || NOT_COVERED.iter().any(|(p, _)| rel == Path::new(p)) {
                continue;
            }
            // No symlinks followed: a link out of the checkout is not its doc.
            let Ok(kind) = e.file_type() else { continue };
            if kind.is_dir() {
                if !SKIPPED_DIRS.contains(&name.as_str()) {
                    walk(root, &path, out);
                }
            } else if kind.is_file() && name.ends_with(".md") {
                out.push(rel);
            }
        }
    }
    let root = root();
    let mut out = Vec::new();
    walk(&root, &root, &mut out);
    out.sort();
    out
}

/// A fenced code block: its info string, first line number and lines.
pub(super) struct Fenced {
    pub info: String,
    pub line: usize,
    pub lines: Vec<String>,
}

/// The fenced blocks of a Markdown text and the text outside them (the
/// block lines blanked, so line numbers stay).
pub(super) fn fenced_blocks(text: &str) -> (Vec<Fenced>, String) {
    let mut blocks = Vec::new();
    let mut prose = String::new();
    let mut open: Option<Fenced> = None;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.starts_with("```") {
            match open.take() {
                Some(b) => blocks.push(b),
                None => {
                    open = Some(Fenced {
                        info: t.trim_start_matches('`').trim().to_string(),
                        line: i + 1,
                        lines: Vec::new(),
                    })
                }
            }
            prose.push('\n');
            continue;
        }
        match &mut open {
            Some(b) => {
                b.lines.push(line.to_string());
                prose.push('\n');
            }
            None => {
                prose.push_str(line);
                prose.push('\n');
            }
        }
    }
    (blocks, prose)
}

/// The commands of a block's lines: continuation lines joined, comment
/// lines and trailing comments left out.
pub(super) fn commands(lines: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let mut pending = String::new();
    for line in lines {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        pending.push_str(t.strip_suffix('\\').unwrap_or(t).trim_end());
        if t.ends_with('\\') {
            pending.push(' ');
            continue;
        }
        out.push(without_comment(&std::mem::take(&mut pending)));
    }
    out
}

/// The command without its trailing comment.
pub(super) fn without_comment(line: &str) -> String {
    // A comment starts at " #" outside quotes.
    let mut quote = None;
    let chars: Vec<char> = line.chars().collect();
    for (i, c) in chars.iter().enumerate() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(*c),
            (Some(q), c) if *c == q => quote = None,
            (None, '#') if i > 0 && chars[i - 1] == ' ' => {
                return chars[..i].iter().collect::<String>().trim().to_string();
            }
            _ => {}
        }
    }
    line.trim().to_string()
}

/// The PATH of a docs script: the built `etp` first, then (`python`: the
/// script runs `python3`) the pinned venv's `python3`, made if need be.
pub(super) fn script_path(python: bool) -> String {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_etp"));
    let mut dirs = vec![bin.parent().expect("bin dir").to_path_buf()];
    if python {
        let py = super::pyenv::python();
        dirs.push(py.parent().expect("venv bin").to_path_buf());
    }
    let mut path: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    path.push(std::env::var("PATH").unwrap_or_default());
    path.join(":")
}

/// Run `script` with bash in `dir`; panics with `what`, the script and its
/// stderr if it fails.
pub(super) fn run_script(script: &str, dir: &Path, path: &str, what: &str) {
    let out = Command::new("bash")
        .args(["-c", script])
        .current_dir(dir)
        .env("PATH", path)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .expect("bash");
    assert!(
        out.status.success(),
        "{what} failed:\n{script}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// One block's commands as a script: `set -e`, each command echoed to
/// stderr before it runs, background jobs waited for.
pub(super) fn script_of(commands: &[String]) -> String {
    let mut script = String::from("set -e\n");
    for cmd in commands {
        script.push_str(&format!("echo '+ {}' >&2\n{cmd}\n", cmd.replace('\'', "")));
    }
    script.push_str("wait\n");
    script
}

#[test]
fn every_command_of_the_other_markdown_files_runs() {
    let root = root();
    let mut ran = 0;
    for file in markdown_files() {
        if file == Path::new("README.md") {
            continue; // readme.rs
        }
        let text = std::fs::read_to_string(root.join(&file)).expect("markdown");
        let (blocks, _) = fenced_blocks(&text);
        let runnable: Vec<&Fenced> = blocks.iter().filter(|b| b.info == "sh").collect();
        if runnable.is_empty() {
            continue;
        }
        let dir = Scratch::new("docs");
        let leftovers = super::RunLeftovers::new("docs");
        let python = runnable
            .iter()
            .flat_map(|b| commands(&b.lines))
            .any(|c| c.split_whitespace().any(|w| w == "python3"));
        let path = script_path(python);
        for b in runnable {
            let cmds: Vec<String> = commands(&b.lines)
                .into_iter()
                .map(|c| {
                    let c = c.strip_prefix("target/release/").unwrap_or(&c).to_string();
                    c.replace("--run-id copy", &format!("--run-id {}", leftovers.0))
                })
                .collect();
            for c in &cmds {
                assert!(
                    !has_placeholder(c),
                    "{}:{}: a placeholder no test can fill: {c}",
                    file.display(),
                    b.line
                );
            }
            run_script(
                &script_of(&cmds),
                &dir.0,
                &path,
                &format!("{}:{} (```sh block)", file.display(), b.line),
            );
            ran += cmds.len();
        }
    }
    assert!(ran > 0, "no command run: the Markdown files were not found");
}

/// `<run-id>`, `<scenario>`: a word in angle brackets (a redirection `< f`
/// has a space).
fn has_placeholder(cmd: &str) -> bool {
    cmd.split('<').skip(1).any(|rest| {
        let word: String = rest
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_'))
            .collect();
        !word.is_empty() && rest[word.len()..].starts_with('>')
    })
}

/// The `etp …` invocations of a Markdown text: inline code spans of the
/// prose, and the commands of every fenced block (a line whose program,
/// maybe after `srun`/`mpirun …`, is `etp` or `…/etp`), with their line.
/// Also the `etp` commands outside `sh` blocks, which must not be there.
struct Invocations {
    found: Vec<(usize, String)>,
    misplaced: Vec<(usize, String)>,
}

fn invocations(text: &str) -> Invocations {
    let (blocks, prose) = fenced_blocks(text);
    let mut found = Vec::new();
    let mut misplaced = Vec::new();
    for b in &blocks {
        let sh = b.info == "sh" || b.info == "sh no-run";
        for (i, line) in b.lines.iter().enumerate() {
            if let Some(words) = etp_words(line) {
                if sh {
                    found.push((b.line + 1 + i, words));
                } else {
                    misplaced.push((b.line + 1 + i, line.trim().to_string()));
                }
            }
        }
        if sh {
            // Continuation lines: check the joined commands too.
            for c in commands(&b.lines) {
                if let Some(words) = etp_words(&c) {
                    found.push((b.line, words));
                }
            }
        }
    }
    // Indented code blocks of the prose (a diagram's `etp strategy ◀──`
    // is not a command: commands are ASCII).
    for (i, line) in prose.lines().enumerate() {
        if line.starts_with("    ") && etp_words(line).is_some() && without_comment(line).is_ascii()
        {
            misplaced.push((i + 1, line.trim().to_string()));
        }
    }
    for (line, span) in code_spans(&prose) {
        if span.starts_with("etp ") {
            found.push((line, span));
        }
    }
    Invocations { found, misplaced }
}

/// The `etp` invocation of a shell line, from `etp` on: the program is
/// `etp` or a path ending in `/etp`, first or after a launcher.
fn etp_words(line: &str) -> Option<String> {
    let line = without_comment(line);
    let tokens: Vec<&str> = line.split_whitespace().collect();
    let first = *tokens.first()?;
    let at = if first == "etp" || first.ends_with("/etp") {
        0
    } else if matches!(first, "srun" | "mpirun" | "exec" | "time" | "nice") {
        tokens
            .iter()
            .position(|t| *t == "etp" || t.ends_with("/etp"))?
    } else {
        return None;
    };
    let mut out = vec!["etp"];
    out.extend(&tokens[at + 1..]);
    Some(out.join(" "))
}

/// Inline code spans (`` `…` ``, ``` `` … `` ```) of a text with their
/// line, whitespace (line breaks included) collapsed to one space.
fn code_spans(text: &str) -> Vec<(usize, String)> {
    let chars: Vec<char> = text.chars().collect();
    let mut spans = Vec::new();
    let (mut i, mut line) = (0, 1);
    while i < chars.len() {
        if chars[i] == '\n' {
            line += 1;
            i += 1;
            continue;
        }
        if chars[i] != '`' {
            i += 1;
            continue;
        }
        let run = chars[i..].iter().take_while(|&&c| c == '`').count();
        let start = i + run;
        // The closing run of the same length.
        let mut j = start;
        let mut close = None;
        while j < chars.len() {
            if chars[j] == '`' {
                let r = chars[j..].iter().take_while(|&&c| c == '`').count();
                if r == run {
                    close = Some(j);
                    break;
                }
                j += r;
            } else {
                j += 1;
            }
        }
        match close {
            Some(end) => {
                let body: String = chars[start..end].iter().collect();
                spans.push((line, body.split_whitespace().collect::<Vec<_>>().join(" ")));
                line += body.matches('\n').count();
                i = end + run;
            }
            None => i = start,
        }
    }
    spans
}

/// Subcommands whose arguments are another program's (`etp process NAME
/// ARGS…` runs the named process with its own command line): not checked.
const RAW_ARGS: &[&str] = &["process"];

/// `etp [path…] --help`: (subcommands, flags), cached per path.
struct Help {
    cache: HashMap<Vec<String>, (Vec<String>, Vec<String>)>,
}

impl Help {
    fn of(&mut self, path: &[String]) -> &(Vec<String>, Vec<String>) {
        self.cache.entry(path.to_vec()).or_insert_with(|| {
            let out = Command::new(env!("CARGO_BIN_EXE_etp"))
                .args(path)
                .arg("--help")
                .output()
                .expect("etp --help");
            assert!(out.status.success(), "etp {path:?} --help failed");
            let text = String::from_utf8_lossy(&out.stdout).to_string();
            let mut subcommands = Vec::new();
            let mut in_commands = false;
            let mut flags = Vec::new();
            for line in text.lines() {
                if line.starts_with("Commands:") {
                    in_commands = true;
                    continue;
                }
                if in_commands {
                    match line.split_whitespace().next() {
                        Some(w) if line.starts_with("  ") => subcommands.push(w.to_string()),
                        _ => in_commands = false,
                    }
                }
                let t = line.trim_start();
                if t.starts_with('-') {
                    // "-o, --out <DIR>", "--json", "--loop [<N>]"
                    for w in t.split(|c: char| c == ',' || c.is_whitespace()) {
                        if w.starts_with('-') && w.len() > 1 {
                            flags.push(w.split(['=', '[', '<']).next().unwrap_or(w).to_string());
                        }
                    }
                }
            }
            (subcommands, flags)
        })
    }
}

/// What is wrong with one `etp …` invocation as the docs show it: a word
/// that is taken for a subcommand but is none, or a flag its (sub)command
/// does not have. Words in the docs' notation (`FILE`, `[--json]`,
/// `info\|cat`, `…`) are read as such.
fn check_invocation(help: &mut Help, words: &str) -> Option<String> {
    let words = words.replace("\\|", "|");
    let tokens: Vec<&str> = words.split_whitespace().skip(1).collect();
    // `etp … --json`: any command; `etp process NAME …`: another program's flags.
    if tokens
        .first()
        .is_some_and(|t| matches!(*t, "…" | "...") || RAW_ARGS.contains(t))
    {
        return None;
    }
    let mut paths: Vec<Vec<String>> = vec![Vec::new()];
    let mut i = 0;
    // Descend while the word names subcommands (alternatives `a|b` each).
    while i < tokens.len() {
        let alternatives: Vec<&str> = tokens[i].split('|').collect();
        let subs = &help.of(&paths[0]).0.clone();
        if subs.is_empty() || !alternatives.iter().all(|a| subs.iter().any(|s| s == a)) {
            break;
        }
        let base = paths[0].clone();
        paths = alternatives
            .iter()
            .map(|a| {
                let mut p = base.clone();
                p.push(a.to_string());
                p
            })
            .collect();
        i += 1;
        if paths.len() > 1 {
            break;
        }
    }
    for t in &tokens[i..] {
        if matches!(*t, "|" | "&&" | ";" | ">" | "&" | "#") {
            break;
        }
        let t = t.trim_start_matches(['[', '(']);
        if !t.starts_with('-') || t.len() < 2 || t[1..].starts_with(|c: char| c.is_ascii_digit()) {
            continue;
        }
        let flag = t
            .split(['=', ']', ')', ',', '`', '…'])
            .next()
            .unwrap_or(t)
            .trim_end_matches('.');
        if flag == "--" || flag == "-" {
            continue;
        }
        if !paths.iter().any(|p| help.of(p).1.iter().any(|f| f == flag)) {
            let shown: Vec<String> = paths
                .iter()
                .map(|p| format!("etp {}", p.join(" ")))
                .collect();
            return Some(format!("{flag} is not an option of {}", shown.join(" / ")));
        }
    }
    None
}

#[test]
fn every_etp_command_of_the_docs_names_real_subcommands_and_flags() {
    let root = root();
    let mut help = Help {
        cache: HashMap::new(),
    };
    let mut bad = Vec::new();
    let mut checked = 0;
    for file in markdown_files() {
        let text = std::fs::read_to_string(root.join(&file)).expect("markdown");
        let inv = invocations(&text);
        for (line, cmd) in inv.misplaced {
            bad.push(format!(
                "{}:{line}: an etp command outside a ```sh block (no test would run it): {cmd}",
                file.display()
            ));
        }
        for (line, words) in inv.found {
            checked += 1;
            if let Some(why) = check_invocation(&mut help, &words) {
                bad.push(format!("{}:{line}: `{words}`: {why}", file.display()));
            }
        }
    }
    assert!(
        checked > 50,
        "only {checked} etp commands found in the docs"
    );
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn the_docs_checker_reads_the_notation_and_catches_a_refused_flag() {
    let mut help = Help {
        cache: HashMap::new(),
    };
    for ok in [
        "etp replay info\\|cat FILE",
        "etp replay export FILE DIR [--format csv|jsonl]",
        "etp strategy DIR --min-target P [--max-collision C]",
        "etp run … --live [ADDR:PORT] [--live-wait]",
        "etp replay cat FILE --topics outcome,ledger | head",
        "etp synthesize winding-2d -o out/w",
        "etp … --json",
        "etp process etp-recorder --run-id copy --out copy.mcap",
    ] {
        assert_eq!(check_invocation(&mut help, ok), None, "{ok}");
    }
    for (bad, flag) in [
        ("etp replay FILE --export DIR", "--export"),
        (
            "etp replay foxglove FILE OUT --foxglove-clock recorded",
            "--foxglove-clock",
        ),
        ("etp simulate winding-2d --detla 1", "--detla"),
    ] {
        let why = check_invocation(&mut help, bad).unwrap_or_default();
        assert!(why.starts_with(flag), "{bad}: {why}");
    }
    let text = "Run `etp check\nwinding-2d --jsn` first.\n\n    etp check x\n    etp run ◀── diagram\n\n```bash\nsrun target/release/etp check x\n```\n";
    let inv = invocations(text);
    assert_eq!(
        inv.found,
        vec![(1, "etp check winding-2d --jsn".to_string())]
    );
    assert_eq!(inv.misplaced.len(), 2, "{:?}", inv.misplaced);
    assert!(has_placeholder("etp replay recordings/w-<run-id>.mcap"));
    assert!(!has_placeholder("python3 x.py < in.txt > out.txt"));
}

/// The repository's files a text names: every `docs/…`, `benchmarks/…`,
/// `schemas/…`, `scenarios/…` or `recordings/…` path with an extension.
fn named_files(text: &str) -> Vec<String> {
    const ROOTS: [&str; 5] = [
        "docs/",
        "benchmarks/",
        "schemas/",
        "scenarios/",
        "recordings/",
    ];
    let path_char = |c: char| c.is_ascii_alphanumeric() || "_.-/".contains(c);
    let mut out = Vec::new();
    for (i, _) in text.char_indices() {
        let rest = &text[i..];
        // A path starts at a word boundary: not inside `target/docs/…`.
        let boundary = text[..i].chars().last().is_none_or(|c| !path_char(c));
        if !boundary || !ROOTS.iter().any(|r| rest.starts_with(r)) {
            continue;
        }
        let end = rest.find(|c: char| !path_char(c)).unwrap_or(rest.len());
        let path = rest[..end].trim_end_matches(['.', '/']);
        let has_extension = path
            .rsplit('/')
            .next()
            .is_some_and(|name| name.contains('.') && !name.ends_with('.'));
        if has_extension {
            out.push(path.to_string());
        }
    }
    out
}

/// The Rust sources of the workspace (their comments cite docs too).
fn rust_files(root: &Path, dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Ok(kind) = e.file_type() else { continue };
        if kind.is_dir() && !name.starts_with('.') && !SKIPPED_DIRS.contains(&name.as_str()) {
            rust_files(root, &e.path(), out);
        } else if kind.is_file() && name.ends_with(".rs") {
            out.push(
                e.path()
                    .strip_prefix(root)
                    .unwrap_or(&e.path())
                    .to_path_buf(),
            );
        }
    }
}

/// Every file a Markdown file or a Rust source of the repository names
/// exists: neither docs nor comments cite a file the repository does not
/// hold.
#[test]
fn every_file_the_docs_name_exists() {
    let root = root();
    let mut missing = Vec::new();
    let mut files = markdown_files();
    rust_files(&root, &root, &mut files);
    for md in files {
        let text = std::fs::read_to_string(root.join(&md)).expect("a readable text file");
        for path in named_files(&text) {
            // A user's own file in an example (`my-…`) or a name to fill
            // in (`NAME`) is not the repository's.
            let name = path.rsplit('/').next().unwrap_or_default();
            let stem = name.split('.').next().unwrap_or_default();
            let placeholder = name.starts_with("my-")
                || (!stem.is_empty() && stem.chars().all(|c| c.is_ascii_uppercase()));
            if !placeholder && !root.join(&path).exists() {
                missing.push(format!("{}: {path}", md.display()));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "files named but absent:\n{}",
        missing.join("\n")
    );
}

#[test]
fn named_files_are_read_at_word_boundaries() {
    assert_eq!(
        named_files("see docs/MODEL.md §3, target/docs/x.md and `schemas/run.json`."),
        ["docs/MODEL.md", "schemas/run.json"]
    );
    assert!(named_files("docs/ and recordings/README").is_empty());
}
