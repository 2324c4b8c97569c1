//! A synthesis directory (`etp synthesize -o DIR`) loaded for selection:
//! its MDP, front, scenario text and the scenario under the synthesis's
//! channel, as `etp strategy` and `etp compare` select and predict on it.

use crate::error::{Context, Error, Result};
use crate::output::{read_front, read_mdp};
use etp_shared::radio::RadioOverride;
use etp_shared::scenario::{Scenario, ScenarioText, builtin_text};
use etp_shared::strategy::Strategy;
use etp_shared::trigger::TriggerFamily;
use etp_synthesis::abstraction;
use etp_synthesis::certify::robust::Certified;
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::ParetoFront;
use etp_synthesis::pareto::policy::{Objectives, RandomisedPolicy};
use etp_synthesis::pareto::to_strategy;
use etp_synthesis::predict::rebuild::{self, OnPolicy};
use etp_synthesis::predict::request::{Goal, LoopSettings, Outcome, meet_request};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};

/// A synthesis directory, loaded for selection.
pub struct Synthesis {
    pub dir: PathBuf,
    pub mdp: Mdp,
    pub scenario_text: Option<String>,
    pub front: ParetoFront,
    /// The scenario under the synthesis's channel (what the rebuilds simulate).
    pub scenario: Scenario,
    pub output: PathBuf,
    /// Where the rebuilds run (threads and ranks); rank 0 writes.
    pub exec: Executor,
}

impl Synthesis {
    pub fn load(dir: &Path, output: Option<&Path>, exec: &Executor) -> Result<Self> {
        let (mdp, scenario_text) = read_mdp(dir)?;
        if mdp.policy_only() {
            return Err(Error::synthesis(format!(
                "{}: this MDP offers at its states only the thresholds of the strategy its pools \
                 were drawn on (`etp synthesize --pool-policy` without --all-actions), so its front \
                 is not the scenario's; predict that strategy with `etp strategy evaluate \
                 STRATEGY.json DIR` on the synthesis it came from",
                dir.display()
            )));
        }
        let front = read_front(dir, &mdp)?;
        Self::from_parts(dir, mdp, scenario_text, front, output, exec)
    }

    /// A synthesis from its parts (read from DIR, or just built): its
    /// scenario from the text (else the built-in of the MDP's name), checked
    /// against the MDP, under the channel the front records.
    pub fn from_parts(
        dir: &Path,
        mdp: Mdp,
        scenario_text: Option<String>,
        front: ParetoFront,
        output: Option<&Path>,
        exec: &Executor,
    ) -> Result<Self> {
        let mut scenario = match &scenario_text {
            Some(t) => Scenario::from_toml(t).in_scenario("parsing DIR/scenario.toml")?,
            None => Scenario::builtin(&mdp.scenario_name).in_scenario(format!(
                "{} has no scenario.toml and `{}` is not a built-in scenario",
                dir.display(),
                mdp.scenario_name
            ))?,
        };
        if scenario.content_hash != mdp.scenario_hash {
            return Err(Error::synthesis(format!(
                "the scenario of {} is not its MDP's (hash {:.12}… vs {:.12}…)",
                dir.display(),
                scenario.content_hash,
                mdp.scenario_hash
            )));
        }
        // The channel the synthesis ran under: steps 1–2 of the one override
        // rule (docs/MODEL.md §8.6), as `Strategy::scenario` applies them.
        scenario.radio = scenario
            .radio
            .for_use(front.radio.as_ref(), &RadioOverride::default())
            .in_synthesis(format!("the channel recorded in {}", dir.display()))?;
        let output = output
            .map(Path::to_path_buf)
            .unwrap_or_else(|| dir.join("strategy.json"));
        Ok(Self {
            dir: dir.to_path_buf(),
            mdp,
            scenario_text,
            front,
            scenario,
            output,
            exec: exec.clone(),
        })
    }

    pub fn cost(&self) -> CostModel {
        self.front.cost_model
    }

    /// A policy on `mdp` (this synthesis's or a refinement of it) as a
    /// strategy file: its exact value there under diagnostics, the
    /// scenario text and channel.
    pub fn strategy_of(
        &self,
        mdp: &Mdp,
        omega: &RandomisedPolicy,
        value: Objectives,
        label: &str,
    ) -> Strategy {
        let mut s = to_strategy(mdp, omega, label.to_string(), value);
        s.policy.scenario_toml.clone_from(&self.scenario_text);
        s.policy.radio.clone_from(&self.front.radio);
        s
    }

