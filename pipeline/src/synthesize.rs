//! A whole synthesis — what `etp synthesize` does and the Python package's
//! `etpareto.synthesize` calls: the MDP ([`crate::mdp_build`]), the Method 1
//! baseline beside it, the Pareto front and its files ([`crate::front`]),
//! what the replaced MDP's derived files become, and the aggregation check
//! ([`crate::aggregation`]). The caller prints; [`Synthesized::to_json`] is
//! `etp synthesize --json`'s object.

use crate::aggregation;
use crate::error::{Context, Error, Result};
use crate::front::{FrontReport, write_front};
use crate::mdp_build::{BuiltMdp, MdpRequest, build_mdp};
use crate::output::{refuse_existing, write_new};
use etp_files::write::{WriteError, output_folder};
use etp_runtime::scenario_arg::scenario_text;
use etp_shared::scenario::{Scenario, ScenarioText};
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::abstraction::aggregation::AggregationReport;
use etp_synthesis::abstraction::{self, default_kf_params};
use etp_synthesis::mdp::Method;
use std::path::{Path, PathBuf};

/// `etp synthesize`'s default `--aggregation-episodes`.
pub const DEFAULT_AGGREGATION_EPISODES: u64 = 50_000;
/// `etp synthesize`'s default `--aggregation-alpha`.
pub const DEFAULT_AGGREGATION_ALPHA: f64 = 0.05;

/// The scenario of `arg` (a built-in name or a path) under the trigger
/// family `trigger`, and its text under that family — what a synthesis
/// writes as `DIR/scenario.toml`, so that the content hash is the family's.
/// No family: the scenario as every process of a run loads it, and its own
/// text.
pub fn scenario_under(arg: &str, trigger: Option<TriggerFamily>) -> Result<(Scenario, String)> {
    // Loaded first: its error names a missing or unknown scenario as every
    // command does.
    let own = etp_runtime::load_scenario(arg)?;
    let text = scenario_text(arg)?;
    let Some(family) = trigger else {
        return Ok((own, text));
    };
    let text = ScenarioText::parse(text)
        .in_scenario("scenario")?
        .with_trigger(family)
        .in_scenario("--trigger")?
        .text;
    let scenario = Scenario::from_toml(&text).in_scenario(format!("scenario {arg}"))?;
    Ok((scenario, text))
}

/// What to synthesize, typed (the command line and Python both make one).
#[derive(Debug, Clone)]
pub struct SynthesisRequest {
    /// The MDP step: the scenario under its channel and trigger family, the
    /// abstraction parameters, the output folder, `force`, `quiet`, …
    pub mdp: MdpRequest,
    /// The scenario's text under the trigger family asked for: written as
    /// `DIR/scenario.toml` (the strategies of DIR carry it).
    pub text: String,
    /// The Method 1 (KF convergence) baseline front beside Method 2's.
    pub kf_baseline: bool,
    /// Episodes of the aggregation check (0: none).
    pub aggregation_episodes: u64,
    /// The check's false discovery rate, in (0, 1).
    pub aggregation_alpha: f64,
}

impl SynthesisRequest {
    /// `etp synthesize`'s defaults on `mdp`'s scenario, whose text is `text`.
    pub fn new(mdp: MdpRequest, text: String) -> Self {
        Self {
            mdp,
            text,
            kf_baseline: true,
            aggregation_episodes: DEFAULT_AGGREGATION_EPISODES,
            aggregation_alpha: DEFAULT_AGGREGATION_ALPHA,
        }
    }

    /// The output folder (default `out/<scenario name>`).
    pub fn dir(&self) -> PathBuf {
        self.mdp
            .out
            .clone()
            .unwrap_or_else(|| Path::new("out").join(&self.mdp.scenario.name))
    }
}

/// What a synthesis built and wrote.
pub struct Synthesized {
    pub built: BuiltMdp,
    pub front: FrontReport,
    /// The aggregation check and its seconds (`None`: not run, or the MDP
    /// has no regions).
    pub aggregation: Option<(AggregationReport, f64)>,
    /// After `force` replaced a synthesis: the folder the replaced MDP's
    /// derived files were moved to, and their names.
    pub stale: Option<(PathBuf, Vec<String>)>,
}

