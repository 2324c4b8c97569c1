//! The command line as a user meets it: one exit code for one kind of
//! error (a bad value is clap's usage error, 2, on every command), a help
//! line for every option and argument (ranges and units said), `etp process
//! --help`, options that would do nothing refused by name, and outputs only
//! where the user said (a missing folder refused, not made).

use super::{Scratch, etp, fails_with, s};
use clap::FromArgMatches;

fn code(args: &[&str]) -> (Option<i32>, String) {
    let out = etp(args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `--episodes 0` and `--episodes -1` are the same kind of error on every
/// command: a bad value of the option named (exit 2) with the range it
/// takes, never an error of the command (1) nor an unknown argument `-1`
/// with a tip to write `-- -1`.
#[test]
fn a_bad_episode_count_is_a_usage_error_on_every_command() {
    let commands: [&[&str]; 6] = [
        &[
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "1.4986",
            "--episodes",
        ],
        &["validate", "strategy.json", "--episodes"],
        &["simulate", "open-2d", "--delta", "1.4986", "--episodes"],
        &["trigger-curves", "open-2d", "--episodes"],
        &["bench", "open-2d", "--episodes"],
        &["demo", "--run-episodes"],
    ];
    for command in commands {
        for value in ["0", "-1"] {
            let mut args = command.to_vec();
            args.push(value);
            let (rc, err) = code(&args);
            assert_eq!(rc, Some(2), "etp {args:?}: {err}");
            let option = command.last().expect("the option");
            assert!(
                err.contains(&format!("invalid value '{value}' for '{option}")),
                "etp {args:?}: {err}"
            );
            assert!(!err.contains("-- -1"), "etp {args:?}: {err}");
            assert!(err.contains("a whole number ≥ 1"), "etp {args:?}: {err}");
        }
    }
}

/// A value outside its option's range is a usage error on every option
/// that has one (exit 2, the option and its range named), refused before
/// any work: not an error of the command (1) after a synthesis, a run file
/// with `null` in it, or an empty output folder left behind.
#[test]
fn a_value_out_of_range_is_a_usage_error_naming_the_range() {
    let dir = Scratch::new("value-ranges");
    let out = dir.path("out");
    let run = ["run", "--scenario", "open-2d", "--delta", "1.4986"];
    let sim = ["simulate", "open-2d", "--delta", "1.4986"];
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            vec!["synthesize", "open-2d", "-o", s(&out), "--samples", "0"],
            "--samples",
            "≥ 1",
        ),
        (
            vec!["demo", "-o", s(&out), "--min-target", "2"],
            "--min-target",
            "[0, 1]",
        ),
        (
            vec!["demo", "-o", s(&out), "--samples", "0"],
            "--samples",
            "≥ 1",
        ),
        (
            vec!["demo", "-o", s(&out), "--front-points", "1"],
            "--front-points",
            "from 2 to 64",
        ),
        (
            [&run[..], &["--predict-episodes", "0"]].concat(),
            "--predict-episodes",
            "≥ 1",
        ),
        (
            [&run[..], &["--clone-sensors", "65"]].concat(),
            "--clone-sensors",
            "from 1 to 64",
        ),
        (
            [&run[..], &["--deadline", "-1"]].concat(),
            "--deadline",
            "seconds > 0",
        ),
        (
            [&run[..], &["--join-timeout", "0"]].concat(),
            "--join-timeout",
            "seconds > 0",
        ),
        (
            [&run[..], &["--slot-deadline", "0"]].concat(),
            "--slot-deadline",
            "≥ 1",
        ),
        (
            vec!["run", "--scenario", "open-2d", "--delta", "-1"],
            "--delta",
            "≥ 0",
        ),
        ([&sim[..], &["--loss", "1"]].concat(), "--loss", "[0, 1)"),
        (
            [&sim[..], &["--loss", "0.1", "--retries", "-1"]].concat(),
            "--retries",
            "from 0 to 1000",
        ),
        (
            [&sim[..], &["--loss", "0.1", "--burst", "0.5"]].concat(),
            "--burst",
            "≥ 1",
        ),
        (
            vec!["simulate", "open-2d", "--delta", "-1"],
            "--delta",
            "≥ 0",
        ),
        (
            vec![
                "strategy",
                s(&out),
                "--min-target",
                "0.9",
                "--replicates",
                "-1",
            ],
            "--replicates",
            "from 2 to 64",
        ),
        (
            vec!["strategy", s(&out), "--min-target", "0.9", "--rounds", "21"],
            "--rounds",
            "from 1 to 20",
        ),
        (vec!["fronts", s(&out), "--points", "1"], "--points", "≥ 2"),
        (
            vec!["fronts", s(&out), "--max-collision", "2"],
            "--max-collision",
            "[0, 1]",
        ),
        (
            vec!["certs", "init", s(&out), "--days", "0"],
            "--days",
            "from 1 to 3650",
        ),
        (
            vec!["bench", "open-2d", "--repeats", "0"],
            "--repeats",
            "≥ 1",
        ),
        (
            vec!["bench", "--front", "--tolerance", "-1"],
            "--tolerance",
            "> 0",
        ),
        (
            vec![
                "synthesize",
                "open-2d",
                "-o",
                s(&out),
                "--magnitude-bins",
                "0",
            ],
            "--magnitude-bins",
            "from 1 to 65535",
        ),
        (
            vec!["synthesize", "open-2d", "-o", s(&out), "--pool", "0"],
            "--pool",
            "≥ 1",
        ),
        (
            vec!["synthesize", "open-2d", "-o", s(&out), "--merge", "2"],
            "--merge",
            "(0, 1)",
        ),
        (
            vec![
                "synthesize",
                "open-2d",
                "-o",
                s(&out),
                "--aggregation-alpha",
                "2",
            ],
            "--aggregation-alpha",
            "(0, 1)",
        ),
        (
            vec!["synthesize", "open-2d", "-o", s(&out), "--split-alpha", "0"],
            "--split-alpha",
            "(0, 1)",
        ),
        (
            vec![
                "synthesize",
                "open-2d",
                "-o",
                s(&out),
                "--split-rounds",
                "0",
            ],
            "--split-rounds",
            "≥ 1",
        ),
        (
            vec![
                "synthesize",
                "open-2d",
                "-o",
                s(&out),
                "--method",
                "kf-convergence",
                "--eps-kf",
                "-1",
            ],
            "--eps-kf",
            "> 0",
        ),
        (
            vec![
                "sensor-host",
                "--connect",
                "tcp/127.0.0.1:9",
                "--join-timeout",
                "0",
            ],
            "--join-timeout",
            "seconds > 0",
        ),
    ];
    // `--loop 0` looped without end; `--loop` alone still means that.
    let publish = ["replay", "publish", "r.mcap", "--loop"];
    assert!(
        etp::cli::command()
            .try_get_matches_from([&["etp"][..], &publish[..]].concat())
            .is_ok()
    );
    let mut cases = cases;
    let refine = [
        "strategy",
        "x",
        "--min-target",
        "0.9",
        "--confidence",
        "0.95",
    ];
    cases.push((
        [&refine[..], &["--refine-gap", "-0.01"]].concat(),
        "--refine-gap",
        "> 0",
    ));
    cases.push(([&publish[..], &["0"]].concat(), "--loop", "≥ 1"));
    for (args, option, range) in cases {
        let (rc, err) = code(&args);
        assert_eq!(rc, Some(2), "etp {args:?}: {err}");
        assert!(
            err.contains(&format!("for '{option}")) && err.contains(range),
            "etp {args:?} should name {option} and {range}: {err}"
        );
        assert!(!out.exists(), "etp {args:?} wrote {}", out.display());
    }
}

