//! A threshold strategy: at decision point i, the belief's covariance region s
//! selects a distribution ω(s) over the thresholds Δ (docs/MODEL.md §5).
//!
//! Stored as `strategy.json`. It carries the scenario's content hash so it is
//! never applied to another scenario, and its own discretization so the
//! coordinator and the in-process validator classify beliefs identically.
//!
//! The file is sealed by its own hash: its last key, `content_sha256`, is the
//! SHA-256 of the file's exact text without that key ([`Strategy::to_json`]).
//! Any edit — a value (`scenario_name`, `predicted`, `leg_energy`, …), a key
//! added or removed, or a reformatting — is refused by
//! [`Strategy::from_sealed_json`] (the loader of strategy files). Files
//! written before the seal are refused too, with a message to re-run `etp
//! strategy`; [`Strategy::from_json`] (strategies embedded in recordings)
//! checks the seal when present and accepts old, unsealed ones.

use crate::discretization::{Discretization, Region, RegionSplit, SPLIT_MARK, check_splits};
use crate::radio::{Radio, RadioOverride};
use crate::scenario::Scenario;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

mod aggregation;
mod format;
mod prediction;
pub use aggregation::{AggregationCheck, AggregationError, PredictionCi95, SimulatedValue};
pub use prediction::{
    CertifiedPrediction, Diagnostics, Prediction, RebuildValue, RequestRound, SelectionValues,
};

/// Version of the `strategy.json` layout. Version 2: `predicted` is the
/// prediction etp stands by (with `predicted_ci95` and `prediction_basis`),
/// every other value under `diagnostics`; version 1 files (whose `predicted`
/// was the selection-time value) are read and converted ([`format`]).
pub const STRATEGY_FORMAT_VERSION: u32 = 2;

/// Why a strategy cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum StrategyError {
    #[error("strategy file is not valid JSON for a strategy: {0}")]
    Parse(String),
    #[error(
        "strategy format version {found} is not supported (this etp reads versions 1 to {expected})"
    )]
    Version { found: u32, expected: u32 },
    #[error(
        "strategy was made for scenario `{strategy_name}` (hash {strategy_hash:.12}…), not for `{scenario_name}` (hash {scenario_hash:.12}…)"
    )]
    ScenarioMismatch {
        strategy_name: String,
        strategy_hash: String,
        scenario_name: String,
        scenario_hash: String,
    },
    #[error("strategy is inconsistent: {0}")]
    Invalid(String),
    #[error(
        "strategy file has no `content_sha256` (written before strategy files were sealed by their hash, or the key was removed); re-create it with `etp strategy` (or `etp run --scenario NAME --delta D` for a constant δ)"
    )]
    Unsealed,
    #[error(
        "strategy file was changed after it was written: {0}; a strategy file is used only as `etp strategy` wrote it (re-create it with `etp strategy`)"
    )]
    Tampered(String),
}

/// The key of the seal, the file's last (see the module doc).
const SEAL_KEY: &str = "content_sha256";

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The seal of a strategy file's text: `Ok(None)` without one, `Ok(Some(()))`
/// when it matches, an error naming what is wrong otherwise.
fn check_seal(text: &str) -> Result<Option<()>, StrategyError> {
    let t = text.trim_end();
    let marker = format!(",\n  \"{SEAL_KEY}\": \"");
    let Some(at) = t.rfind(&marker) else {
        return if t.contains(&format!("\"{SEAL_KEY}\"")) {
            Err(StrategyError::Tampered(format!(
                "`{SEAL_KEY}` is not the file's last key as written (the file was reformatted or keys were moved)"
            )))
        } else {
            Ok(None)
        };
    };
    let rest = &t[at + marker.len()..];
    let Some(hex) = rest.strip_suffix("\"\n}") else {
        return Err(StrategyError::Tampered(format!(
            "keys follow `{SEAL_KEY}`, which is the file's last key as written"
        )));
    };
    let body = format!("{}\n}}", &t[..at]);
    let actual = sha256_hex(body.as_bytes());
    if hex != actual {
        return Err(StrategyError::Tampered(format!(
            "its text hashes to {actual:.12}…, not to the `{SEAL_KEY}` {hex:.12}… it was written with (a field such as `scenario_name`, `predicted`, `leg_energy` or `states` was edited)"
        )));
    }
    Ok(Some(()))
}

/// ω for one abstract state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StrategyState {
    pub decision_point: usize,
    pub region: Region,
    /// Probability of each threshold (same order as [`Strategy::deltas`]); sums to 1.
    pub omega: Vec<f64>,
}

