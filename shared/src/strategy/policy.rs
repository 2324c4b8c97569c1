//! The policy of a strategy: what running it needs (the coordinator, the
//! in-process validator, `etp run`) — which scenario it is for, the
//! thresholds Δ, the covariance regions and ω per abstract state.

use super::{StrategyError, StrategyState};
use crate::discretization::{Discretization, Region, RegionSplit, SPLIT_MARK, check_splits};
use crate::radio::{Radio, RadioOverride};
use crate::scenario::Scenario;
use nalgebra::DMatrix;

/// A memoryless randomised threshold policy: at decision point i, the
/// belief's covariance region s selects ω(s) over the thresholds Δ.
#[derive(Debug, Clone, PartialEq)]
pub struct Policy {
    /// The scenario it was made for, by name and content hash: a policy is
    /// never applied to another scenario ([`Policy::check_scenario`]).
    pub scenario_name: String,
    pub scenario_hash: String,
    /// The actions Δ.
    pub deltas: Vec<f64>,
    /// Regions of covariances; `None` for a region-free policy (ω depends on
    /// the decision point only, e.g. a constant δ). Carried so the
    /// coordinator and the in-process validator classify beliefs identically.
    pub discretization: Option<Discretization>,
    pub states: Vec<StrategyState>,
    /// The scenario's TOML text, so a strategy file is self-contained
    /// (`etp validate` / `etp run` need nothing else). Optional: without it the
    /// scenario is looked up among the built-ins by name and hash.
    pub scenario_toml: Option<String>,
    /// The radio the strategy was synthesized for (docs/MODEL.md §8) when it
    /// is not its scenario text's own `[radio]` (`etp synthesize --loss …`);
    /// absent = the scenario's own. [`Policy::scenario`] applies it, so a
    /// strategy is evaluated under its own channel unless told otherwise.
    pub radio: Option<Radio>,
    /// Regions split by `etp synthesize --split-budget` (docs/MODEL.md §7.3):
    /// the belief's region is refined by them before ω is looked up. Empty in
    /// older files and without splitting, which classify as before.
    pub splits: Vec<RegionSplit>,
}

impl Policy {
    /// The same δ on every leg (region-free).
    pub fn constant(scenario: &Scenario, delta_index: usize) -> Self {
        let mut omega = vec![0.0; scenario.deltas.len()];
        omega[delta_index] = 1.0;
        Self {
            scenario_name: scenario.name.clone(),
            scenario_hash: scenario.content_hash.clone(),
            deltas: scenario.deltas.clone(),
            discretization: None,
            states: (0..scenario.num_legs())
                .map(|i| StrategyState {
                    decision_point: i,
                    region: Region(Vec::new()),
                    omega: omega.clone(),
                })
                .collect(),
            scenario_toml: None,
            radio: None,
            splits: Vec::new(),
        }
    }

    /// The scenario this policy was made for: the embedded text, else the
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

    /// `scenario` (this policy's, hash checked) under the radio the
    /// strategy was synthesized for: steps 1–2 of the one override rule
    /// ([`Radio::for_use`], docs/MODEL.md §8.6) — [`Policy::radio`] when
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

    /// Δ, ω and the splits are consistent on their own (a scenario is
    /// checked by [`Policy::check_scenario`]).
    pub(super) fn check_consistent(&self) -> Result<(), StrategyError> {
        if self.deltas.is_empty() || self.deltas.iter().any(|d| !(d.is_finite() && *d >= 0.0)) {
            return Err(StrategyError::Invalid(
                "deltas must be non-empty, finite and ≥ 0".into(),
            ));
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

    /// Refuse a policy made for another scenario.
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
    /// policy's splits (empty when region-free).
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

    /// ω of a region at decision point `dp` (of this policy's bins and
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