/// Every option and argument of every command has a help line; the ones
/// with a range or a unit say it.
#[test]
fn every_option_has_a_help_line_with_its_range() {
    fn walk(c: &clap::Command, path: &str, empty: &mut Vec<String>) {
        for a in c.get_arguments() {
            let id = a.get_id().as_str();
            if a.is_hide_set() || id == "help" || id == "version" {
                continue;
            }
            if a.get_help().is_none_or(|h| h.to_string().trim().is_empty()) {
                empty.push(format!("{path} {id}"));
            }
        }
        for sub in c.get_subcommands() {
            walk(sub, &format!("{path} {}", sub.get_name()), empty);
        }
    }
    let mut cmd = etp::cli::command();
    cmd.build();
    let mut empty = Vec::new();
    walk(&cmd, "etp", &mut empty);
    assert!(empty.is_empty(), "options without a help line: {empty:?}");

    let help = |args: &[&str]| {
        let out = etp(args);
        assert_eq!(out.status.code(), Some(0), "etp {args:?}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let strategy = help(&["strategy", "--help"]);
    for needle in [
        "R in 2..=64",
        "(1..=20)",
        "energy unit",
        "P in [0, 1]",
        "level (in (0, 1)",
        "(a probability, G > 0)",
    ] {
        assert!(strategy.contains(needle), "lacks {needle:?}: {strategy}");
    }
    let run = help(&["run", "--help"]);
    assert!(run.contains("Number of episodes (at least 1)"), "{run}");
    assert!(run.contains("link), 0 to 1000"), "--retries' range: {run}");
    for sub in ["filter", "repair", "foxglove", "export", "plot", "summary"] {
        let h = help(&["replay", sub, "--help"]);
        assert!(h.contains("An MCAP recording"), "replay {sub}: {h}");
    }
}

/// `etp process --help` says what the hidden command does; a process's own
/// `--help` still reaches the process.
#[test]
fn process_has_a_help() {
    let out = etp(&["process", "--help"]);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("etp-sensor-node"), "{text}");
    let out = etp(&["process", "etp-recorder", "--help"]);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("--run-id"), "the recorder's own help: {text}");
}