/// A memoryless randomised threshold strategy.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Strategy {
    pub format_version: u32,
    pub scenario_name: String,
    pub scenario_hash: String,
    /// How it was obtained (e.g. "min energy s.t. P_tar ≥ 0.95", "constant δ = 0").
    pub label: String,
    /// The actions Δ.
    pub deltas: Vec<f64>,
    /// Regions of covariances; `None` for a region-free strategy (ω depends on
    /// the decision point only, e.g. a constant δ).
    pub discretization: Option<Discretization>,
    pub states: Vec<StrategyState>,
    /// The prediction etp stands by (docs/MODEL.md §7.4): for a strategy of
    /// `etp strategy`, the mean cross-fitted value of its on-policy rebuilds
    /// (its own beliefs in the pools, so no aggregation error), with
    /// [`Strategy::predicted_ci95`]; for a constant δ of `etp run --scenario
    /// … --delta`, an in-process simulation. `None` for a `--quick`
    /// strategy, whose only values are the biased ones of [`Diagnostics`].
    pub predicted: Option<Prediction>,
    /// The 95 % half-widths of [`Strategy::predicted`] (Student's t over the
    /// rebuilds, or the simulation's interval).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub predicted_ci95: Option<PredictionCi95>,
    /// How [`Strategy::predicted`] was obtained, in words.
    #[serde(default)]
    pub prediction_basis: String,
    /// Certified bounds at a confidence level (for a strategy of `etp
    /// strategy`: from the first on-policy rebuild's own transitions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certified: Option<CertifiedPrediction>,
    /// The scenario's TOML text, so a strategy file is self-contained
    /// (`etp validate` / `etp run` need nothing else). Optional: without it the
    /// scenario is looked up among the built-ins by name and hash.
    #[serde(default)]
    pub scenario_toml: Option<String>,
    /// Selection-time expected energy spent on each leg (the MDP's
    /// occupation measure × mean segment energy, transmissions × cost): the
    /// per-sensor prediction of `etp run` and `etp validate` (a sensor's
    /// share = the legs it serves). Absent in older files and for strategies
    /// made without an MDP.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leg_energy: Option<Vec<f64>>,
    /// The radio the strategy was synthesized for (docs/MODEL.md §8) when it
    /// is not its scenario text's own `[radio]` (`etp synthesize --loss …`);
    /// absent = the scenario's own. [`Strategy::scenario`] applies it, so a
    /// strategy is evaluated under its own channel unless told otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radio: Option<Radio>,
    /// Regions split by `etp synthesize --split-budget` (docs/MODEL.md §7.3):
    /// the belief's region is refined by them before ω is looked up. Absent
    /// (none) in older files and without splitting, which classify as before.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub splits: Vec<RegionSplit>,
    /// The aggregation error measured at selection time (`etp strategy
    /// --aggregation-check N`, on by default): the strategy simulated
    /// against its prediction. Absent in older files and with N = 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aggregation: Option<AggregationCheck>,
    /// Every other value, for diagnosis only: the selection-time and
    /// cross-fitted values on the MDP it was selected on (biased), each
    /// rebuild's, and the rounds of the request loop.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diagnostics: Option<Diagnostics>,
}

impl Strategy {
    /// Predicted energy per episode of each of `scenario`'s sensors, from
    /// [`Strategy::leg_energy`]; `None` without it (or if it does not match
    /// the scenario's legs).
    pub fn sensor_energy(&self, scenario: &Scenario) -> Option<Vec<f64>> {
        let legs = self.leg_energy.as_ref()?;
        if legs.len() != scenario.legs.len() {
            return None;
        }
        let mut out = vec![0.0; scenario.sensors.len()];
        for (leg, e) in scenario.legs.iter().zip(legs) {
            *out.get_mut(leg.sensor)? += e;
        }
        Some(out)
    }

    /// The same δ on every leg (region-free).
    pub fn constant(
        scenario: &Scenario,
        delta_index: usize,
        predicted: Option<Prediction>,
    ) -> Self {
        let mut omega = vec![0.0; scenario.deltas.len()];
        omega[delta_index] = 1.0;
        Self {
            format_version: STRATEGY_FORMAT_VERSION,
            scenario_name: scenario.name.clone(),
            scenario_hash: scenario.content_hash.clone(),
            label: format!("constant δ = {}", scenario.deltas[delta_index]),
            deltas: scenario.deltas.clone(),
            discretization: None,
            states: (0..scenario.num_legs())
                .map(|i| StrategyState {
                    decision_point: i,
                    region: Region(Vec::new()),
                    omega: omega.clone(),
                })
                .collect(),
            predicted,
            predicted_ci95: None,
            prediction_basis: String::new(),
            certified: None,
            scenario_toml: None,
            leg_energy: None,
            radio: None,
            splits: Vec::new(),
            aggregation: None,
            diagnostics: None,
        }
    }

