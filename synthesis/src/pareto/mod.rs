//! The Pareto front of (expected energy, P_coll, 1 − P_tar) over randomised
//! strategies on the acyclic MDP, strategies for requested trade-offs, and the
//! `front.json` file (docs/MODEL.md §5).
//!
//! * [`policy`] — weighted backward induction (with the exact optimum as a
//!   bound), evaluation of any memoryless randomised policy, occupation measures.
//! * [`enumerate`] — the front by supporting hyperplanes, with a certified gap ε.
//! * [`optimal`] — the exact strategy of a request: the whole-MDP occupation
//!   LP realised as ω.
//! * [`select`] — the vertex-mixture LP (the human-readable explanation).
//! * [`PredictedFront`] — the predicted front's data in `front.json`
//!   (computed by `predict::front`).
//! * [`CertifiedFront`] — the certified front's data in `front.json`
//!   (computed by `certify::front`; kept here so `pareto` imports nothing of
//!   `certify`).

mod certified;
pub mod enumerate;
pub mod optimal;
pub mod policy;
mod predicted;
pub mod select;

pub use certified::{CertifiedFront, CertifiedPoint};
pub use predicted::{PredictedFront, PredictedPoint};

use crate::mdp::{CostModel, Mdp, Method};
use etp_shared::strategy::{
    Diagnostics, Policy, Predictions, Provenance, STRATEGY_FORMAT_VERSION, SelectionValues,
    Strategy, StrategyState,
};
use policy::{
    DeterministicPolicy, Objectives, RandomisedPolicy, as_randomised, constant_action, evaluate,
};
use serde::{Deserialize, Serialize};

/// Version of the `front.json` layout (2: certified `epsilon`, deterministic;
/// 3: the certified front `certified` beside the nominal vertices).
pub const FRONT_FORMAT_VERSION: u32 = 3;

/// A vertex of the front: a deterministic policy optimal for some weight λ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Vertex {
    pub objectives: Objectives,
    /// A weight vector (on energy/scale, P_coll, 1 − P_tar) it is optimal for.
    pub lambda: [f64; 3],
    /// Chosen choice per MDP state (index into `State::choices`).
    pub policy: DeterministicPolicy,
}

/// A bounded facet of the (lifted, triangulated) lower hull: its vertices and
/// weight vector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Facet {
    pub vertices: Vec<usize>,
    pub lambda: [f64; 3],
}

/// A reference strategy evaluated on the same MDP.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Baseline {
    pub label: String,
    /// δ of a constant strategy.
    pub delta: Option<f64>,
    pub objectives: Objectives,
}

/// The front of one MDP (`front.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParetoFront {
    pub format_version: u32,
    pub scenario_name: String,
    pub scenario_hash: String,
    pub method: Method,
    pub cost_model: CostModel,
    /// Energy normalisation: the full-KF (δ = 0) energy on this MDP.
    pub energy_scale: f64,
    /// Certified gap in scaled units (energy / `energy_scale`, probabilities):
    /// every strategy's objective vector, raised by `epsilon` in each
    /// coordinate, is dominated by a mixture of `vertices` (docs/MODEL.md §5).
    /// The front is exact up to this ε, not exact.
    pub epsilon: f64,
    /// `epsilon · energy_scale`: the certified gap in energy units.
    pub epsilon_energy: f64,
    /// Stopping tolerance of the enumeration (scaled units).
    pub tolerance: f64,
    /// Corners of the lower hull, sorted by increasing energy.
    pub vertices: Vec<Vertex>,
    pub facets: Vec<Facet>,
    /// Each constant δ (the smallest δ is the full KF when δ = 0 is in Δ).
    pub baselines: Vec<Baseline>,
    /// Method 1's front, when both methods were built.
    pub kf_convergence: Option<Box<ParetoFront>>,
    /// The nominal vertices with their certified bounds and cross-fitted
    /// values (docs/MODEL.md §4.1); `None` for the Method 1 baseline.
    pub certified: Option<CertifiedFront>,
    /// Weighted optimisations and hull rounds of the enumeration.
    pub optimisations: usize,
    pub rounds: usize,
    pub mdp_states: usize,
    pub mdp_transitions: usize,
    /// The radio the MDP's segments were sampled under when it is not the
    /// scenario text's own `[radio]` (`etp synthesize --loss …`, docs/MODEL.md
    /// §8); strategies made from this front carry it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radio: Option<etp_shared::radio::Radio>,
    /// The predicted front (docs/MODEL.md §7.5): one curve per P_coll bound
    /// asked, each point the strategy `etp strategy` returns for its request
    /// with the prediction it stands by. Absent until computed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub predicted: Vec<PredictedFront>,
}

impl ParetoFront {
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Parse `front.json`.
    pub fn from_json(text: &str) -> Result<Self, String> {
        // The version first, so an older file says so rather than naming a field.
        #[derive(Deserialize)]
        struct Version {
            format_version: u32,
        }
        let v: Version = serde_json::from_str(text).map_err(|e| e.to_string())?;
        if v.format_version != FRONT_FORMAT_VERSION {
            return Err(format!(
                "front format version {} is not supported (expected {FRONT_FORMAT_VERSION}; run `etp synthesize` again)",
                v.format_version
            ));
        }
        serde_json::from_str(text).map_err(|e| e.to_string())
    }

