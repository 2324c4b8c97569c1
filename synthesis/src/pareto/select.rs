//! The vertex-mixture explanation of a requested trade-off: an LP over convex
//! weights μ of the front's vertices, realised as a memoryless randomised
//! strategy through occupation measures (docs/MODEL.md §5). The exact optimum, which
//! `etp strategy` writes, is [`super::optimal`]; the two differ by at most the
//! front's certified gap.

use super::ParetoFront;
use super::policy::{Objectives, RandomisedPolicy, as_randomised, mixed_occupation};
use crate::mdp::Mdp;
use good_lp::{Expression, Solution, SolverModel, constraint, microlp, variable, variables};

/// What the user asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// Least energy with `P_tar ≥ min_target` (and `P_coll ≤ max_collision`).
    MinTarget {
        min_target: f64,
        max_collision: Option<f64>,
    },
    /// Highest `P_tar` with `E ≤ max_energy` (ties: least collision).
    MaxEnergy { max_energy: f64 },
    /// Exactly vertex `k` of the front.
    Vertex(usize),
}

/// Why a request cannot be met.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SelectError {
    #[error(
        "infeasible: {request}; best achievable on this abstraction: P_tar ≤ {best_target:.4}, P_coll ≥ {best_collision:.4}, energy ≥ {best_energy:.2}{detail}"
    )]
    Infeasible {
        request: String,
        best_target: f64,
        best_collision: f64,
        best_energy: f64,
        detail: String,
    },
    #[error("vertex {0} does not exist (the front has {1} vertices)")]
    NoSuchVertex(usize, usize),
    #[error("LP solver failed: {0}")]
    Solver(String),
}

/// A mixture of vertices and what it achieves.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// (vertex index, μ) with μ > 0.
    pub weights: Vec<(usize, f64)>,
    pub predicted: Objectives,
}

/// Solve the vertex LP for a request.
pub fn select(front: &ParetoFront, request: Request) -> Result<Selection, SelectError> {
    let v = &front.vertices;
    if let Request::Vertex(k) = request {
        let vx = v.get(k).ok_or(SelectError::NoSuchVertex(k, v.len()))?;
        return Ok(Selection {
            weights: vec![(k, 1.0)],
            predicted: vx.objectives,
        });
    }
    let mut vars = variables!();
    let mu: Vec<_> = v
        .iter()
        .map(|_| vars.add(variable().min(0.0).max(1.0)))
        .collect();
    let sum = |f: &dyn Fn(&Objectives) -> f64| -> Expression {
        mu.iter().zip(v).map(|(m, x)| f(&x.objectives) * *m).sum()
    };
    let total: Expression = mu.iter().copied().sum();
    let e = sum(&|o| o.energy);
    let pt = sum(&|o| o.p_target);
    let pc = sum(&|o| o.p_collision);
    // Secondary terms keep the optimum Pareto-optimal when the primary ties.
    let eps_scale = 1e-7;
    let (objective, constraints, describe): (Expression, Vec<good_lp::Constraint>, String) =
        match request {
            Request::MinTarget {
                min_target,
                max_collision,
            } => {
                let mut c = vec![constraint!(pt.clone() >= min_target)];
                let mut d = format!("P_tar ≥ {min_target}");
                if let Some(mc) = max_collision {
                    c.push(constraint!(pc.clone() <= mc));
                    d.push_str(&format!(" and P_coll ≤ {mc}"));
                }
                let scale = front.energy_scale.max(1e-12);
                (
                    e.clone() / scale + eps_scale * (pc.clone() - pt.clone()),
                    c,
                    d,
                )
            }
            Request::MaxEnergy { max_energy } => (
                -pt.clone() + eps_scale * pc.clone(),
                vec![constraint!(e.clone() <= max_energy)],
                format!("energy ≤ {max_energy}"),
            ),
            Request::Vertex(_) => unreachable!("handled above"),
        };
    let mut problem = vars
        .minimise(objective)
        .using(microlp)
        .with(constraint!(total == 1.0));
    for c in constraints {
        problem = problem.with(c);
    }
    match problem.solve() {
        Ok(sol) => {
            let weights: Vec<(usize, f64)> = mu
                .iter()
                .enumerate()
                .map(|(k, m)| (k, sol.value(*m)))
                .filter(|(_, w)| *w > 1e-12)
                .collect();
            let norm: f64 = weights.iter().map(|(_, w)| w).sum();
            let weights: Vec<(usize, f64)> =
                weights.into_iter().map(|(k, w)| (k, w / norm)).collect();
            let predicted = Objectives::mix(weights.iter().map(|&(k, w)| (w, v[k].objectives)));
            Ok(Selection { weights, predicted })
        }
        Err(good_lp::ResolutionError::Infeasible) => {
            let best_target = v.iter().map(|x| x.objectives.p_target).fold(0.0, f64::max);
            let best_collision = v
                .iter()
                .map(|x| x.objectives.p_collision)
                .fold(1.0, f64::min);
            let best_energy = v
                .iter()
                .map(|x| x.objectives.energy)
                .fold(f64::INFINITY, f64::min);
            let detail = match request {
                Request::MinTarget {
                    min_target,
                    max_collision: Some(_),
                } if min_target <= best_target => {
                    // Least collision compatible with the target constraint.
                    let c = least_collision_with_target(front, min_target).unwrap_or(f64::NAN);
                    format!("; with P_tar ≥ {min_target} the least P_coll is {c:.4}")
                }
                _ => String::new(),
            };
            Err(SelectError::Infeasible {
                request: describe,
                best_target,
                best_collision,
                best_energy,
                detail,
            })
        }
        Err(e) => Err(SelectError::Solver(e.to_string())),
    }
}

pub fn least_collision_with_target(front: &ParetoFront, min_target: f64) -> Option<f64> {
    let v = &front.vertices;
    let mut vars = variables!();
    let mu: Vec<_> = v.iter().map(|_| vars.add(variable().min(0.0))).collect();
    let pt: Expression = mu
        .iter()
        .zip(v)
        .map(|(m, x)| x.objectives.p_target * *m)
        .sum();
    let pc: Expression = mu
        .iter()
        .zip(v)
        .map(|(m, x)| x.objectives.p_collision * *m)
        .sum();
    let total: Expression = mu.iter().copied().sum();
    let sol = vars
        .minimise(pc.clone())
        .using(microlp)
        .with(constraint!(total == 1.0))
        .with(constraint!(pt >= min_target))
        .solve()
        .ok()?;
    Some(sol.eval(pc))
}

/// The memoryless randomised policy realising a vertex mixture:
/// `x(s,c) = Σ μ_k x_k(s,c)`, `ω(s)(c) = x(s,c) / Σ_c' x(s,c')`. States no
/// mixture reaches take the policy of the heaviest vertex.
pub fn realise(mdp: &Mdp, front: &ParetoFront, selection: &Selection) -> RandomisedPolicy {
    let n = mdp.states.len();
    let x = mixed_occupation(
        mdp,
        selection
            .weights
            .iter()
            .map(|&(k, w)| (w, &front.vertices[k].policy)),
    );
    let heaviest = selection
        .weights
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0, |&(k, _)| k);
    let fallback = as_randomised(mdp, &front.vertices[heaviest].policy);
    (0..n)
        .map(|s| {
            let total: f64 = x[s].iter().sum();
            if total > 0.0 {
                x[s].iter().map(|v| v / total).collect()
            } else {
                fallback[s].clone()
            }
        })
        .collect()
}
