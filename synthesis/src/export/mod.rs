//! The MDP for other model checkers, in three formats that share one
//! numbering, one labelling, one reward and one set of queries:
//! * [`prism`] — PRISM's explicit files (`prism -importmodel model.all -mdp`);
//! * [`jani`] — the JANI interchange format of QComp, properties included
//!   (Storm: `storm --jani model.jani --janiproperty`, or stormpy);
//! * [`drn`] — Storm's explicit DRN format (`storm --explicit-drn model.drn`).
//!
//! Numbering: the MDP's states keep their indices `0..S`; the absorbing
//! terminals follow: `coll = S`, `tar = S + 1`, `free = S + 2`, each with one
//! self-loop choice labelled `done`. Choices keep their order within a state
//! and are labelled `d<k>` for threshold `deltas[k]`. Labels: `init` (the
//! initial state), `coll`, `tar`, `free` (the terminals). The energy reward is
//! named `energy`: the choice's cost, earned once per choice taken, so the
//! total expected reward (`R{"energy"}min=? [ C ]`) is a strategy's expected
//! energy.
//!
//! [`queries`] reads the queries off the front: thresholds the front shows to
//! be feasible with etp's exact answer to each (so a model checker's run can
//! be compared line by line), one query infeasible on purpose, the
//! single-objective extremes and the Pareto curve.

pub mod drn;
pub mod jani;
pub mod prism;

use crate::mdp::{CostModel, Mdp, Next};
use crate::pareto::ParetoFront;
use crate::pareto::optimal::{LpRequest, optimal_strategy};
use crate::pareto::policy::weighted_optimum;
use crate::pareto::select::{Request, least_collision_with_target, select};

/// Names of the three terminal labels, in the order of their indices.
pub const TERMINAL_LABELS: [&str; 3] = ["coll", "tar", "free"];

/// Index of a transition target in the exported numbering.
pub fn target_index(mdp: &Mdp, next: Next) -> usize {
    let s = mdp.states.len();
    match next {
        Next::State(j) => j as usize,
        Next::Collision => s,
        Next::Target => s + 1,
        Next::Free => s + 2,
    }
}

/// What one query asks, in the terms every format can say.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Formula {
    /// The least expected energy under `P(F tar) >= min_target` and/or
    /// `P(F coll) <= max_collision`: `multi(R{"energy"}min=? [ C ], …)`.
    LeastEnergy {
        min_target: Option<f64>,
        max_collision: Option<f64>,
    },
    /// `Pmax=? [ F "tar" ]`.
    MaxTarget,
    /// `Pmin=? [ F "coll" ]`.
    MinCollision,
    /// The Pareto curve `multi(R{"energy"}min=? [ C ], Pmax=? [ F "tar" ])`.
    ParetoTarget,
}

/// One query of the exported properties.
#[derive(Debug, Clone, PartialEq)]
pub struct Query {
    /// A name (JANI's property name): letters, digits and `_`.
    pub name: &'static str,
    /// What it asks, in words.
    pub comment: String,
    pub formula: Formula,
    /// etp's exact answer (or why there is none), for comparison.
    pub etp: Option<String>,
}

/// `floor(x · 1000) / 1000`.
fn floor3(x: f64) -> f64 {
    (x * 1000.0).floor() / 1000.0
}

/// The smallest multiple of 0.001 strictly above `x`.
fn above3(x: f64) -> f64 {
    let mut k = (x * 1000.0).floor();
    while k / 1000.0 <= x {
        k += 1.0;
    }
    k / 1000.0
}

