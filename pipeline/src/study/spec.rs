//! A study's SPEC file (TOML): which cases — every scenario × trigger
//! family × request — and how each is done (the settings of `etp
//! synthesize`, `etp strategy` and `etp validate`). Parsed once into a
//! [`Spec`] whose jobs are numbered in the file's order; every error names
//! the key.

use crate::error::{SpecError, StudyError};
use etp_runtime::scenario_arg::scenario_text_in;
use etp_shared::scenario::random::{AgentKind, random_scenario};
use etp_shared::scenario::{Scenario, ScenarioText};
use etp_shared::trigger::TriggerFamily;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The SPEC as written (unknown keys refused).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSpec {
    /// The study's name (default: the SPEC file's stem).
    name: Option<String>,
    scenarios: Vec<RawScenario>,
    /// Trigger families (default: each scenario's own).
    families: Option<Vec<String>>,
    /// Requests (default none: the study synthesizes only).
    #[serde(default)]
    requests: Vec<RawRequest>,
    samples: Option<u32>,
    seed: Option<u64>,
    replicates: Option<u32>,
    rounds: Option<u32>,
    episodes: Option<u64>,
    aggregation_check: Option<u64>,
    kf_episodes: Option<u64>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum RawScenario {
    /// A built-in name or a TOML path (relative to the SPEC's folder).
    Named(String),
    /// `{ random = N, seed = S }`: `etp scenario random --dim-agent N --seed S`.
    Random { random: usize, seed: u64 },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRequest {
    min_target: RawTarget,
    max_collision: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum RawTarget {
    Value(f64),
    /// `"kf-0.02"`: the full Kalman filter's simulated P_tar minus 0.02.
    Relative(String),
}

/// What a request asks for P_tar.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Target {
    /// P_tar ≥ this.
    Value(f64),
    /// P_tar ≥ (the full Kalman filter's simulated P_tar − this), rounded
    /// to 4 decimals: a request every scenario can meet, scaled to it.
    BelowKf(f64),
}

/// One request of every case: least energy with P_tar ≥ …, P_coll ≤ ….
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Request {
    pub min_target: Target,
    pub max_collision: Option<f64>,
}

impl Request {
    /// The request in words (the table's `request` column).
    pub fn describe(&self) -> String {
        let t = match self.min_target {
            Target::Value(p) => format!("P_tar ≥ {p}"),
            Target::BelowKf(d) => format!("P_tar ≥ KF − {d}"),
        };
        match self.max_collision {
            Some(c) => format!("{t}, P_coll ≤ {c}"),
            None => t,
        }
    }
}

/// How every case is done: `etp synthesize --samples --seed`, `etp
/// strategy --replicates --rounds --aggregation-check`, `etp validate
/// --episodes --seed`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Settings {
    pub samples: u32,
    pub seed: u64,
    pub replicates: u32,
    pub rounds: u32,
    /// Validation episodes (0: no validation).
    pub episodes: u64,
    pub aggregation_check: u64,
    /// Episodes of the full-Kalman-filter simulation of a `kf-…` request.
    pub kf_episodes: u64,
}

/// One scenario under one trigger family, with every request: the unit a
/// rank is handed (one synthesis, then its requests).
#[derive(Debug, Clone, Serialize)]
pub struct Job {
    /// `NN-<scenario>-<family>`: its folder under `DIR/cases/`.
    pub id: String,
    /// Where the scenario came from (name, path or `random n=N seed=S`).
    pub source: String,
    pub family: TriggerFamily,
    /// The scenario's content hash under the family.
    pub scenario_hash: String,
    #[serde(skip)]
    pub text: String,
    #[serde(skip)]
    pub scenario: Scenario,
}

/// A parsed SPEC.
#[derive(Debug, Clone, Serialize)]
pub struct Spec {
    pub name: String,
    pub settings: Settings,
    pub requests: Vec<Request>,
    pub jobs: Vec<Job>,
}

fn probability(key: &str, v: f64) -> Result<f64, SpecError> {
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(SpecError::value(
            key,
            format!("must be a probability in [0, 1], got {v}"),
        ))
    }
}