/// `--retries`/`--burst` on a channel that loses nothing would change
/// nothing: refused by name, on `simulate` and on `run` (before any
/// process starts). With a loss they are taken.
#[test]
fn retries_without_a_loss_are_refused_by_name() {
    for extra in [&["--retries", "1000"][..], &["--loss", "0", "--burst", "3"]] {
        let mut sim = vec![
            "simulate",
            "open-2d",
            "--delta",
            "1.4986",
            "--episodes",
            "5",
        ];
        sim.extend(extra);
        fails_with(&sim, &[extra[extra.len() - 2], "does nothing", "--loss"]);
        // The option's name, not a scenario field's.
        let (rc, err) = code(&sim);
        assert_eq!(rc, Some(1), "{err}");
        assert!(!err.contains("scenario field"), "{err}");
        let mut run = vec![
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "1.4986",
            "--episodes",
            "1",
        ];
        run.extend(extra);
        let (rc, err) = code(&run);
        assert_eq!(rc, Some(1), "{err}");
        assert!(
            err.contains(extra[extra.len() - 2]) && err.contains("--loss"),
            "{err}"
        );
    }
    let out = etp(&[
        "simulate",
        "open-2d",
        "--delta",
        "1.4986",
        "--episodes",
        "5",
        "--loss",
        "0.2",
        "--retries",
        "2",
        "--json",
    ]);
    assert!(out.status.success(), "{out:?}");
}