impl Synthesized {
    /// `etp synthesize --json`'s object.
    pub fn to_json(&self) -> serde_json::Value {
        let front = &self.front;
        serde_json::json!({
            "mdp": self.built.report,
            "aggregation": self.aggregation.as_ref().map(|r| &r.0),
            "front": {
                "vertices": front.front.vertices.len(),
                "facets": front.front.facets.len(),
                "optimisations": front.front.optimisations,
                "seconds": front.seconds,
                "energy_scale": front.front.energy_scale,
                "files": front.files,
            }
        })
    }
}

/// Synthesize: refuses before any work (touching nothing) when `front.json`
/// exists and `force` is not set, or the request is malformed.
pub fn synthesize(r: SynthesisRequest) -> Result<Synthesized> {
    let dir = r.dir();
    let front_path = dir.join("front.json");
    output_folder(&dir)?;
    refuse_existing(&r.mdp.exec, &front_path, r.mdp.force)?;
    if !(r.aggregation_alpha > 0.0 && r.aggregation_alpha < 1.0) {
        return Err(Error::request(format!(
            "--aggregation-alpha must lie in (0, 1) (got {})",
            r.aggregation_alpha
        )));
    }
    // The channel is recorded when the options changed the scenario text's own.
    let own_radio = Scenario::from_toml(&r.text).in_scenario("scenario")?.radio;
    let params = r.mdp.params;
    let progress = r.mdp.progress.clone();
    let force = r.mdp.force;
    let exec = r.mdp.exec.clone();
    let built = build_mdp(r.mdp)?;
    // Method 1 as a baseline beside Method 2 (cheap: one state per decision point).
    let method1 = if params.method == Method::Discretized && r.kf_baseline {
        let mut p = params;
        p.method = Method::KfConvergence;
        p.kf = Some(default_kf_params(&built.scenario));
        // The baseline is only drawn; it needs no cross-fitting.
        p.holdout_samples = 0;
        let m1 = abstraction::build(&built.scenario, &p, &exec.work(|_| {}))
            .computing("building the Method 1 baseline")?;
        write_new(
            &exec,
            &dir.join("mdp-kf-convergence.bin"),
            &m1.encode(),
            true,
        )?;
        Some(m1)
    } else {
        None
    };
    let radio = (built.scenario.radio != own_radio).then_some(&built.scenario.radio);
    let replaced = front_path.exists();
    let front = write_front(
        &built.dir,
        &built.mdp,
        method1.as_ref(),
        &r.text,
        radio,
        force,
        &exec,
    )?;
    // Only now that the new front is written: what was derived from the
    // old MDP would sit beside it as if derived from the new one.
    let stale = if replaced && exec.is_root() {
        set_aside_stale(&built.dir)?
    } else {
        None
    };
    let aggregation = aggregation::measure(
        &built.scenario,
        &built.mdp,
        r.aggregation_episodes,
        r.aggregation_alpha,
        &progress,
        &exec,
    )?;
    Ok(Synthesized {
        built,
        front,
        aggregation,
        stale,
    })
}

/// What `etp strategy`, `etp validate --plot` and `etp export` write
/// into a synthesis folder by default: derived from its MDP.
const DERIVED: [&str; 4] = [
    "strategy.json",
    "strategy-map.png",
    "strategy-map.svg",
    "prism",
];

/// After `force` replaced a synthesis: move what was derived from the old
/// MDP into `DIR/stale-<unix seconds>/` (moved, not deleted). The folder and
/// the names moved, if any.
fn set_aside_stale(dir: &Path) -> Result<Option<(PathBuf, Vec<String>)>> {
    let found: Vec<&str> = DERIVED
        .into_iter()
        .filter(|n| dir.join(n).symlink_metadata().is_ok())
        .collect();
    if found.is_empty() {
        return Ok(None);
    }
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let mut stale = dir.join(format!("stale-{secs}"));
    let mut k = 1;
    while stale.symlink_metadata().is_ok() {
        stale = dir.join(format!("stale-{secs}-{k}"));
        k += 1;
    }
    std::fs::create_dir(&stale).map_err(|source| WriteError::Io {
        what: format!("creating {}", stale.display()),
        source,
    })?;
    for n in &found {
        std::fs::rename(dir.join(n), stale.join(n)).map_err(|source| WriteError::Io {
            what: format!("moving {} to {}", dir.join(n).display(), stale.display()),
            source,
        })?;
    }
    Ok(Some((stale, found.iter().map(|n| n.to_string()).collect())))
}