impl Settings {
    /// The settings a SPEC gives, the commands' defaults for the rest.
    fn of(raw: &RawSpec) -> Result<Self, SpecError> {
        let settings = Settings {
            samples: raw
                .samples
                .unwrap_or(etp_synthesis::abstraction::DEFAULT_SAMPLES),
            seed: raw.seed.unwrap_or(0),
            replicates: raw
                .replicates
                .unwrap_or(etp_synthesis::predict::rebuild::DEFAULT_REPLICATES),
            rounds: raw
                .rounds
                .unwrap_or(etp_synthesis::predict::request::DEFAULT_ROUNDS),
            episodes: raw.episodes.unwrap_or(3000),
            aggregation_check: raw
                .aggregation_check
                .unwrap_or(crate::predictions::AGGREGATION_CHECK_EPISODES),
            kf_episodes: raw.kf_episodes.unwrap_or(3000),
        };
        if settings.samples == 0 {
            return Err(SpecError::value(
                "samples",
                "at least 1 segment per state-action",
            ));
        }
        if !(2..=64).contains(&settings.replicates) {
            return Err(SpecError::value(
                "replicates",
                format!(
                    "2 to 64 rebuilds per prediction, got {}",
                    settings.replicates
                ),
            ));
        }
        if !(1..=20).contains(&settings.rounds) {
            return Err(SpecError::value(
                "rounds",
                format!("1 to 20, got {}", settings.rounds),
            ));
        }
        if settings.kf_episodes == 0 {
            return Err(SpecError::value("kf_episodes", "at least 1"));
        }
        Ok(settings)
    }
}

impl Request {
    /// Request `k` of the SPEC, checked.
    fn of(k: usize, r: &RawRequest) -> Result<Self, SpecError> {
        let key = format!("requests[{k}]");
        let min_target = match &r.min_target {
            RawTarget::Value(p) => Target::Value(probability(&format!("{key}.min_target"), *p)?),
            RawTarget::Relative(t) => {
                let d = t
                    .strip_prefix("kf-")
                    .and_then(|x| x.parse::<f64>().ok())
                    .ok_or_else(|| {
                        SpecError::value(
                            format!("{key}.min_target"),
                            format!(
                                "a probability or \"kf-D\" (the full Kalman filter's P_tar \
                                 minus D), got \"{t}\""
                            ),
                        )
                    })?;
                Target::BelowKf(probability(&format!("{key}.min_target"), d)?)
            }
        };
        let max_collision = r
            .max_collision
            .map(|c| probability(&format!("{key}.max_collision"), c))
            .transpose()?;
        Ok(Request {
            min_target,
            max_collision,
        })
    }
}

/// `scenarios[i]`'s error under its key.
fn at<E: std::error::Error + Send + Sync + 'static>(key: String) -> impl FnOnce(E) -> SpecError {
    move |e| SpecError::Scenario {
        key,
        source: Box::new(e),
    }
}

/// The jobs of scenario `i` of the SPEC (`s`), one per family (`None`:
/// its own), numbered on from `first`.
fn jobs_of(
    (i, s): (usize, &RawScenario),
    families: Option<&[TriggerFamily]>,
    base: &Path,
    first: usize,
) -> Result<Vec<Job>, SpecError> {
    let key = || format!("scenarios[{i}]");
    let (source, own_text) = match s {
        RawScenario::Named(name) => (
            name.clone(),
            scenario_text_in(base, name).map_err(at(key()))?,
        ),
        RawScenario::Random { random, seed } => {
            let kind = AgentKind::from_dim(*random).map_err(at(key()))?;
            let (text, _) = random_scenario(kind, *seed).map_err(at(key()))?;
            (format!("random n={random} seed={seed}"), text)
        }
    };
    let own = ScenarioText::parse(own_text).map_err(at(key()))?;
    // Each family as `etp synthesize --trigger FAMILY` writes it into the
    // text; without `families`, the scenario's own text.
    let texts: Vec<(TriggerFamily, String)> = match families {
        None => vec![(own.scenario.trigger, own.text.clone())],
        Some(fs) => fs
            .iter()
            .map(|&f| {
                own.clone()
                    .with_trigger(f)
                    .map(|t| (f, t.text))
                    .map_err(at(format!("scenarios[{i}] under {f}")))
            })
            .collect::<Result<_, _>>()?,
    };
    let mut jobs = Vec::new();
    for (family, text) in texts {
        let scenario = Scenario::from_toml(&text).map_err(at(key()))?;
        jobs.push(Job {
            id: format!(
                "{:02}-{}-{}",
                first + jobs.len(),
                scenario.name,
                family.name()
            ),
            source: source.clone(),
            family,
            scenario_hash: scenario.content_hash.clone(),
            text,
            scenario,
        });
    }
    Ok(jobs)
}