/// `--live localhost:PORT` is the loopback, as `127.0.0.1:PORT` is.
#[test]
fn live_accepts_localhost() {
    let parse = |addr: &str| {
        let m = etp::cli::command()
            .try_get_matches_from([
                "etp",
                "run",
                "--scenario",
                "open-2d",
                "--delta",
                "1.4986",
                "--live",
                addr,
            ])
            .map_err(|e| e.to_string())?;
        match etp::cli::Cli::from_arg_matches(&m).map_err(|e| e.to_string())? {
            etp::cli::Cli {
                command: etp::cli::Command::Run(a),
            } => Ok(a.live),
            _ => Err("not a run".to_string()),
        }
    };
    let loopback: std::net::SocketAddr = "127.0.0.1:8765".parse().expect("addr");
    assert_eq!(parse("localhost:8765"), Ok(Some(loopback)));
    assert_eq!(parse("LOCALHOST:8765"), Ok(Some(loopback)));
    assert_eq!(parse("127.0.0.1:8765"), Ok(Some(loopback)));
    let e = parse("localhost").expect_err("no port");
    assert!(e.contains("--live") && e.contains("ADDR:PORT"), "{e}");
    let e = parse("localhost:99999").expect_err("bad port");
    assert!(e.contains("port"), "{e}");
}

/// `--record` into a folder that does not exist is refused by name (the
/// folder is not made); a folder as the target is refused by name, with
/// or without `--force`. Nothing is written.
#[test]
fn record_refuses_a_missing_folder_and_a_folder_by_name() {
    let dir = Scratch::new("record-target");
    let run = |target: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "run",
            "--scenario",
            "open-2d",
            "--delta",
            "1.4986",
            "--episodes",
            "1",
            "--record",
            s(target),
        ];
        args.extend(extra);
        code(&args)
    };
    let missing = dir.path("a/b/c.mcap");
    let (rc, err) = run(&missing, &[]);
    assert_eq!(rc, Some(1), "{err}");
    assert!(
        err.contains("--record") && err.contains("does not exist") && err.contains("a/b"),
        "{err}"
    );
    assert!(!dir.path("a").exists(), "the missing folder was made");
    let folder = dir.path("existing");
    std::fs::create_dir(&folder).expect("folder");
    for extra in [&[][..], &["--force"]] {
        let (rc, err) = run(&folder, extra);
        assert_eq!(rc, Some(1), "{extra:?}: {err}");
        assert!(
            err.contains("--record") && err.contains("is a folder") && !err.contains("use --force"),
            "{extra:?}: {err}"
        );
    }
    assert_eq!(std::fs::read_dir(&folder).expect("folder").count(), 0);
}

/// Every file the user names with `-o` goes into a folder that exists: a
/// missing one is refused by name before any work (exit 1), never made.
#[test]
fn every_named_output_file_needs_its_folder() {
    let dir = Scratch::new("named-outputs");
    let missing = dir.path("no");
    let file = |name: &str| missing.join(name);
    let (stem, json, toml) = (file("figure"), file("s.json"), file("s.toml"));
    let synthesis = dir.path("synthesis");
    let cases: [Vec<&str>; 6] = [
        vec![
            "trigger-curves",
            "open-2d",
            "--episodes",
            "5",
            "-o",
            s(&stem),
        ],
        vec!["fronts", s(&synthesis), "-o", s(&stem)],
        vec![
            "strategy",
            s(&synthesis),
            "--min-target",
            "0.9",
            "-o",
            s(&json),
        ],
        vec![
            "strategy",
            "evaluate",
            s(&json),
            s(&synthesis),
            "-o",
            s(&json),
        ],
        vec![
            "scenario",
            "random",
            "--dim-agent",
            "2",
            "--seed",
            "1",
            "-o",
            s(&toml),
        ],
        vec![
            "scenario",
            "radio",
            "open-2d",
            "--loss",
            "0.1",
            "-o",
            s(&toml),
        ],
    ];
    for args in cases {
        let (rc, err) = code(&args);
        assert_eq!(rc, Some(1), "etp {args:?}: {err}");
        assert!(
            err.contains("-o ")
                && err.contains(&format!("the folder {} does not exist", missing.display())),
            "etp {args:?}: {err}"
        );
        assert!(!missing.exists(), "etp {args:?} made the folder");
    }
}

