//! A run's request, typed: what [`crate::execute_run`] takes. It is built
//! once, from the command line (`etp run`'s flags merged with its `--config`
//! run file), from a run file alone, from Python or from the demo, always
//! through the run file's keys ([`RunConfig`]) or directly; nothing below
//! this point parses text or knows a flag.
//!
//! The checks that hold whatever the source (what to run, the recording,
//! the remote sensors, the numbers' ranges) are [`RunRequest::from_config`]'s,
//! and its errors name the key (which is also the flag's long name).

use crate::config::{self, RunConfig};
use crate::error::{Error, Result};
use etp_runtime::link_keys;
use etp_shared::drift::OnDrift;
use etp_shared::radio::{Estimator, RadioOverride};
use etp_shared::trigger::TriggerFamily;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// What a run runs.
#[derive(Debug, Clone, PartialEq)]
pub enum RunTarget {
    /// A strategy file (from `etp strategy`), on its own scenario or on
    /// `scenario` (a built-in name or a TOML path).
    Strategy {
        path: PathBuf,
        scenario: Option<String>,
    },
    /// A constant threshold `delta` (one of the scenario's Δ), made into a
    /// strategy on the fly.
    Constant { scenario: String, delta: f64 },
}

/// Where the run's messages are recorded.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum RecordTo {
    /// Not recorded.
    #[default]
    Nothing,
    /// This MCAP file (`--record FILE`).
    File(PathBuf),
    /// `recordings/<scenario>-<run-id>.mcap` (`--record-default`).
    DefaultFile,
}

/// How a link across hosts (and a live view off loopback) is protected.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinkProtection {
    /// Key folder of `etp certs init DIR`: TLS, both ends authenticated.
    pub tls: Option<PathBuf>,
    /// Plain TCP, neither authenticated nor encrypted (`--insecure`).
    pub insecure: bool,
}

impl LinkProtection {
    /// The bridge's arguments for `endpoint` as host `name` of the key
    /// folder, checked (refusal names the option); `--insecure` is warned.
    pub fn bridge_args(&self, endpoint: &str, name: &str) -> Result<Vec<String>> {
        link_keys::resolve(endpoint, self.tls.as_deref(), name, self.insecure)?;
        if self.insecure {
            eprintln!(
                "etp: warning: --insecure: the link at {endpoint} is plain TCP, neither \
                 authenticated nor encrypted (isolated test networks only)"
            );
            return Ok(vec!["--insecure".into()]);
        }
        let dir = self.tls.as_ref().map(|d| {
            std::path::absolute(d)
                .unwrap_or_else(|_| d.clone())
                .display()
                .to_string()
        });
        Ok(match dir {
            Some(d) => vec!["--tls".into(), d],
            None => Vec::new(),
        })
    }
}

/// Sensors served from other hosts.
#[derive(Debug, Clone, PartialEq)]
pub struct RemoteSensors {
    /// The Zenoh endpoint the agent host listens on (`tls/ADDR:PORT`).
    pub listen: String,
    /// The remote sensors' names.
    pub sensors: Vec<String>,
    /// Seconds to wait for them to join.
    pub join_timeout: f64,
}

/// The live Foxglove view of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveView {
    pub addr: SocketAddr,
    /// Start the episodes only once a client subscribed (`--live-wait`).
    pub wait_for_client: bool,
}

/// The run's channel monitor (docs/MODEL.md §11).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftWatch {
    /// The probability that any flag is raised in a run on the synthesized
    /// channel, in (0, 1).
    pub false_alarm: f64,
    pub on_drift: OnDrift,
}

impl Default for DriftWatch {
    fn default() -> Self {
        Self {
            false_alarm: etp_shared::drift::DEFAULT_FALSE_ALARM,
            on_drift: OnDrift::Warn,
        }
    }
}

