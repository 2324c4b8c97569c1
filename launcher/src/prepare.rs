//! Everything decided before a process is spawned.

use super::{RunRequest, RunTarget};
use crate::error::{Context, Error, IoContext, Result};
use etp_runtime::scenario_arg::scenario_text;
use etp_runtime::wire::RunId;
use etp_shared::radio::schedule::ChannelSchedule;
use etp_shared::radio::{Radio, RadioOverride};
use etp_shared::scenario::{Scenario, ScenarioText};
use etp_shared::strategy::{Prediction, Strategy};
use etp_synthesis::validate::simulate_strategy;
use std::path::PathBuf;

/// A run ready to be spawned.
#[derive(Debug)]
pub struct Plan {
    pub run_id: RunId,
    pub seed: u64,
    pub episodes: u64,
    pub scenario: Scenario,
    /// The run's private folder (scenario and strategy files for the processes).
    pub dir: PathBuf,
    pub scenario_path: PathBuf,
    pub strategy_path: PathBuf,
    /// Predicted energy per episode of each sensor.
    pub sensor_energy_per_episode: Vec<f64>,
    /// Where [`Plan::sensor_energy_per_episode`] comes from (reports, recording).
    pub prediction_from: String,
    pub predict_episodes: u64,
    /// The resolved run as a run file (`etp.config` of the recording).
    pub config_toml: String,
    /// The strategy's constant threshold, if it is constant (`etp_recording_tools::vocab`).
    pub delta: Option<f64>,
    /// The channel a strategy file was synthesized for (`None` for a
    /// constant threshold made here); the run's is `scenario.radio`.
    pub radio_synthesized: Option<Radio>,
    /// Changes of sensors' links during the run (`--channel-schedule`), and
    /// the run folder's copy the sensors read; empty and `None` without.
    pub channel_schedule: ChannelSchedule,
    pub channel_schedule_path: Option<PathBuf>,
    /// The channel monitor's false-alarm rate and what its flags do.
    pub drift: crate::request::DriftWatch,
}

/// The run's channel schedule (`--channel-schedule FILE`), checked against
/// the run's channel and sensors, and its copy in the run folder `dir`
/// (every key written out) for the sensor processes.
fn channel_schedule(
    a: &RunRequest,
    scenario: &Scenario,
    dir: &std::path::Path,
) -> Result<(ChannelSchedule, Option<PathBuf>)> {
    let Some(path) = &a.channel_schedule else {
        return Ok((ChannelSchedule::default(), None));
    };
    let shown = format!("--channel-schedule {}", path.display());
    let text =
        std::fs::read_to_string(path).map_err(|e| Error::request(format!("{shown}: {e}")))?;
    let names: Vec<String> = scenario.sensors.iter().map(|s| s.name.clone()).collect();
    let schedule = ChannelSchedule::parse(&text, &shown, &scenario.radio, &names)
        .map_err(|e| Error::request(e.to_string()))?;
    let copy = dir.join("channel-schedule.toml");
    std::fs::write(&copy, schedule.to_toml(&names))
        .doing(|| format!("writing {}", copy.display()))?;
    Ok((schedule, Some(copy)))
}

/// `--clone-sensors K`: K copies of the first sensor (named c0…), legs served
/// round robin. The maths of every step is unchanged when the sensors are
/// identical, so step rates with 1 and with 32 sensor processes compare.
fn clone_sensors(text: &str, k: usize) -> Result<String> {
    if k == 0 || k > MAX_SENSORS {
        return Err(Error::request(format!(
            "--clone-sensors must be between 1 and {MAX_SENSORS}, got {k}"
        )));
    }
    let mut v: toml::Table =
        toml::from_str(text).in_scenario(|| "parsing the scenario for --clone-sensors")?;
    let first = v
        .get("sensor")
        .and_then(|s| s.as_array())
        .and_then(|a| a.first())
        .cloned()
        .ok_or_else(|| Error::scenario("scenario has no sensor"))?;
    let sensors: Vec<toml::Value> = (0..k)
        .map(|i| {
            let mut s = first.clone();
            if let Some(t) = s.as_table_mut() {
                t.insert("name".into(), toml::Value::String(format!("c{i}")));
            }
            s
        })
        .collect();
    v.insert("sensor".into(), toml::Value::Array(sensors));
    if let Some(legs) = v.get_mut("leg").and_then(|l| l.as_array_mut()) {
        for (i, leg) in legs.iter_mut().enumerate() {
            if let Some(t) = leg.as_table_mut() {
                t.insert("sensor".into(), toml::Value::String(format!("c{}", i % k)));
            }
        }
    }
    if let Some(name) = v.get("name").and_then(|n| n.as_str()).map(str::to_string) {
        v.insert("name".into(), toml::Value::String(format!("{name}-x{k}")));
    }
    toml::to_string(&v).in_scenario(|| "writing the cloned scenario")
}

