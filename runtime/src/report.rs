//! The coordinator's run report (JSON on its stdout), read by `etp run` and the
//! end-to-end tests.

use etp_shared::strategy::{Prediction, PredictionCi95};
use serde::{Deserialize, Serialize};

/// One leg of one episode, as the coordinator saw it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LegRecord {
    pub leg: u32,
    pub sensor: u32,
    pub delta: f64,
    /// Plant steps of the leg.
    pub steps: u32,
    /// Measurements the agent received on this leg.
    pub received: u32,
    /// Transmission attempts in the sensor's ledger (`None`: no ledger,
    /// sensor dead); each costs c_m.
    #[serde(rename = "transmissions")]
    pub transmitted: Option<u32>,
    /// Of those, delivered to the agent and lost on the radio (the ledger's).
    #[serde(default)]
    pub delivered: Option<u32>,
    #[serde(default)]
    pub lost: Option<u32>,
    /// Slots in which the trigger fired (the ledger's).
    #[serde(default)]
    pub triggers: Option<u32>,
    /// Slots in the sensor's ledger.
    pub slots: Option<u32>,
}

/// One episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    pub episode: u64,
    /// "target", "collision" or "free".
    pub outcome: String,
    /// A dead link in this episode (prediction-only slots) or a missing ledger.
    pub degraded: bool,
    pub steps: u32,
    /// Sensor-side energy: Σ c_m × transmissions (agent-received where no ledger).
    pub energy: f64,
    pub legs: Vec<LegRecord>,
}

/// A dead link the agent detected.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FaultRecord {
    pub episode: u64,
    pub sensor: String,
    /// From the start of the agent's wait on the slot to its verdict, ms.
    pub detect_ms: f64,
    pub wait_started_unix_ns: u64,
    pub detected_unix_ns: u64,
    /// Slots of the episode done with prediction only.
    pub dead_slots: u32,
}

/// A flag of the agent's channel monitor (a `drift` message), as `run
/// --json` and `replay summary --json` show it (docs/MODEL.md §11).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DriftRecord {
    pub sensor: String,
    /// `loss`, `more_triggers` or `fewer_triggers`.
    pub quantity: String,
    pub episode: u64,
    /// Episode step k of the slot that raised it.
    pub step: u32,
    /// The CUSUM statistic; `None` (JSON null) when infinite: the slot
    /// carried what the synthesized channel cannot produce.
    pub statistic: Option<f64>,
    pub threshold: f64,
    /// The alternative the statistic tested against (loss per attempt, or
    /// trigger probability per slot).
    pub alternative: f64,
    /// Observations from the estimated onset to the flag.
    pub since_onset: u64,
    pub observations: u64,
    /// A loss flag's lost / attempts since the onset.
    pub estimate: Option<f64>,
}

impl DriftRecord {
    /// The record of a `drift` message; `None` for a quantity code this
    /// build does not know. `sensor_name` names an index.
    pub fn from_wire(
        d: &crate::wire::agent_to_coordinator::Drift,
        sensor_name: impl Fn(u32) -> String,
    ) -> Option<Self> {
        let quantity = crate::wire::DriftQuantity::try_from(d.quantity).ok()?;
        Some(Self {
            sensor: sensor_name(d.sensor),
            quantity: quantity.name().to_string(),
            episode: d.header.episode,
            step: d.header.step,
            statistic: d.statistic.is_finite().then_some(d.statistic),
            threshold: d.threshold,
            alternative: d.alternative,
            since_onset: d.since_onset,
            observations: d.observations,
            estimate: (d.estimate >= 0.0).then_some(d.estimate),
        })
    }

    /// One line: `s1 loss at episode 55 step 12: CUSUM 18.3 ≥ 17.1 (loss
    /// 0.3 against the model; 40 observations since the onset, loss
    /// measured 0.31)`.
    pub fn describe(&self) -> String {
        let stat = self
            .statistic
            .map_or_else(|| "∞".to_string(), |s| format!("{s:.2}"));
        let what = match self.quantity.as_str() {
            "loss" => format!("loss per attempt {:.3}", self.alternative),
            _ => format!("trigger probability {:.3}", self.alternative),
        };
        let mut line = format!(
            "{} {} at episode {} step {}: CUSUM {stat} ≥ {:.2} against {what}, {} observation{} since the onset",
            self.sensor,
            self.quantity.replace('_', " "),
            self.episode,
            self.step,
            self.threshold,
            self.since_onset,
            if self.since_onset == 1 { "" } else { "s" }
        );
        if let Some(e) = self.estimate {
            line.push_str(&format!(", loss measured since then {e:.3}"));
        }
        line
    }
}