/// One run, every value resolved (defaults filled in).
#[derive(Debug, Clone, PartialEq)]
pub struct RunRequest {
    pub target: RunTarget,
    /// At least 1.
    pub episodes: u64,
    pub seed: u64,
    /// Each setting given replaces the strategy's (or scenario's) channel.
    pub radio: RadioOverride,
    /// The trigger family over the scenario's own.
    pub trigger: Option<TriggerFamily>,
    /// A file of changes of sensors' links during the run (docs/MODEL.md
    /// §8.8), applied on the sensor side.
    pub channel_schedule: Option<PathBuf>,
    /// The channel monitor's false-alarm rate and what its flags do.
    pub drift: DriftWatch,
    /// Seconds after which everything is killed and the run fails.
    pub deadline: f64,
    /// Names the services `etp/<run-id>/…` (generated when `None`).
    pub run_id: Option<String>,
    /// In-process episodes that predict each sensor's energy.
    pub predict_episodes: u64,
    /// Benchmark: K copies of the first sensor, legs served round robin.
    pub clone_sensors: Option<usize>,
    pub record: RecordTo,
    /// Replace an existing recording once the run ran.
    pub force: bool,
    /// Exit 0 on episodes degraded by a dead link (counts must still agree).
    pub allow_degraded: bool,
    /// A slot not closed within this many ms is a dead link.
    pub slot_deadline: Option<u64>,
    pub remote: Option<RemoteSensors>,
    pub link: LinkProtection,
    pub live: Option<LiveView>,
    /// Quiet progress (the caller prints one JSON object).
    pub json: bool,
    /// Every episode in the JSON report.
    pub episode_details: bool,
}

impl RunRequest {
    /// A run of `target` with every default.
    pub fn new(target: RunTarget) -> RunRequest {
        RunRequest {
            target,
            episodes: config::DEFAULT_EPISODES,
            seed: config::DEFAULT_SEED,
            radio: RadioOverride::default(),
            trigger: None,
            channel_schedule: None,
            drift: DriftWatch::default(),
            deadline: config::DEFAULT_DEADLINE,
            run_id: None,
            predict_episodes: config::DEFAULT_PREDICT_EPISODES,
            clone_sensors: None,
            record: RecordTo::Nothing,
            force: false,
            allow_degraded: false,
            slot_deadline: None,
            remote: None,
            link: LinkProtection::default(),
            live: None,
            json: false,
            episode_details: false,
        }
    }