/// Most sensor processes a run may have (the service limits and the two
/// cores of the reference machine are sized for 32; beyond 64 a run only
/// loads the machine before failing).
pub const MAX_SENSORS: usize = 64;
// A recording's protobuf enums name every sensor a run can have.
const _: () = assert!(MAX_SENSORS <= etp_runtime::wire::NAMED_SENSORS as usize);

/// The run's scenario text (`--trigger` and `--clone-sensors` applied) and
/// the strategy file it runs, if any.
fn run_text(a: &RunRequest) -> Result<(String, Option<Strategy>)> {
    let (mut text, strategy_in) = match &a.target {
        RunTarget::Strategy { path, scenario } => {
            let s =
                std::fs::read_to_string(path).doing(|| format!("reading {}", path.display()))?;
            let st = Strategy::from_sealed_json(&s)
                .in_strategy(|| format!("loading strategy {}", path.display()))?;
            let text = match (scenario, &st.policy.scenario_toml) {
                (Some(arg), _) => scenario_text(arg)?,
                (None, Some(t)) => t.clone(),
                (None, None) => scenario_text(&st.policy.scenario_name).in_strategy(|| {
                    format!(
                        "strategy {} names scenario `{}`",
                        path.display(),
                        st.policy.scenario_name
                    )
                })?,
            };
            (text, Some(st))
        }
        RunTarget::Constant { scenario, .. } => (scenario_text(scenario)?, None),
    };
    if let Some(family) = a.trigger
        && strategy_in.is_some()
    {
        let own = ScenarioText::parse(text.clone()).in_scenario(|| "scenario")?;
        if own.scenario.trigger != family {
            return Err(Error::request(format!(
                "--trigger {family}: the strategy was made for trigger family `{}` (a strategy \
                 is tied to its scenario's hash); give --scenario with --delta to run another \
                 family",
                own.scenario.trigger
            )));
        }
    }
    if let Some(family) = a.trigger {
        let own = ScenarioText::parse(text).in_scenario(|| "scenario")?;
        text = own.with_trigger(family).in_scenario(|| "--trigger")?.text;
    }
    if let Some(k) = a.clone_sensors {
        if strategy_in.is_some() {
            return Err(Error::request(
                "--clone-sensors works with --scenario/--delta only (a strategy is tied to its scenario's hash)",
            ));
        }
        text = clone_sensors(&text, k)?;
    }
    Ok((text, strategy_in))
}

/// Each sensor's predicted energy per episode and where it comes from; a
/// constant strategy made here, or a strategy run under another channel
/// than its own (`robustness`), gets its whole prediction from the
/// in-process simulation.
fn sensor_energy(
    a: &RunRequest,
    scenario: &Scenario,
    strategy: &mut Strategy,
    robustness: bool,
) -> Result<(Vec<f64>, String)> {
    // Per-sensor energy: the MDP's expected energy per leg when the strategy
    // file carries it (`leg_energy`), else an in-process simulation of the
    // same strategy (which also predicts everything for a constant strategy
    // made here).
    let predict_episodes = a.predict_episodes.max(1);
    let from_file = matches!(a.target, RunTarget::Strategy { .. });
    // Under another channel than its own, the strategy file's predictions
    // (the MDP's, of its own channel) are not the run's: the in-process
    // simulation under the run's channel predicts instead.
    let (sensor_energy_per_episode, prediction_from) = match strategy.predictions.sensor_energy(scenario) {
        Some(e) if from_file && !robustness => (
            e,
            "the MDP: the strategy's expected energy per leg (strategy.json `leg_energy`: occupation measure × segment energy on its rebuilds, scaled to sum to `predicted`), summed over each sensor's legs".to_string(),
        ),
        _ => {
            let sim =
                simulate_strategy(scenario, &strategy.policy, predict_episodes, a.seed, &|_: u64| {})?.summary();
            if !from_file || robustness {
                let under = if robustness {
                    " under the run's channel"
                } else {
                    ""
                };
                strategy.predictions.predicted = Some(Prediction {
                    p_target: sim.p_target.value,
                    p_collision: sim.p_collision.value,
                    p_free: sim.p_free.value,
                    energy_mean: sim.energy_mean.value,
                });
                strategy.predictions.predicted_ci95 = Some(etp_shared::strategy::PredictionCi95 {
                    p_target: sim.p_target.ci95,
                    p_collision: sim.p_collision.ci95,
                    energy_mean: sim.energy_mean.ci95,
                });
                strategy.predictions.prediction_basis = format!(
                    "in-process simulation{under}, {predict_episodes} episodes (seed {})",
                    a.seed
                );
                strategy.provenance.label = format!(
                    "{} (prediction: in-process simulation{under}, {predict_episodes} episodes)",
                    strategy.provenance.label
                );
            }
            (
                scenario
                    .sensors
                    .iter()
                    .zip(&sim.sensors)
                    .map(|(s, c)| s.cost * c.transmissions as f64 / predict_episodes as f64)
                    .collect(),
                format!(
                    "in-process simulation of the same strategy: {predict_episodes} episodes, seed {} (--predict-episodes)",
                    a.seed
                ),
            )
        }
    };
    Ok((sensor_energy_per_episode, prediction_from))
}