    /// The scenario this strategy was made for: the embedded text, else the
    /// built-in of that name; refused unless its content hash matches.
    pub fn scenario(&self) -> Result<Scenario, StrategyError> {
        let parsed = match &self.scenario_toml {
            Some(text) => Scenario::from_toml(text),
            None => Scenario::builtin(&self.scenario_name),
        }
        .map_err(|e| {
            StrategyError::Invalid(format!("its scenario `{}`: {e}", self.scenario_name))
        })?;
        self.check_scenario(&parsed)?;
        self.with_own_radio(parsed)
    }

    /// `scenario` (this strategy's, hash checked) under the radio the
    /// strategy was synthesized for: steps 1–2 of the one override rule
    /// ([`Radio::for_use`], docs/MODEL.md §8.6) — [`Strategy::radio`] when
    /// present (one link per sensor, or none for every link ideal), else the
    /// scenario's own.
    pub fn with_own_radio(&self, mut scenario: Scenario) -> Result<Scenario, StrategyError> {
        scenario.radio = scenario
            .radio
            .for_use(self.radio.as_ref(), &RadioOverride::default())
            .map_err(|e| {
                StrategyError::Invalid(format!("its `radio` for scenario `{}`: {e}", scenario.name))
            })?;
        Ok(scenario)
    }

    /// A strategy file: the seal must be present and match (see the module
    /// doc), then as [`Strategy::from_json`].
    pub fn from_sealed_json(text: &str) -> Result<Self, StrategyError> {
        if check_seal(text)?.is_none() {
            // Not JSON at all is a parse error, not a missing seal.
            serde_json::from_str::<serde_json::Value>(text)
                .map_err(|e| StrategyError::Parse(e.to_string()))?;
            return Err(StrategyError::Unsealed);
        }
        Self::from_json(text)
    }

    /// Parse and check internal consistency; the seal is checked when the
    /// text has one (strategies recorded before it was introduced have none).
    pub fn from_json(text: &str) -> Result<Self, StrategyError> {
        #[derive(Deserialize)]
        struct Versioned {
            format_version: u32,
        }
        let v: Versioned =
            serde_json::from_str(text).map_err(|e| StrategyError::Parse(e.to_string()))?;
        if !(1..=STRATEGY_FORMAT_VERSION).contains(&v.format_version) {
            return Err(StrategyError::Version {
                found: v.format_version,
                expected: STRATEGY_FORMAT_VERSION,
            });
        }
        check_seal(text)?;
        let s: Self = match v.format_version {
            STRATEGY_FORMAT_VERSION => {
                serde_json::from_str(text).map_err(|e| StrategyError::Parse(e.to_string()))?
            }
            1 => format::from_version_1(text)?,
            found => {
                return Err(StrategyError::Version {
                    found,
                    expected: STRATEGY_FORMAT_VERSION,
                });
            }
        };
        s.check_consistent()?;
        Ok(s)
    }

    /// The sealed text of a strategy file: pretty JSON whose last key,
    /// `content_sha256`, hashes the text without it.
    pub fn to_json(&self) -> String {
        let body = serde_json::to_string_pretty(self).unwrap_or_default();
        let hash = sha256_hex(body.as_bytes());
        match body.strip_suffix("\n}") {
            Some(head) => format!("{head},\n  \"{SEAL_KEY}\": \"{hash}\"\n}}"),
            None => body,
        }
    }