/// A folder where an output file goes is refused as a folder at once, with
/// or without `--force` (not "use --force", then "Is a directory" after
/// the work), and left as it was.
#[test]
fn an_output_that_is_a_folder_is_refused_as_one() {
    let dir = Scratch::new("output-folder");
    let folder = dir.path("taken");
    std::fs::create_dir(&folder).expect("folder");
    let recording = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../recordings/fixtures/open-2d-4-episodes.mcap");
    let cases: [Vec<&str>; 3] = [
        vec![
            "scenario",
            "random",
            "--dim-agent",
            "2",
            "--seed",
            "1",
            "-o",
            s(&folder),
        ],
        vec!["replay", "filter", s(&recording), s(&folder)],
        vec!["replay", "repair", s(&recording), s(&folder)],
    ];
    for case in cases {
        for force in [false, true] {
            let mut args = case.clone();
            if force {
                args.push("--force");
            }
            let (rc, err) = code(&args);
            assert_eq!(rc, Some(1), "etp {args:?}: {err}");
            assert!(
                err.contains(&format!("{} is a folder", folder.display()))
                    && !err.contains("use --force")
                    && !err.contains("os error"),
                "etp {args:?}: {err}"
            );
            assert_eq!(std::fs::read_dir(&folder).expect("folder").count(), 0);
        }
    }
}

/// The open-2d strategy fixture, copied into `dir` as `s.json`.
fn open_2d_strategy(dir: &Scratch) -> std::path::PathBuf {
    let strategy = dir.path("s.json");
    std::fs::copy(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/tests/fixtures/strategy-open-2d-predicted.json"),
        &strategy,
    )
    .expect("fixture strategy");
    strategy
}

/// `validate --plot -o STEM` draws the map where the user said; a folder
/// that does not exist is refused by name before any work; `-o` without
/// `--plot` is a usage error.
#[test]
fn validate_plot_goes_to_its_out_stem() {
    let dir = Scratch::new("validate-out");
    let strategy = open_2d_strategy(&dir);
    let stem = dir.path("figure");
    let args = [
        "validate",
        s(&strategy),
        "--episodes",
        "20",
        "--plot",
        "--plot-episodes",
        "3",
        "-o",
        s(&stem),
    ];
    let (rc, err) = code(&args);
    assert!(matches!(rc, Some(0 | 6)), "{err}");
    assert!(dir.path("figure.png").is_file() && dir.path("figure.svg").is_file());
    assert!(
        !dir.path("s-map.png").exists(),
        "drawn beside the strategy too"
    );
    let missing = dir.path("no/figure");
    let (rc, err) = code(&["validate", s(&strategy), "--plot", "-o", s(&missing)]);
    assert_eq!(rc, Some(1), "{err}");
    assert!(
        err.contains("-o") && err.contains("does not exist"),
        "{err}"
    );
    assert!(!dir.path("no").exists());
    let (rc, err) = code(&["validate", s(&strategy), "-o", s(&stem)]);
    assert_eq!(rc, Some(2), "{err}");
}

/// `run --plot -o STEM` draws the report where the user said (and nowhere
/// else); a folder that does not exist is refused by name before any process
/// starts; `-o` without `--plot` is a usage error.
#[test]
fn run_plot_goes_to_its_out_stem() {
    let dir = Scratch::new("run-out");
    let strategy = open_2d_strategy(&dir);
    let stem = dir.path("report");
    let (rc, err) = code(&[
        "run",
        s(&strategy),
        "--episodes",
        "2",
        "--plot",
        "-o",
        s(&stem),
    ]);
    assert!(matches!(rc, Some(0 | 6)), "{err}");
    assert!(dir.path("report.png").is_file() && dir.path("report.svg").is_file());
    let missing = dir.path("no/report");
    let (rc, err) = code(&["run", s(&strategy), "--plot", "-o", s(&missing)]);
    assert_eq!(rc, Some(1), "{err}");
    assert!(
        err.contains("-o") && err.contains("does not exist"),
        "{err}"
    );
    assert!(!dir.path("no").exists());
    let (rc, err) = code(&["run", s(&strategy), "-o", s(&stem)]);
    assert_eq!(rc, Some(2), "{err}");
}