/// The queries for `mdp` from its front: two feasible multi-objective
/// queries with thresholds read off the front (and etp's exact answer to
/// each), one infeasible query marked as such, the single-objective extremes
/// and the Pareto curve of energy against P_tar.
pub fn queries(mdp: &Mdp, front: &ParetoFront, cost: CostModel) -> Vec<Query> {
    let mut out = Vec::new();
    // Exact extremes by backward induction.
    let bound = |lambda| weighted_optimum(mdp, lambda, 1.0, cost).bound;
    let max_target = 1.0 - bound([0.0, 0.0, 1.0]);
    let min_collision = bound([0.0, 1.0, 0.0]);
    let (lo, hi) = front
        .vertices
        .iter()
        .map(|v| v.objectives.p_target)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    let exact = |r: LpRequest| match optimal_strategy(mdp, cost, r) {
        Ok(s) => format!("{:.12}", s.predicted.energy),
        Err(e) => e.to_string(),
    };
    if lo.is_finite() && hi.is_finite() {
        // Three quarters of the way up the front's P_tar range, rounded down
        // (feasible: a vertex reaches `hi`).
        let p = floor3(lo + 0.75 * (hi - lo));
        out.push(Query {
            name: "least_energy_target",
            comment: format!(
                "Least expected energy with P(reach target) >= {p} (feasible: the front reaches P_tar = {hi:.6})"
            ),
            formula: Formula::LeastEnergy {
                min_target: Some(p),
                max_collision: None,
            },
            etp: Some(exact(LpRequest::MinEnergy {
                min_target: p,
                max_collision: None,
            })),
        });
        // A collision bound halfway between the least P_coll compatible with
        // the target (feasible: a mixture of vertices attains it) and the
        // P_coll of the least-energy strategy, rounded up.
        let least = least_collision_with_target(front, p);
        let unconstrained = select(
            front,
            Request::MinTarget {
                min_target: p,
                max_collision: None,
            },
        )
        .ok()
        .map(|s| s.predicted.p_collision);
        if let (Some(least), Some(free)) = (least, unconstrained) {
            let c = above3(least + 0.5 * (free - least).max(0.0)).min(1.0);
            out.push(Query {
                name: "least_energy_target_collision",
                comment: format!(
                    "Least expected energy with P(reach target) >= {p} and P(collide) <= {c} (feasible: the front reaches P_coll = {least:.6} there)"
                ),
                formula: Formula::LeastEnergy {
                    min_target: Some(p),
                    max_collision: Some(c),
                },
                etp: Some(exact(LpRequest::MinEnergy {
                    min_target: p,
                    max_collision: Some(c),
                })),
            });
        }
    }
    let p_inf = above3(max_target);
    if p_inf <= 1.0 {
        out.push(Query {
            name: "infeasible_target",
            comment: format!(
                "INFEASIBLE on purpose: no strategy reaches P(reach target) >= {p_inf} (the highest is {max_target:.6}); PRISM answers NaN or false, Storm false"
            ),
            formula: Formula::LeastEnergy {
                min_target: Some(p_inf),
                max_collision: None,
            },
            etp: None,
        });
    } else if min_collision >= 0.001 {
        let c_inf = floor3(min_collision) - 0.001;
        let c_inf = if c_inf < min_collision {
            c_inf.max(0.0)
        } else {
            0.0
        };
        out.push(Query {
            name: "infeasible_collision",
            comment: format!(
                "INFEASIBLE on purpose: no strategy keeps P(collide) <= {c_inf} (the lowest is {min_collision:.6}); PRISM answers NaN or false, Storm false"
            ),
            formula: Formula::LeastEnergy {
                min_target: None,
                max_collision: Some(c_inf),
            },
            etp: None,
        });
    }
    out.push(Query {
        name: "max_target",
        comment: "Highest probability of reaching the target".into(),
        formula: Formula::MaxTarget,
        etp: Some(format!("{max_target:.12}")),
    });
    out.push(Query {
        name: "min_collision",
        comment: "Lowest probability of colliding".into(),
        formula: Formula::MinCollision,
        etp: Some(format!("{min_collision:.12}")),
    });
    out.push(Query {
        name: "pareto_energy_target",
        comment: "Pareto curve: expected energy vs. probability of reaching the target".into(),
        formula: Formula::ParetoTarget,
        etp: None,
    });
    out
}

/// The queries in PRISM's (and Storm's) property language, one per line.
pub fn prism_formula(f: &Formula) -> String {
    match *f {
        Formula::LeastEnergy {
            min_target,
            max_collision,
        } => {
            let mut s = String::from("multi(R{\"energy\"}min=? [ C ]");
            if let Some(p) = min_target {
                s += &format!(", P>={p} [ F \"tar\" ]");
            }
            if let Some(c) = max_collision {
                s += &format!(", P<={c} [ F \"coll\" ]");
            }
            s + ")"
        }
        Formula::MaxTarget => "Pmax=? [ F \"tar\" ]".into(),
        Formula::MinCollision => "Pmin=? [ F \"coll\" ]".into(),
        Formula::ParetoTarget => "multi(R{\"energy\"}min=? [ C ], Pmax=? [ F \"tar\" ])".into(),
    }
}

/// `model.props`: the queries as a PRISM/Storm properties file, each
/// preceded by its comment and followed by etp's answer.
pub fn properties_file(mdp: &Mdp, queries: &[Query]) -> String {
    let mut o = format!(
        "// Properties for the etp MDP of scenario \"{}\" (scenario hash {:.12}…),\n\
         // thresholds taken from its Pareto front (front.json). Each \"etp:\" line is\n\
         // the exact value etp computes (whole-MDP occupation LP, `etp strategy`).\n",
        mdp.scenario_name, mdp.scenario_hash
    );
    for q in queries {
        o += &format!("\n// {}\n{}\n", q.comment, prism_formula(&q.formula));
        if let Some(e) = &q.etp {
            o += &format!("// etp: {e}\n");
        }
    }
    o
}

/// A probability or reward as the shortest decimal that reads back as the
/// same `f64` (every format here parses decimals).
fn number(x: f64) -> String {
    format!("{x}")
}
