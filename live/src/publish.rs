//! The view's channels and what a frame becomes on them.

use crate::draw::{self, Map};
use etp_runtime::live::{LiveMsg, OutcomeFrame, SlotFrame, Totals};
use etp_runtime::wire::OutcomeCode;
use etp_shared::scenario::Scenario;
use foxglove::messages::{Log, SceneUpdate, Timestamp, log::Level};
use foxglove::{Channel, ChannelBuilder, Context, RawChannel, Schema};
use serde_json::{Value, json};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The topics of the live view, with their schema names (what a client
/// sees advertised).
pub mod topics {
    pub const SCENE: &str = "/scene";
    pub const AGENT: &str = "/agent";
    pub const OUTCOME: &str = "/outcome";
    pub const STATUS: &str = "/status";
    pub const OUTCOMES: &str = "/outcomes";
    pub const ENERGY: &str = "/energy";
    pub const RATES: &str = "/rates";
    /// A flag of the channel monitor (docs/MODEL.md §11), once each.
    pub const DRIFT: &str = "/drift";
    /// `/sensor/<name>`, one per sensor.
    pub const SENSOR_PREFIX: &str = "/sensor/";

    /// (topic, schema name) of the fixed topics.
    pub const FIXED: [(&str, &str); 8] = [
        (SCENE, "foxglove.SceneUpdate"),
        (AGENT, "foxglove.SceneUpdate"),
        (OUTCOME, "foxglove.Log"),
        (STATUS, "etp.live.Status"),
        (OUTCOMES, "etp.live.Outcomes"),
        (ENERGY, "etp.live.Energy"),
        (RATES, "etp.live.Rates"),
        (DRIFT, "etp.live.Drift"),
    ];
    /// The schema of every `/sensor/<name>`.
    pub const SENSOR_SCHEMA: &str = "etp.live.Sensor";
}

/// A JSON channel with a JSON Schema of numeric properties (the Plot
/// panel's fare).
fn json_channel(
    ctx: &Arc<Context>,
    topic: &str,
    schema: &str,
    props: &[(&str, &str)],
) -> Option<Arc<RawChannel>> {
    let properties: serde_json::Map<String, Value> = props
        .iter()
        .map(|(name, description)| {
            let kind =
                if name.ends_with("_name") || ["outcome", "sensor", "quantity"].contains(name) {
                    "string"
                } else {
                    "number"
                };
            (
                (*name).to_string(),
                json!({"type": kind, "description": description}),
            )
        })
        .collect();
    let text = json!({
        "title": schema,
        "type": "object",
        "properties": properties,
    })
    .to_string();
    let built = ChannelBuilder::new(topic)
        .message_encoding("json")
        .schema(Schema::new(schema, "jsonschema", text.into_bytes()))
        .context(ctx)
        .build_raw();
    match built {
        Ok(c) => Some(c),
        Err(e) => {
            tracing::warn!("live view: channel {topic}: {e}");
            None
        }
    }
}

fn log_json(c: &Option<Arc<RawChannel>>, v: &Value) {
    if let Some(c) = c
        && c.has_sinks()
    {
        c.log(v.to_string().as_bytes());
    }
}

/// Every channel of the view, and what it needs to draw.
pub struct Channels {
    /// The channels' context: the channels (and their advertisements to
    /// clients) live as long as it does.
    _ctx: Arc<Context>,
    scenario: Scenario,
    map: Map,
    /// Predicted energy per episode, per sensor.
    predicted: Vec<f64>,
    scene: Channel<SceneUpdate>,
    agent: Channel<SceneUpdate>,
    outcome: Channel<Log>,
    status: Option<Arc<RawChannel>>,
    outcomes: Option<Arc<RawChannel>>,
    energy: Option<Arc<RawChannel>>,
    rates: Option<Arc<RawChannel>>,
    drift: Option<Arc<RawChannel>>,
    /// Flags of the channel monitor already shown (frames carry them all).
    drift_shown: AtomicUsize,
    sensors: Vec<Option<Arc<RawChannel>>>,
}

impl Channels {
    pub fn new(ctx: &Arc<Context>, scenario: &Scenario, predicted: Vec<f64>) -> Self {
        use topics::*;
        let typed = |topic: &str| ChannelBuilder::new(topic).context(ctx);
        Self {
            _ctx: ctx.clone(),
            map: Map::new(scenario),
            scene: typed(SCENE).build(),
            agent: typed(AGENT).build(),
            outcome: typed(OUTCOME).build(),
            status: json_channel(
                ctx,
                STATUS,
                "etp.live.Status",
                &[
                    ("episode", "episode of the frame"),
                    ("leg", "leg"),
                    ("step", "plant step k in the episode"),
                    ("sensor", "serving sensor's name"),
                    ("delta", "threshold δ of the leg"),
                    (
                        "attempts",
                        "transmission attempts of the serving sensor in this slot",
                    ),
                    ("delivered", "1 if a measurement was delivered in this slot"),
                    ("position_error", "‖C x − C x̂⁻‖ of the prior in this slot"),
                ],
            ),
            outcomes: json_channel(
                ctx,
                OUTCOMES,
                "etp.live.Outcomes",
                &[
                    ("episodes", "episodes finished"),
                    ("target", "episodes that reached the target"),
                    ("collision", "episodes that collided"),
                    ("free", "episodes that hit the step limit"),
                    ("p_target", "target / episodes"),
                    ("p_collision", "collision / episodes"),
                ],
            ),
            energy: json_channel(
                ctx,
                ENERGY,
                "etp.live.Energy",
                &[
                    (
                        "energy",
                        "Σ cost × attempts so far (the episode in progress included)",
                    ),
                    ("energy_finished", "Σ cost × attempts in finished episodes"),
                    (
                        "predicted",
                        "predicted energy of the finished episodes (per-episode prediction × episodes)",
                    ),
                    ("predicted_per_episode", "predicted energy per episode"),
                    ("energy_per_episode", "energy_finished / episodes"),
                    ("episodes", "episodes finished"),
                ],
            ),
            rates: json_channel(
                ctx,
                RATES,
                "etp.live.Rates",
                &[
                    ("all", "attempts per slot over every sensor so far"),
                    ("delivered", "delivered measurements per slot so far"),
                ],
            ),
            drift: json_channel(
                ctx,
                DRIFT,
                "etp.live.Drift",
                &[
                    ("sensor", "the flagged sensor's name"),
                    ("quantity", "loss, more_triggers or fewer_triggers"),
                    ("episode", "episode of the slot that raised the flag"),
                    ("step", "episode step k of that slot"),
                    ("statistic", "the CUSUM statistic (null: infinite)"),
                    ("threshold", "the threshold it reached"),
                    ("alternative", "the alternative tested against"),
                    ("since_onset", "observations from the estimated onset"),
                    ("observations", "observations of this sensor's test so far"),
                    ("estimate", "a loss flag's lost / attempts since the onset"),
                ],
            ),
            drift_shown: AtomicUsize::new(0),
            sensors: scenario
                .sensors
                .iter()
                .map(|s| {
                    json_channel(
                        ctx,
                        &format!("{SENSOR_PREFIX}{}", s.name),
                        SENSOR_SCHEMA,
                        &[
                            ("serving", "1 while this sensor serves the leg of the frame"),
                            (
                                "threshold",
                                "δ of the leg it serves (absent when not serving)",
                            ),
                            ("slots", "slots served so far"),
                            ("attempts", "transmission attempts so far (energy / cost)"),
                            ("delivered", "measurements delivered so far"),
                            ("rate", "attempts per served slot so far"),
                            ("energy", "cost × attempts so far"),
                            ("predicted_per_episode", "predicted energy per episode"),
                        ],
                    )
                })
                .collect(),
            scenario: scenario.clone(),
            predicted,
        }
    }

    /// Send the map.
    pub fn scene(&self) {
        if self.scene.has_sinks() {
            self.scene
                .log(&draw::scene(&self.scenario, &self.map, Timestamp::now()));
        }
    }

    pub fn publish(&self, m: &LiveMsg) {
        match m {
            LiveMsg::Slot(f) => self.slot(f),
            LiveMsg::Outcome(o) => self.episode_end(o),
        }
    }

    fn slot(&self, f: &SlotFrame) {
        let t = Timestamp::now();
        if self.agent.has_sinks() {
            self.agent
                .log(&draw::agent(&self.scenario, &self.map, f, t));
        }
        let name = self
            .scenario
            .sensors
            .get(f.sensor as usize)
            .map_or("?", |s| s.name.as_str());
        let error = match (
            self.map.project(&f.x, None),
            self.map.project(&f.mean, None),
        ) {
            (Some((a, _)), Some((b, _))) => Some((a - b).norm()),
            _ => None,
        };
        log_json(
            &self.status,
            &json!({
                "episode": f.episode, "leg": f.leg, "step": f.step, "sensor": name,
                "delta": f.delta, "attempts": f.attempts, "delivered": u32::from(f.delivered),
                "position_error": error,
            }),
        );
        self.totals(&f.totals, Some((f.sensor as usize, f.delta)));
    }

    fn episode_end(&self, o: &OutcomeFrame) {
        let name = OutcomeCode::try_from(o.outcome).map_or("unknown", OutcomeCode::name);
        if self.outcome.has_sinks() {
            let level = match OutcomeCode::try_from(o.outcome) {
                Ok(OutcomeCode::Target) => Level::Info,
                Ok(OutcomeCode::Collision) => Level::Error,
                _ => Level::Warning,
            };
            self.outcome.log(&Log {
                timestamp: Some(Timestamp::now()),
                level: level as i32,
                message: format!(
                    "episode {}: {name} after {} steps{}",
                    o.episode,
                    o.steps,
                    if o.degraded {
                        " (degraded: a dead link)"
                    } else {
                        ""
                    }
                ),
                name: "etp run".into(),
                ..Log::default()
            });
        }
        let t = &o.totals;
        let n = t.episodes.max(1) as f64;
        log_json(
            &self.outcomes,
            &json!({
                "episodes": t.episodes, "target": t.target, "collision": t.collision,
                "free": t.free, "p_target": t.target as f64 / n,
                "p_collision": t.collision as f64 / n, "outcome": name,
            }),
        );
        self.totals(t, None);
    }

    /// `/energy`, `/rates` and `/sensor/<name>` from the running totals;
    /// `serving` is the frame's serving sensor and δ, if it is a slot's.
    fn totals(&self, t: &Totals, serving: Option<(usize, f64)>) {
        let cost = |i: usize| self.scenario.sensors.get(i).map_or(1.0, |s| s.cost);
        let energy: f64 = t
            .attempts
            .iter()
            .enumerate()
            .map(|(i, a)| cost(i) * *a as f64)
            .sum();
        let finished: f64 = t
            .attempts_finished
            .iter()
            .enumerate()
            .map(|(i, a)| cost(i) * *a as f64)
            .sum();
        let per_episode: f64 = self.predicted.iter().sum();
        log_json(
            &self.energy,
            &json!({
                "energy": energy, "energy_finished": finished,
                "predicted": per_episode * t.episodes as f64,
                "predicted_per_episode": per_episode,
                "energy_per_episode": if t.episodes > 0 { Some(finished / t.episodes as f64) } else { None },
                "episodes": t.episodes,
            }),
        );
        let steps = t.steps.max(1) as f64;
        let mut rates = serde_json::Map::new();
        rates.insert(
            "all".into(),
            json!(t.attempts.iter().sum::<u64>() as f64 / steps),
        );
        rates.insert(
            "delivered".into(),
            json!(t.delivered.iter().sum::<u64>() as f64 / steps),
        );
        for (i, c) in self.sensors.iter().enumerate() {
            let (slots, attempts) = (
                t.slots.get(i).copied().unwrap_or(0),
                t.attempts.get(i).copied().unwrap_or(0),
            );
            let rate = (slots > 0).then(|| attempts as f64 / slots as f64);
            if let (Some(r), Some(s)) = (rate, self.scenario.sensors.get(i)) {
                rates.insert(s.name.clone(), json!(r));
            }
            let here = serving.filter(|(s, _)| *s == i);
            log_json(
                c,
                &json!({
                    "serving": u32::from(here.is_some()),
                    "threshold": here.map(|(_, d)| d),
                    "slots": slots, "attempts": attempts,
                    "delivered": t.delivered.get(i).copied().unwrap_or(0),
                    "rate": rate, "energy": cost(i) * attempts as f64,
                    "predicted_per_episode": self.predicted.get(i),
                }),
            );
        }
        log_json(&self.rates, &Value::Object(rates));
        self.drift_flags(t);
    }

    /// The flags in `t` not shown yet: each on `/drift` and as a warning
    /// line on `/outcome`.
    fn drift_flags(&self, t: &Totals) {
        let shown = self.drift_shown.load(Ordering::Relaxed);
        let Some(new) = t.drift.get(shown..).filter(|n| !n.is_empty()) else {
            return;
        };
        self.drift_shown.store(t.drift.len(), Ordering::Relaxed);
        for flag in new {
            if let Ok(v) = serde_json::to_value(flag) {
                log_json(&self.drift, &v);
            }
            if self.outcome.has_sinks() {
                self.outcome.log(&Log {
                    timestamp: Some(Timestamp::now()),
                    level: Level::Warning as i32,
                    message: format!("channel drift: {}", flag.describe()),
                    name: "etp run".into(),
                    ..Log::default()
                });
            }
        }
    }
}