    /// Index of the vertex with the highest P_tar (least energy among ties).
    pub fn max_target_vertex(&self) -> Option<usize> {
        (0..self.vertices.len()).max_by(|&a, &b| {
            let (x, y) = (&self.vertices[a].objectives, &self.vertices[b].objectives);
            x.p_target
                .total_cmp(&y.p_target)
                .then(y.energy.total_cmp(&x.energy))
        })
    }
}

/// Compute the front of an MDP with its baselines.
pub fn compute_front(
    mdp: &Mdp,
    cost: CostModel,
) -> Result<ParetoFront, enumerate::EnumerationError> {
    compute_front_to(mdp, cost, enumerate::TOLERANCE)
}

/// [`compute_front`] with another stopping tolerance of the enumeration
/// (coarser: fewer vertices, faster, a larger certified ε).
pub fn compute_front_to(
    mdp: &Mdp,
    cost: CostModel,
    tolerance: f64,
) -> Result<ParetoFront, enumerate::EnumerationError> {
    let mut baselines = Vec::new();
    for (a, &delta) in mdp.deltas.iter().enumerate() {
        if let Some(p) = constant_action(mdp, a as u16) {
            baselines.push(Baseline {
                label: if delta == 0.0 {
                    "full KF (δ = 0)".into()
                } else {
                    format!("constant δ = {delta}")
                },
                delta: Some(delta),
                objectives: evaluate(mdp, &as_randomised(mdp, &p), cost),
            });
        }
    }
    let full_kf = baselines
        .iter()
        .filter(|b| b.delta.is_some())
        .min_by(|a, b| {
            a.delta
                .unwrap_or(f64::MAX)
                .total_cmp(&b.delta.unwrap_or(f64::MAX))
        })
        .map(|b| b.objectives.energy);
    let scale = full_kf.filter(|e| *e > 0.0).unwrap_or(1.0);
    let en = enumerate::enumerate_front_to(mdp, scale, cost, tolerance)?;
    let mut order: Vec<usize> = en.vertices.clone();
    order.sort_by(|&a, &b| {
        let (x, y) = (&en.points[a].objectives, &en.points[b].objectives);
        x.energy
            .total_cmp(&y.energy)
            .then(y.p_target.total_cmp(&x.p_target))
    });
    let position = |p: usize| order.iter().position(|&q| q == p);
    let vertices = order
        .iter()
        .map(|&i| Vertex {
            objectives: en.points[i].objectives,
            lambda: en.points[i].lambda,
            policy: en.points[i].policy.clone(),
        })
        .collect();
    let facets = en
        .facets
        .iter()
        .filter_map(|f| {
            Some(Facet {
                vertices: f
                    .points
                    .iter()
                    .map(|&p| position(p))
                    .collect::<Option<Vec<_>>>()?,
                lambda: f.lambda,
            })
        })
        .collect();
    Ok(ParetoFront {
        format_version: FRONT_FORMAT_VERSION,
        scenario_name: mdp.scenario_name.clone(),
        scenario_hash: mdp.scenario_hash.clone(),
        method: mdp.method,
        cost_model: cost,
        energy_scale: scale,
        epsilon: en.epsilon,
        epsilon_energy: en.epsilon * scale,
        tolerance,
        vertices,
        facets,
        baselines,
        kf_convergence: None,
        certified: None,
        optimisations: en.optimisations,
        rounds: en.rounds,
        mdp_states: mdp.states.len(),
        mdp_transitions: mdp.num_transitions(),
        radio: None,
        predicted: Vec::new(),
    })
}

/// Package a randomised policy over MDP choices as a `strategy.json`
/// (ω over Δ per abstract state).
pub fn to_strategy(
    mdp: &Mdp,
    policy: &RandomisedPolicy,
    label: String,
    predicted: Objectives,
) -> Strategy {
    // A lumped state (`--merge`) is one row per region, all with its ω.
    let states = mdp
        .states
        .iter()
        .zip(policy)
        .flat_map(|(s, w)| {
            let mut omega = vec![0.0; mdp.deltas.len()];
            for (c, p) in s.choices.iter().zip(w) {
                omega[c.action as usize] += p;
            }
            let sum: f64 = omega.iter().sum();
            if sum > 0.0 {
                omega.iter_mut().for_each(|p| *p /= sum);
            }
            std::iter::once(&s.region)
                .chain(&s.merged)
                .map(move |region| StrategyState {
                    decision_point: s.decision_point as usize,
                    region: region.clone(),
                    omega: omega.clone(),
                })
        })
        .collect();
    Strategy {
        provenance: Provenance {
            format_version: STRATEGY_FORMAT_VERSION,
            label,
        },
        policy: Policy {
            scenario_name: mdp.scenario_name.clone(),
            scenario_hash: mdp.scenario_hash.clone(),
            deltas: mdp.deltas.clone(),
            discretization: mdp.discretization.clone(),
            states,
            scenario_toml: None,
            radio: None,
            splits: mdp.splits.clone(),
        },
        // Its value on this MDP is a diagnostic: the prediction etp stands
        // by comes from the strategy's own rebuilds (`crate::predict`).
        predictions: Predictions {
            leg_energy: Some(policy::leg_energy(mdp, policy, CostModel::Counted)),
            diagnostics: Some(Diagnostics {
                selection: SelectionValues {
                    selection_time: Some(predicted.prediction()),
                    ..SelectionValues::default()
                },
                ..Diagnostics::default()
            }),
            ..Predictions::default()
        },
    }
}

#[cfg(test)]
mod tests;