impl Spec {
    /// Read and check the SPEC file at `path` (its name defaults to the
    /// file's stem, its scenario paths are relative to its folder).
    pub fn load(path: &Path) -> Result<Self, StudyError> {
        let text = std::fs::read_to_string(path).map_err(|source| StudyError::ReadSpec {
            path: path.to_path_buf(),
            source,
        })?;
        let stem = path
            .file_stem()
            .map_or_else(|| "study".into(), |s| s.to_string_lossy().into_owned());
        let base = path.parent().unwrap_or(Path::new("."));
        Self::parse(&text, &stem, base).map_err(|source| StudyError::SpecFile {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Parse SPEC `text` (TOML); scenario paths relative to `base`.
    pub fn parse(text: &str, default_name: &str, base: &Path) -> Result<Self, SpecError> {
        Self::from_raw(toml::from_str(text)?, default_name, base)
    }

    /// Parse a SPEC written as JSON (the same keys and values as the TOML
    /// file; the Python package's dict); scenario paths relative to `base`.
    pub fn from_json(text: &str, default_name: &str, base: &Path) -> Result<Self, SpecError> {
        Self::from_raw(serde_json::from_str(text)?, default_name, base)
    }

    fn from_raw(raw: RawSpec, default_name: &str, base: &Path) -> Result<Self, SpecError> {
        let settings = Settings::of(&raw)?;
        let requests = raw
            .requests
            .iter()
            .enumerate()
            .map(|(k, r)| Request::of(k, r))
            .collect::<Result<_, _>>()?;
        let families: Option<Vec<TriggerFamily>> = raw
            .families
            .as_ref()
            .map(|fs| {
                fs.iter()
                    .map(|f| {
                        TriggerFamily::parse(f)
                            .map_err(|e| SpecError::value("families", e.to_string()))
                    })
                    .collect::<Result<_, _>>()
            })
            .transpose()?;
        if raw.scenarios.is_empty() {
            return Err(SpecError::value("scenarios", "give at least one"));
        }
        let mut jobs = Vec::new();
        for s in raw.scenarios.iter().enumerate() {
            let more = jobs_of(s, families.as_deref(), base, jobs.len())?;
            jobs.extend(more);
        }
        Ok(Self {
            name: raw.name.unwrap_or_else(|| default_name.to_string()),
            settings,
            requests,
            jobs,
        })
    }

    /// The SPEC as stored beside the results (`DIR/spec.json`): what a
    /// resumed study must equal.
    pub fn canonical(&self) -> Result<String, StudyError> {
        let text =
            serde_json::to_string_pretty(self).map_err(StudyError::serde("the SPEC as JSON"))?;
        Ok(text + "\n")
    }

    /// The rows of a job: one per request, or one (the synthesis) when the
    /// study asks none.
    pub fn rows_per_job(&self) -> usize {
        self.requests.len().max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_scenario_under_every_family_with_its_requests() {
        let s = Spec::parse(
            r#"
            scenarios = ["winding-2d", { random = 4, seed = 9105 }]
            families = ["box", "stochastic"]
            requests = [{ min_target = 0.9 }, { min_target = "kf-0.02", max_collision = 0.05 }]
            samples = 100
            "#,
            "t",
            Path::new("."),
        )
        .expect("parses");
        let ids: Vec<&str> = s.jobs.iter().map(|j| j.id.as_str()).collect();
        assert_eq!(
            ids,
            [
                "00-winding-2d-box",
                "01-winding-2d-stochastic",
                "02-random-n4-s9105-box",
                "03-random-n4-s9105-stochastic"
            ]
        );
        assert_eq!(s.requests[1].min_target, Target::BelowKf(0.02));
        assert_eq!(s.requests[1].describe(), "P_tar ≥ KF − 0.02, P_coll ≤ 0.05");
        assert_eq!(s.settings.samples, 100);
        assert_eq!(s.rows_per_job(), 2);
        // The family said aloud keeps the scenario's own text (and hash).
        assert_eq!(
            s.jobs[0].scenario_hash,
            Scenario::builtin("winding-2d")
                .expect("built-in")
                .content_hash
        );
        assert_ne!(s.jobs[0].scenario_hash, s.jobs[1].scenario_hash);
    }

    #[test]
    fn the_repository_specs_parse() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies");
        let mut n = 0;
        for e in std::fs::read_dir(&dir).expect("studies/").flatten() {
            let spec = Spec::load(&e.path()).unwrap_or_else(|err| panic!("{err:#}"));
            assert!(!spec.jobs.is_empty());
            n += 1;
        }
        assert!(n >= 3, "{n} SPECs in studies/");
        let families = Spec::load(&dir.join("families.toml")).expect("families.toml");
        assert_eq!(families.jobs.len(), 15);
        // The study SPECs of benchmarks/ (docs/performance.md) parse too.
        let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join("../benchmarks");
        let mut jobs = Vec::new();
        for e in std::fs::read_dir(&bench).expect("benchmarks/").flatten() {
            if e.path().extension().is_some_and(|x| x == "toml") {
                let spec = Spec::load(&e.path()).unwrap_or_else(|err| panic!("{err:#}"));
                jobs.push((spec.name.clone(), spec.jobs.len()));
            }
        }
        jobs.sort();
        assert_eq!(
            jobs,
            [
                ("fresh-scenarios".to_string(), 15),
                ("mpi-study".to_string(), 4),
                ("prediction-accuracy".to_string(), 20),
            ]
        );
    }

    #[test]
    fn errors_name_the_key() {
        let err = |t: &str| {
            format!(
                "{:#}",
                Spec::parse(t, "t", Path::new(".")).expect_err("refused")
            )
        };
        assert!(
            err(r#"scenarios = ["winding-2d"]
            requests = [{ min_target = 1.5 }]"#)
            .contains("requests[0].min_target")
        );
        assert!(
            err(r#"scenarios = ["winding-2d"]
            requests = [{ min_target = "kf+0.1" }]"#)
            .contains("requests[0].min_target")
        );
        assert!(
            err(r#"scenarios = ["winding-2d"]
            families = ["boxy"]"#)
            .contains("families")
        );
        assert!(err(r#"scenarios = ["no-such-scenario"]"#).contains("scenarios[0]"));
        assert!(
            err(r#"scenarios = ["winding-2d"]
            sample = 3"#)
            .contains("sample")
        );
        assert!(err(r#"scenarios = [{ random = 5, seed = 1 }]"#).contains("scenarios[0]"));
        assert!(matches!(
            Spec::parse(r#"scenarios = ["no-such-scenario"]"#, "t", Path::new(".")),
            Err(SpecError::Scenario { .. })
        ));
        assert!(matches!(
            Spec::parse("scenarios = [\"winding-2d\"]\nrounds = 0", "t", Path::new(".")),
            Err(SpecError::Value { key, .. }) if key == "rounds"
        ));
    }

    #[test]
    fn a_spec_as_json_is_the_spec_as_toml() {
        let toml = Spec::parse(
            r#"
            scenarios = ["winding-2d", { random = 4, seed = 9105 }]
            families = ["box"]
            requests = [{ min_target = 0.9 }, { min_target = "kf-0.02", max_collision = 0.05 }]
            samples = 100
            "#,
            "t",
            Path::new("."),
        )
        .expect("TOML parses");
        let json = Spec::from_json(
            r#"{"scenarios": ["winding-2d", {"random": 4, "seed": 9105}], "families": ["box"],
                "requests": [{"min_target": 0.9}, {"min_target": "kf-0.02", "max_collision": 0.05}],
                "samples": 100}"#,
            "t",
            Path::new("."),
        )
        .expect("JSON parses");
        assert_eq!(
            toml.canonical().expect("canonical"),
            json.canonical().expect("canonical")
        );
        let err = Spec::from_json(
            r#"{"scenarios": ["winding-2d"], "sampels": 3}"#,
            "t",
            Path::new("."),
        )
        .expect_err("refused");
        assert!(
            matches!(err, SpecError::Json(_)) && err.to_string().contains("sampels"),
            "{err}"
        );
    }
}