    /// `strategy`'s prediction from `replicates` rebuilds of this synthesis
    /// (docs/MODEL.md §7.4) and the first rebuild's certified bounds at
    /// `level`; the rebuilds' segments counted on `pb`.
    pub fn predict(
        &self,
        strategy: &Strategy,
        replicates: u32,
        level: f64,
        pb: &ProgressBar,
    ) -> Result<(OnPolicy, Certified)> {
        let params = abstraction::params_of(&self.mdp);
        let on_policy = rebuild::predict(
            &self.scenario,
            &params,
            &strategy.policy,
            replicates,
            self.cost(),
            Vec::new(),
            &self.exec.work(|k| pb.inc(k)),
        )?;
        let certified = on_policy.certify_first(level, self.cost())?;
        Ok((on_policy, certified))
    }

    /// The request loop (`meet_request`) for `goal` on `mdp` (this
    /// synthesis's or a refinement of it), rebuilding on this synthesis's
    /// scenario and parameters; `pb` grows by each round's rebuilds and
    /// counts their segments.
    pub fn meet(
        &self,
        mdp: &Mdp,
        goal: Goal,
        settings: LoopSettings,
        level: f64,
        make: &dyn Fn(&RandomisedPolicy, Objectives) -> Strategy,
        pb: &ProgressBar,
    ) -> Result<Outcome> {
        let params = abstraction::params_of(&self.mdp);
        let units = rebuild::progress_units(&self.scenario, &params);
        Ok(meet_request(
            mdp,
            self.cost(),
            &self.scenario,
            &params,
            goal,
            settings,
            level,
            make,
            &|n| pb.inc_length(u64::from(n) * units),
            &self.exec.work(|k| pb.inc(k)),
        )?)
    }
}

/// What tells syntheses of one scenario apart in a comparison (`etp fronts`,
/// `etp compare`): the trigger family, the channel, and the scenario
/// without its family.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    pub trigger: TriggerFamily,
    /// The channel the synthesis sampled under, in `Radio::describe`'s words.
    pub radio: String,
    /// The content hash of its scenario with the family `box`: syntheses of
    /// "one scenario" under different families share it (the family changes
    /// the content hash, docs/MODEL.md §9).
    pub scenario_key: String,
}

/// The identity of the synthesis in `dir` from its front and scenario text
/// (`None`: the built-in scenario of the front's name).
pub fn identity(dir: &Path, front: &ParetoFront, text: Option<&str>) -> Result<Identity> {
    let own = match text {
        Some(t) => ScenarioText::parse(t.to_string())
            .in_scenario(format!("the scenario of {}", dir.display()))?,
        None => {
            let name = &front.scenario_name;
            let t = builtin_text(name).ok_or_else(|| {
                Error::scenario(format!(
                    "{} has no scenario.toml and `{name}` is not a built-in scenario",
                    dir.display()
                ))
            })?;
            ScenarioText::parse(t.to_string())?
        }
    };
    let trigger = own.scenario.trigger;
    let names: Vec<String> = own
        .scenario
        .sensors
        .iter()
        .map(|s| s.name.clone())
        .collect();
    let radio = own
        .scenario
        .radio
        .for_use(front.radio.as_ref(), &RadioOverride::default())
        .in_synthesis(format!("the radio of {}", dir.display()))?
        .describe(&names);
    let scenario_key = own
        .with_trigger(TriggerFamily::Box)
        .in_scenario(format!(
            "the scenario of {} without its family",
            dir.display()
        ))?
        .scenario
        .content_hash;
    Ok(Identity {
        trigger,
        radio,
        scenario_key,
    })
}

/// Refuse syntheses of different scenarios (by [`Identity::scenario_key`]).
pub fn check_one_scenario(items: &[(&Path, &str, &Identity)]) -> Result<()> {
    if let Some((d0, n0, first)) = items.first() {
        for (dir, name, id) in items {
            if id.scenario_key != first.scenario_key {
                return Err(Error::request(format!(
                    "{} is a synthesis of scenario `{name}`, {} of `{n0}`: compare syntheses of one \
                     scenario (the same scenario under different radios or trigger families)",
                    dir.display(),
                    d0.display(),
                )));
            }
        }
    }
    Ok(())
}

/// Each synthesis's legend: the family where families differ, the channel
/// where channels differ (both when both do, the channel when neither); the
/// directory added where two would read the same.
pub fn labels(items: &[(&Path, &Identity)]) -> Vec<String> {
    let Some((_, first)) = items.first() else {
        return Vec::new();
    };
    let families = items.iter().any(|(_, i)| i.trigger != first.trigger);
    let radios = items.iter().any(|(_, i)| i.radio != first.radio);
    let base: Vec<String> = items
        .iter()
        .map(|(_, i)| match (families, radios) {
            (true, true) => format!("{} · {}", i.trigger, i.radio),
            (true, false) => i.trigger.name().to_string(),
            _ => i.radio.clone(),
        })
        .collect();
    base.iter()
        .zip(items)
        .map(|(l, (dir, _))| {
            if base.iter().filter(|b| *b == l).count() > 1 {
                format!("{l} ({})", dir.display())
            } else {
                l.clone()
            }
        })
        .collect()
}