/// Per-sensor totals over the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorTotals {
    pub name: String,
    /// Σ transmission attempts in the sensor's ledgers (legs that have one).
    pub transmitted: u64,
    /// Σ attempts delivered and lost, from the same ledgers: `transmitted =
    /// delivered + lost` in a sound run.
    #[serde(default)]
    pub delivered: u64,
    #[serde(default)]
    pub lost: u64,
    /// Σ slots in which the trigger fired, from the same ledgers.
    #[serde(default)]
    pub triggers: u64,
    /// Σ measurements the agent received from it on the legs that have a
    /// ledger: the same legs as `delivered`, so the two are equal in a
    /// sound run (with or without dead sensors).
    pub received: u64,
    /// Σ measurements the agent received on legs whose ledger never came (a
    /// dead sensor's open leg): counted, but checked against nothing.
    #[serde(default)]
    pub received_without_ledger: u64,
    /// Σ slots it served.
    pub slots: u64,
    /// Σ c_m × transmitted.
    pub energy: f64,
    /// Legs whose ledger never came (sensor dead).
    pub missing_ledgers: u64,
}

/// Everything the coordinator knows at the end of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunReport {
    pub run_id: String,
    pub scenario: String,
    pub scenario_hash: String,
    pub strategy_label: String,
    pub seed: u64,
    pub requested_episodes: u64,
    pub episodes: u64,
    pub target: u64,
    pub collision: u64,
    pub free: u64,
    pub degraded: u64,
    pub steps: u64,
    /// Wall time from the first episode's start to the last outcome, s.
    pub seconds: f64,
    /// The strategy file's prediction (None for a `--quick` strategy) and
    /// its 95 % half-widths.
    pub predicted: Option<Prediction>,
    #[serde(default)]
    pub predicted_ci95: Option<PredictionCi95>,
    pub sensors: Vec<SensorTotals>,
    pub faults: Vec<FaultRecord>,
    pub episode_results: Vec<EpisodeRecord>,
    /// Why the run stopped early, if it did.
    pub aborted: Option<String>,
    /// The channel monitor's flags in the episodes reported, in the order
    /// raised.
    #[serde(default)]
    pub drift: Vec<DriftRecord>,
}

/// What a sensor host needs to take part in a run across hosts (served by
/// the agent host's bridge): everything, so nothing is copied by hand.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SessionInfo {
    pub run_id: String,
    /// The scenario's TOML text.
    pub scenario_toml: String,
    pub seed: u64,
    /// Names of every sensor of the scenario, in index order.
    pub sensors: Vec<String>,
    /// Indices of the sensors served from other hosts.
    pub remote: Vec<usize>,
    /// The run's channel changes (`etp run --channel-schedule`, every key
    /// written out), applied by the sensors wherever they run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub channel_schedule_toml: Option<String>,
    /// What the agent host puts on the link
    /// ([`crate::wire::stamp::LINK_PROTOCOL`]); absent (1) from an etp
    /// whose link carried the payload alone. A sensor host of another
    /// version refuses to join.
    #[serde(default = "link_protocol_1")]
    pub link_protocol: u32,
}

fn link_protocol_1() -> u32 {
    1
}

/// Puts towards one remote sensor held up by a peer that stopped reading:
/// the bridge's `stalled` line, per sensor, as `etp run` reads it.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Stall {
    pub puts: u64,
    pub longest_ms: u64,
    /// The host the sensor's downlink went to (agent host).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
    /// The host was closed for not reading and refused for the rest of the run.
    #[serde(default)]
    pub refused: bool,
    /// The sensor's messages not sent since (its host refused).
    #[serde(default)]
    pub dropped: u64,
}