    fn check_consistent(&self) -> Result<(), StrategyError> {
        if self.deltas.is_empty() || self.deltas.iter().any(|d| !(d.is_finite() && *d >= 0.0)) {
            return Err(StrategyError::Invalid(
                "deltas must be non-empty, finite and ≥ 0".into(),
            ));
        }
        if let Some(i) = self
            .leg_energy
            .iter()
            .flatten()
            .position(|e| !(e.is_finite() && *e >= 0.0))
        {
            return Err(StrategyError::Invalid(format!(
                "leg_energy[{i}] must be finite and ≥ 0"
            )));
        }
        if !self.splits.is_empty() {
            let d = self.discretization.as_ref().ok_or_else(|| {
                StrategyError::Invalid("`splits` without a discretization".into())
            })?;
            check_splits(&self.splits, d).map_err(StrategyError::Invalid)?;
        }
        for (i, st) in self.states.iter().enumerate() {
            if st.omega.len() != self.deltas.len() {
                return Err(StrategyError::Invalid(format!(
                    "states[{i}].omega has {} entries for {} thresholds",
                    st.omega.len(),
                    self.deltas.len()
                )));
            }
            let sum: f64 = st.omega.iter().sum();
            if st.omega.iter().any(|p| !(p.is_finite() && *p >= 0.0)) || (sum - 1.0).abs() > 1e-6 {
                return Err(StrategyError::Invalid(format!(
                    "states[{i}].omega is not a probability distribution (sum {sum})"
                )));
            }
            if let Some(d) = &self.discretization
                && st.decision_point >= d.decision_points.len()
            {
                return Err(StrategyError::Invalid(format!(
                    "states[{i}].decision_point {} beyond the discretization's {} decision points",
                    st.decision_point,
                    d.decision_points.len()
                )));
            }
        }
        Ok(())
    }

    /// Refuse a strategy made for another scenario.
    pub fn check_scenario(&self, scenario: &Scenario) -> Result<(), StrategyError> {
        if self.scenario_hash != scenario.content_hash {
            return Err(StrategyError::ScenarioMismatch {
                strategy_name: self.scenario_name.clone(),
                strategy_hash: self.scenario_hash.clone(),
                scenario_name: scenario.name.clone(),
                scenario_hash: scenario.content_hash.clone(),
            });
        }
        // Bit-for-bit: Δ are the MDP's actions; a strategy naming any other
        // threshold (an edited file) would run thresholds nothing predicted.
        if self.deltas.len() != scenario.deltas.len()
            || self
                .deltas
                .iter()
                .zip(&scenario.deltas)
                .any(|(a, b)| a.to_bits() != b.to_bits())
        {
            return Err(StrategyError::Invalid(format!(
                "its `deltas` {:?} are not the scenario's Δ {:?}",
                self.deltas, scenario.deltas
            )));
        }
        if let Some(d) = &self.discretization
            && d.decision_points.len() != scenario.num_legs()
        {
            return Err(StrategyError::Invalid(format!(
                "its discretization has {} decision points but the scenario has {} legs",
                d.decision_points.len(),
                scenario.num_legs()
            )));
        }
        if let Some(max) = self.states.iter().map(|s| s.decision_point).max()
            && max >= scenario.num_legs()
        {
            return Err(StrategyError::Invalid(format!(
                "decision point {max} but the scenario has {} legs",
                scenario.num_legs()
            )));
        }
        Ok(())
    }

    /// The region of a covariance at decision point `dp`, refined by the
    /// strategy's splits (empty when region-free).
    pub fn region(&self, dp: usize, cov: &DMatrix<f64>) -> Region {
        match &self.discretization {
            Some(d) => d.classify_split(dp, cov, &self.splits),
            None => Region(Vec::new()),
        }
    }

    /// ω for a belief at decision point `dp`: the state with the belief's region;
    /// for a region never seen in synthesis, the nearest region at `dp` (L1
    /// distance in bins, first in file order on ties); with no state at `dp`
    /// at all, the full Kalman filter (smallest δ) — the safe choice.
    pub fn omega(&self, dp: usize, cov: &DMatrix<f64>) -> OmegaChoice<'_> {
        self.omega_of_region(dp, &self.region(dp, cov))
    }

    /// ω of a region at decision point `dp` (of this strategy's bins and
    /// splits), looked up as [`Self::omega`] does.
    pub fn omega_of_region(&self, dp: usize, region: &Region) -> OmegaChoice<'_> {
        let mut best: Option<(u64, &StrategyState)> = None;
        for st in self.states.iter().filter(|s| s.decision_point == dp) {
            let d = region_distance(&st.region, region);
            if d == 0 {
                return OmegaChoice::Exact(&st.omega);
            }
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, st));
            }
        }
        match best {
            Some((_, st)) => OmegaChoice::Nearest(&st.omega),
            None => OmegaChoice::FullKf(self.smallest_delta_index()),
        }
    }

    /// Draw a threshold index for a belief, with `u` uniform on [0, 1).
    pub fn draw(&self, dp: usize, cov: &DMatrix<f64>, u: f64) -> usize {
        match self.omega(dp, cov) {
            OmegaChoice::Exact(w) | OmegaChoice::Nearest(w) => sample_index(w, u),
            OmegaChoice::FullKf(i) => i,
        }
    }

    fn smallest_delta_index(&self) -> usize {
        self.deltas
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map_or(0, |(i, _)| i)
    }
}

