//! A `SCENARIO` argument, resolved once for every program: a built-in name
//! (`winding-2d`, …) or the path of a TOML file. `etp`, the pipeline, the
//! launcher and every process of a run (the supervisor passes them the same
//! argument) read it here, so that all of them accept the same names and
//! refuse an unknown one with the same message.

use etp_shared::scenario::{BUILTIN_NAMES, Scenario, ScenarioError, builtin_text};
use std::path::{Path, PathBuf};

/// Why a scenario argument could not be resolved (the cause is the
/// `source`: the binaries' `{:#}` of an `anyhow` error shows it after a
/// colon).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioArgError {
    #[error("built-in scenario `{name}`")]
    Builtin {
        name: String,
        #[source]
        source: ScenarioError,
    },
    #[error("`{arg}` is neither a built-in scenario ({}) nor an existing file", BUILTIN_NAMES.join(", "))]
    NotFound { arg: String },
    #[error("reading scenario file {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("scenario file {}", path.display())]
    Invalid {
        path: PathBuf,
        #[source]
        source: ScenarioError,
    },
}

/// What a `SCENARIO` argument names, decided once: a built-in scenario or
/// a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ScenarioSource {
    /// One of [`BUILTIN_NAMES`].
    Builtin(String),
    /// A TOML file (not yet checked to exist).
    File(PathBuf),
}

impl ScenarioSource {
    /// A built-in name is a built-in; anything else is a path.
    pub fn parse(arg: &str) -> Self {
        if builtin_text(arg).is_some() {
            Self::Builtin(arg.to_string())
        } else {
            Self::File(PathBuf::from(arg))
        }
    }

    /// As written in a file in folder `base` (a run file, a study): a
    /// relative path is relative to `base`; a built-in stays a name.
    pub fn in_folder(self, base: &Path) -> Self {
        match self {
            Self::File(p) => Self::File(base.join(p)),
            b => b,
        }
    }

    /// With an absolute path (a file's path made absolute against the
    /// current folder; a built-in stays a name).
    pub fn absolute(self) -> std::io::Result<Self> {
        match self {
            Self::File(p) => Ok(Self::File(std::path::absolute(p)?)),
            b => Ok(b),
        }
    }

    /// The argument that names it again (for a run file, a process's
    /// command line).
    pub fn to_arg(&self) -> String {
        match self {
            Self::Builtin(name) => name.clone(),
            Self::File(p) => p.display().to_string(),
        }
    }

    /// The TOML text: a built-in's embedded text, else the file's.
    pub fn text(&self) -> Result<String, ScenarioArgError> {
        match self {
            Self::Builtin(name) => builtin_text(name)
                .map(str::to_string)
                .ok_or_else(|| ScenarioArgError::NotFound { arg: name.clone() }),
            Self::File(path) => {
                if !path.exists() {
                    return Err(ScenarioArgError::NotFound {
                        arg: path.display().to_string(),
                    });
                }
                std::fs::read_to_string(path).map_err(|source| ScenarioArgError::Read {
                    path: path.clone(),
                    source,
                })
            }
        }
    }
}

/// The TOML text of a `SCENARIO` argument, not parsed: a built-in's
/// embedded text, else the file's (written into outputs as given, and
/// edited as text by the trigger and radio options before parsing).
pub fn scenario_text(arg: &str) -> Result<String, ScenarioArgError> {
    scenario_text_in(Path::new(""), arg)
}

/// [`scenario_text`] of an argument written in a file (a study): a path is
/// relative to `base`, the file's folder; a built-in name stays a name.
pub fn scenario_text_in(base: &Path, arg: &str) -> Result<String, ScenarioArgError> {
    ScenarioSource::parse(arg).in_folder(base).text()
}

/// The scenario of a `SCENARIO` argument: a built-in name or a TOML path.
pub fn load_scenario(arg: &str) -> Result<Scenario, ScenarioArgError> {
    let source = ScenarioSource::parse(arg);
    let text = source.text()?;
    Scenario::from_toml(&text).map_err(|e| match source {
        ScenarioSource::Builtin(name) => ScenarioArgError::Builtin { name, source: e },
        ScenarioSource::File(path) => ScenarioArgError::Invalid { path, source: e },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names of `scenarios/*.toml`, the reference scenarios' files.
    fn scenario_files() -> Vec<String> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .expect("scenarios/ is readable")
            .map(|e| e.expect("a folder entry").path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .collect();
        names.sort();
        names
    }

    #[test]
    fn every_scenario_file_is_a_built_in_that_resolves() {
        let files = scenario_files();
        assert!(files.len() >= 5, "{files:?}");
        for name in &files {
            let text = scenario_text(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            let on_disk = std::fs::read_to_string(
                Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../scenarios/{name}.toml")),
            )
            .expect("readable");
            assert_eq!(text, on_disk, "{name}: the embedded text is the file's");
            load_scenario(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        let mut builtins: Vec<String> = BUILTIN_NAMES.iter().map(|s| s.to_string()).collect();
        builtins.sort();
        assert_eq!(builtins, files, "BUILTIN_NAMES against scenarios/*.toml");
    }

    #[test]
    fn a_source_is_a_built_in_or_a_path_relative_to_its_file() {
        let b = ScenarioSource::parse("open-2d");
        assert_eq!(b, ScenarioSource::Builtin("open-2d".into()));
        assert_eq!(b.clone().in_folder(Path::new("/runs")), b);
        assert_eq!(b.clone().absolute().expect("absolute"), b);
        let f = ScenarioSource::parse("my.toml").in_folder(Path::new("/runs"));
        assert_eq!(f, ScenarioSource::File(PathBuf::from("/runs/my.toml")));
        assert_eq!(f.to_arg(), "/runs/my.toml");
        // An absolute path stays itself in any folder.
        let a = ScenarioSource::parse("/abs/s.toml").in_folder(Path::new("/runs"));
        assert_eq!(a.to_arg(), "/abs/s.toml");
        assert!(
            ScenarioSource::parse("rel.toml")
                .absolute()
                .expect("absolute")
                .to_arg()
                .starts_with('/')
        );
    }

    #[test]
    fn an_unknown_name_is_refused_with_every_built_in() {
        for e in [
            scenario_text("windy-9d").expect_err("unknown"),
            load_scenario("windy-9d").expect_err("unknown"),
        ] {
            assert!(matches!(&e, ScenarioArgError::NotFound { arg } if arg == "windy-9d"));
            let message = e.to_string();
            assert!(message.starts_with("`windy-9d` is neither"), "{message}");
            for name in scenario_files() {
                assert!(message.contains(&name), "{name} missing from: {message}");
            }
        }
    }

    #[test]
    fn a_missing_file_is_named() {
        let e = load_scenario("/nonexistent/x.toml").expect_err("missing");
        assert!(
            e.to_string()
                .starts_with("`/nonexistent/x.toml` is neither a built-in scenario (winding-2d"),
            "{e}"
        );
    }

    #[test]
    fn a_path_in_a_file_is_relative_to_its_folder() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
        assert_eq!(
            scenario_text_in(&dir, "open-2d.toml").expect("a file"),
            scenario_text("open-2d").expect("a built-in")
        );
        // A built-in name is not looked up in the folder.
        assert!(scenario_text_in(Path::new("/nonexistent"), "open-2d").is_ok());
        let e = scenario_text_in(Path::new("/nonexistent"), "x.toml").expect_err("missing");
        assert!(matches!(&e, ScenarioArgError::NotFound { arg } if arg == "/nonexistent/x.toml"));
    }
}