    /// The request a run file (or the command line's flags written as its
    /// keys) asks for; the errors name the key. `force`, `json` and
    /// `episode_details` are not run-file keys: set them on the result.
    pub fn from_config(c: RunConfig) -> Result<RunRequest> {
        let target = match (c.strategy, c.scenario, c.delta) {
            (Some(path), scenario, None) => RunTarget::Strategy { path, scenario },
            (None, Some(scenario), Some(delta)) => RunTarget::Constant { scenario, delta },
            (Some(_), _, Some(_)) => {
                return Err(Error::request(
                    "give either a strategy file or --scenario with --delta, not both",
                ));
            }
            (None, None, Some(_)) => {
                return Err(Error::request(
                    "`delta` needs `scenario` (a constant-δ run)",
                ));
            }
            _ => {
                return Err(Error::request(
                    "give a strategy.json, or --scenario NAME --delta D for a constant threshold",
                ));
            }
        };
        let episodes = c.episodes.unwrap_or(config::DEFAULT_EPISODES);
        if episodes == 0 {
            return Err(Error::request("--episodes must be at least 1"));
        }
        let deadline = c.deadline.unwrap_or(config::DEFAULT_DEADLINE);
        if !(deadline.is_finite() && deadline > 0.0) {
            return Err(Error::request(
                "--deadline must be a positive number of seconds",
            ));
        }
        if c.slot_deadline == Some(0) {
            return Err(Error::request("--slot-deadline must be at least 1 ms"));
        }
        let record = match (c.record, c.record_default.unwrap_or(false)) {
            (Some(_), true) => {
                return Err(Error::request(
                    "`record` and `record_default` exclude each other",
                ));
            }
            (Some(p), false) => RecordTo::File(p),
            (None, true) => RecordTo::DefaultFile,
            (None, false) => RecordTo::Nothing,
        };
        let remote = match (c.listen, c.remote.filter(|r| !r.is_empty())) {
            (Some(listen), Some(sensors)) => Some(RemoteSensors {
                listen,
                sensors,
                join_timeout: c.join_timeout.unwrap_or(config::DEFAULT_JOIN_TIMEOUT),
            }),
            (None, None) => None,
            _ => {
                return Err(Error::request(
                    "`listen` and `remote` go together (sensors served from other hosts)",
                ));
            }
        };
        let estimator = match c.estimator.as_deref() {
            None => None,
            Some(e) => Some(Estimator::parse(e).ok_or_else(|| {
                Error::request(format!(
                    "--estimator `{e}`: the estimator is `aware` or `naive`"
                ))
            })?),
        };
        let drift = DriftWatch {
            false_alarm: match c.drift_false_alarm {
                None => etp_shared::drift::DEFAULT_FALSE_ALARM,
                Some(a) if a > 0.0 && a < 1.0 => a,
                Some(a) => {
                    return Err(Error::request(format!(
                        "--drift-false-alarm {a}: a probability per run, in (0, 1)"
                    )));
                }
            },
            on_drift: match c.on_drift.as_deref() {
                None => OnDrift::Warn,
                Some(o) => OnDrift::parse(o)
                    .ok_or_else(|| Error::request(format!("--on-drift `{o}`: `warn` or `stop`")))?,
            },
        };
        let live_wait = c.live_wait.unwrap_or(false);
        let live = match c.live {
            Some(addr) => Some(LiveView {
                addr,
                wait_for_client: live_wait,
            }),
            None if live_wait => return Err(Error::request("--live-wait needs --live")),
            None => None,
        };
        Ok(RunRequest {
            target,
            episodes,
            seed: c.seed.unwrap_or(config::DEFAULT_SEED),
            radio: RadioOverride {
                loss: c.loss,
                retries: c.retries,
                burst: c.burst,
                estimator,
            },
            trigger: c.trigger,
            channel_schedule: c.channel_schedule,
            drift,
            deadline,
            run_id: c.run_id,
            predict_episodes: c
                .predict_episodes
                .unwrap_or(config::DEFAULT_PREDICT_EPISODES),
            clone_sensors: c.clone_sensors,
            record,
            force: false,
            allow_degraded: c.allow_degraded.unwrap_or(false),
            slot_deadline: c.slot_deadline,
            remote,
            link: LinkProtection {
                tls: c.tls,
                insecure: c.insecure.unwrap_or(false),
            },
            live,
            json: false,
            episode_details: false,
        })
    }

    /// The request as a run file that runs it again (the `etp.config`
    /// record, through [`config::stored`]): every resolved value, the
    /// recording as the file it went to, never the live view (how a run is
    /// watched, not what it computes).
    pub fn to_config(&self, record: Option<&Path>) -> RunConfig {
        let (strategy, scenario, delta) = match &self.target {
            RunTarget::Strategy { path, scenario } => (Some(path.clone()), scenario.clone(), None),
            RunTarget::Constant { scenario, delta } => (None, Some(scenario.clone()), Some(*delta)),
        };
        let r = &self.radio;
        RunConfig {
            strategy,
            scenario,
            delta,
            episodes: Some(self.episodes),
            seed: Some(self.seed),
            deadline: Some(self.deadline),
            run_id: self.run_id.clone(),
            predict_episodes: Some(self.predict_episodes),
            clone_sensors: self.clone_sensors,
            record: record.map(Path::to_path_buf),
            record_default: None,
            allow_degraded: Some(self.allow_degraded),
            slot_deadline: self.slot_deadline,
            listen: self.remote.as_ref().map(|x| x.listen.clone()),
            remote: self.remote.as_ref().map(|x| x.sensors.clone()),
            join_timeout: Some(
                self.remote
                    .as_ref()
                    .map_or(config::DEFAULT_JOIN_TIMEOUT, |x| x.join_timeout),
            ),
            tls: self.link.tls.clone(),
            insecure: self.link.insecure.then_some(true),
            loss: r.loss,
            retries: r.retries,
            burst: r.burst,
            estimator: r.estimator.map(|e| e.name().to_string()),
            trigger: self.trigger,
            channel_schedule: self.channel_schedule.clone(),
            drift_false_alarm: Some(self.drift.false_alarm),
            on_drift: Some(self.drift.on_drift.name().to_string()),
            live: None,
            live_wait: None,
        }
    }
}