/// Where ω came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OmegaChoice<'a> {
    Exact(&'a [f64]),
    Nearest(&'a [f64]),
    FullKf(usize),
}

/// L1 distance in bins between two regions of one decision point. Split
/// entries (`SPLIT_MARK`) count by their side, plus one per entry only one of
/// them has; regions with different base lengths are far apart.
fn region_distance(a: &Region, b: &Region) -> u64 {
    let base = |r: &Region| r.0.iter().take_while(|e| e.0 != SPLIT_MARK).count();
    let (ka, kb) = (base(a), base(b));
    if ka != kb {
        return u64::MAX / 2;
    }
    let common: u64 =
        a.0.iter()
            .zip(&b.0)
            .map(|(x, y)| u64::from(x.0.abs_diff(y.0)) + u64::from(x.1.abs_diff(y.1)))
            .sum();
    common + a.0.len().abs_diff(b.0.len()) as u64
}

/// Inverse-CDF draw from a distribution with `u ∈ [0, 1)`.
pub fn sample_index(weights: &[f64], u: f64) -> usize {
    let mut acc = 0.0;
    let mut last = 0;
    for (i, &w) in weights.iter().enumerate() {
        if w <= 0.0 {
            continue;
        }
        acc += w;
        last = i;
        if u < acc {
            return i;
        }
    }
    last
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prediction() -> Prediction {
        Prediction {
            p_target: 0.9,
            p_collision: 0.1,
            p_free: 0.0,
            energy_mean: 10.0,
        }
    }

    #[test]
    fn constant_strategy_round_trips_and_checks_the_scenario() {
        let s = Scenario::builtin("winding-2d").expect("built-in");
        let st = Strategy::constant(&s, 2, Some(prediction()));
        let back = Strategy::from_json(&st.to_json()).expect("round trip");
        assert_eq!(back, st);
        back.check_scenario(&s).expect("same scenario");
        assert_eq!(
            back.scenario().expect("built-in by name").content_hash,
            s.content_hash
        );
        let mut tampered = back.clone();
        tampered.scenario_toml = Some(
            crate::scenario::builtin_text("winding-2d")
                .expect("built-in")
                .replace("k_max = 200", "k_max = 201"),
        );
        assert!(matches!(
            tampered.scenario(),
            Err(StrategyError::ScenarioMismatch { .. })
        ));
        let other = Scenario::builtin("open-2d").expect("built-in");
        assert!(matches!(
            back.check_scenario(&other),
            Err(StrategyError::ScenarioMismatch { .. })
        ));
        let cov = DMatrix::identity(2, 2);
        assert_eq!(back.draw(3, &cov, 0.7), 2);
        // One δ edited (still a consistent file on its own): refused, naming the field.
        let mut bent = back.clone();
        bent.deltas[2] = 3.5;
        let bent = Strategy::from_json(&bent.to_json()).expect("consistent on its own");
        let e = bent.check_scenario(&s).expect_err("δ not in Δ").to_string();
        assert!(e.contains("`deltas`") && e.contains("3.5"), "{e}");
        let mut fewer = back.clone();
        fewer.deltas.pop();
        for st in &mut fewer.states {
            st.omega.pop();
        }
        assert!(matches!(
            fewer.check_scenario(&s),
            Err(StrategyError::Invalid(_))
        ));
    }

    #[test]
    fn corrupted_strategies_are_refused() {
        let s = Scenario::builtin("winding-2d").expect("built-in");
        let text = Strategy::constant(&s, 0, Some(prediction())).to_json();
        assert!(matches!(
            Strategy::from_json(&text[..text.len() / 2]),
            Err(StrategyError::Parse(_))
        ));
        let bad = text.replacen("\"format_version\": 2", "\"format_version\": 99", 1);
        assert!(matches!(
            Strategy::from_json(&bad),
            Err(StrategyError::Version { .. })
        ));
        let mut broken = Strategy::constant(&s, 0, Some(prediction()));
        broken.states[4].omega[0] = 0.5;
        let bad = broken.to_json();
        assert!(matches!(
            Strategy::from_json(&bad),
            Err(StrategyError::Invalid(_))
        ));
    }

    #[test]
    fn the_whole_file_is_covered_by_its_hash() {
        let s = Scenario::builtin("winding-2d").expect("built-in");
        let mut st = Strategy::constant(&s, 1, Some(prediction()));
        st.leg_energy = Some(vec![1.5; s.legs.len()]);
        let text = st.to_json();
        assert!(text.trim_end().ends_with('}'));
        assert_eq!(Strategy::from_sealed_json(&text).expect("sealed"), st);
        // A trailing newline (an editor's) is not an edit.
        Strategy::from_sealed_json(&format!("{text}\n")).expect("trailing newline");
        // Every field is covered, those no other check looks at included.
        for (from, to) in [
            (
                "\"scenario_name\": \"winding-2d\"",
                "\"scenario_name\": \"winding-3d\"",
            ),
            ("\"p_target\": 0.9", "\"p_target\": 0.5"),
            ("\"energy_mean\": 10.0", "\"energy_mean\": 1.0"),
            ("1.5,", "0.5,"),
            ("\"label\": \"constant", "\"label\": \"Constant"),
            (
                "{\n  \"format_version\"",
                "{\n  \"extra\": 1,\n  \"format_version\"",
            ),
        ] {
            assert!(text.contains(from), "{from}");
            let edited = text.replacen(from, to, 1);
            for e in [
                Strategy::from_sealed_json(&edited),
                Strategy::from_json(&edited),
            ] {
                let e = e.expect_err(from).to_string();
                assert!(
                    e.contains("changed after it was written") && e.contains("etp strategy"),
                    "{e}"
                );
            }
        }
        // Reformatted (the seal no longer the last key as written): refused.
        let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        let compact = serde_json::to_string(&v).expect("JSON");
        assert!(matches!(
            Strategy::from_sealed_json(&compact),
            Err(StrategyError::Tampered(_))
        ));
        // A file written before the seal: refused as a strategy file, saying
        // what to do; accepted where recordings are read.
        let old = serde_json::to_string_pretty(&st).expect("JSON");
        let e = Strategy::from_sealed_json(&old).expect_err("unsealed");
        assert!(matches!(e, StrategyError::Unsealed));
        assert!(e.to_string().contains("etp strategy"), "{e}");
        assert_eq!(Strategy::from_json(&old).expect("recorded, unsealed"), st);
        assert!(matches!(
            Strategy::from_sealed_json("{ not json"),
            Err(StrategyError::Parse(_))
        ));
    }

    #[test]
    fn a_version_1_file_reads_with_its_values_under_diagnostics() {
        let s = Scenario::builtin("winding-2d").expect("built-in");
        let st = Strategy::constant(&s, 1, Some(prediction()));
        let mut v: serde_json::Value = serde_json::from_str(&st.to_json()).expect("JSON");
        let m = v.as_object_mut().expect("object");
        m.remove("content_sha256");
        m.remove("predicted_ci95");
        m.remove("prediction_basis");
        m.insert("format_version".into(), 1.into());
        let cf = serde_json::json!({"p_target": 0.8, "p_collision": 0.15, "p_free": 0.05, "energy_mean": 11.0});
        m.insert("crossfit".into(), cf);
        let old = serde_json::to_string_pretty(&v).expect("JSON");
        let back = Strategy::from_json(&old).expect("version 1");
        assert_eq!(back.format_version, STRATEGY_FORMAT_VERSION);
        assert_eq!(back.predicted, Some(prediction()));
        assert_eq!(back.prediction_basis, format::VERSION_1_BASIS);
        let d = back.diagnostics.expect("diagnostics");
        assert_eq!(d.selection.selection_time, Some(prediction()));
        assert_eq!(d.selection.crossfit.map(|c| c.p_target), Some(0.8));
        // Written again, it is a version 2 file that reads as itself.
        let again = Strategy::from_sealed_json(&back_json(&old)).expect("v2");
        assert_eq!(again.format_version, 2);
    }

    fn back_json(old: &str) -> String {
        Strategy::from_json(old).expect("v1").to_json()
    }

    #[test]
    fn sampling_follows_the_cdf() {
        let w = [0.0, 0.25, 0.0, 0.75];
        assert_eq!(sample_index(&w, 0.0), 1);
        assert_eq!(sample_index(&w, 0.2499), 1);
        assert_eq!(sample_index(&w, 0.25), 3);
        assert_eq!(sample_index(&w, 0.999_999), 3);
    }
}