/// Decide everything about a run; its files go into `dir` (the claimed run
/// folder).
pub fn prepare(a: &RunRequest, run_id: &RunId, dir: &std::path::Path) -> Result<Plan> {
    let (text, strategy_in) = run_text(a)?;
    // The run's channel, by the one override rule (docs/MODEL.md §8.6): the
    // text's own, replaced by the channel the strategy was synthesized for,
    // then by the radio options (a robustness study). Every process and the
    // recording read the channel from the run's copy of the scenario text,
    // so it is written there; the strategy is checked against its own text
    // first and then re-stamped with the run text's hash.
    let own = ScenarioText::parse(text).in_scenario(|| "scenario")?;
    if let Some(st) = &strategy_in {
        st.policy
            .check_scenario(&own.scenario)
            .in_strategy(|| "strategy and scenario")?;
    }
    let recorded = strategy_in.as_ref().and_then(|st| st.policy.radio.as_ref());
    let own_radio = own
        .scenario
        .radio
        .for_use(recorded, &RadioOverride::default())
        .in_strategy(|| "strategy")?;
    let run_radio = own
        .scenario
        .radio
        .for_use(recorded, &a.radio)
        .map_err(Error::Radio)?;
    let ScenarioText { text, scenario } = own
        .with_channel(&run_radio)
        .in_scenario(|| "the run's channel")?;
    // Refused before any work, like the radio options.
    let (channel_schedule, channel_schedule_path) = channel_schedule(a, &scenario, dir)?;
    let radio_synthesized = strategy_in.as_ref().map(|_| own_radio.clone());
    let robustness = strategy_in.is_some() && run_radio != own_radio;
    if scenario.sensors.len() > MAX_SENSORS {
        return Err(Error::request(format!(
            "the scenario has {} sensors; a run supports at most {MAX_SENSORS} sensor processes",
            scenario.sensors.len()
        )));
    }
    let mut strategy = match strategy_in {
        Some(mut st) => {
            // Checked against its own text above; the run's text carries the
            // channel (and so another hash when it is not the text's own).
            st.policy.scenario_hash = scenario.content_hash.clone();
            st.policy.radio = None;
            st
        }
        None => {
            let delta = match a.target {
                RunTarget::Constant { delta, .. } => delta,
                RunTarget::Strategy { .. } => 0.0,
            };
            let index = scenario
                .deltas
                .iter()
                .position(|d| (d - delta).abs() <= 1e-9 * d.abs().max(1.0))
                .ok_or_else(|| {
                    Error::request(format!(
                        "δ = {delta} is not one of the scenario's thresholds {:?}",
                        scenario.deltas
                    ))
                })?;
            // Predicted below by an in-process simulation.
            Strategy::constant(&scenario, index, None)
        }
    };
    let predict_episodes = a.predict_episodes.max(1);
    let (sensor_energy_per_episode, prediction_from) =
        sensor_energy(a, &scenario, &mut strategy, robustness)?;
    strategy.policy.scenario_toml = Some(text.clone());

    let dir = dir.to_path_buf();
    let scenario_path = dir.join("scenario.toml");
    let strategy_path = dir.join("strategy.json");
    std::fs::write(&scenario_path, &text)
        .doing(|| format!("writing {}", scenario_path.display()))?;
    std::fs::write(&strategy_path, strategy.to_json())
        .doing(|| format!("writing {}", strategy_path.display()))?;
    Ok(Plan {
        run_id: run_id.clone(),
        seed: a.seed,
        episodes: a.episodes,
        scenario,
        dir,
        scenario_path,
        strategy_path,
        sensor_energy_per_episode,
        prediction_from,
        predict_episodes,
        config_toml: String::new(),
        delta: etp_recording_tools::vocab::constant_delta(&strategy.policy),
        radio_synthesized,
        channel_schedule,
        channel_schedule_path,
        drift: a.drift,
    })
}
