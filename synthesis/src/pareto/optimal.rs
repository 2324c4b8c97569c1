//! The exact optimum of a request: the occupation-measure LP over the whole
//! MDP (Etessami et al. 2007, what PRISM's multi-objective engine solves),
//! realised as a memoryless randomised strategy (docs/MODEL.md §5).
//!
//! Solved by Dantzig–Wolfe column generation ([`solve_by_columns`]): the
//! occupation polytope is the convex hull of the deterministic policies'
//! occupation measures, so the LP is a master LP over convex weights of
//! deterministic policies (three rows plus convexity) whose pricing problem —
//! the most negative reduced cost over all policies — is one exact backward
//! induction with the master's dual prices as weights. It stops when no policy
//! has a negative reduced cost: then the master's dual is feasible for the whole
//! LP and its optimum is the whole LP's. A few milliseconds per iteration on
//! thousands of states, where a general simplex over all `x(s, c)`
//! ([`solve_occupation_lp`], kept as a cross-check for small MDPs) takes
//! seconds to minutes.
//!
//! LP: variables `x(s, c) ≥ 0`, the probability of visiting state s and taking
//! choice c; flow `Σ_c x(s, c) = [s = s₀] + Σ_{s', c'} x(s', c') T(s', c', s)`;
//! objectives and constraints are linear in x (energy `Σ x·cost`, P_tar and
//! P_coll the flow into the terminals). Realisation:
//! `ω(s)(c) = x(s, c) / Σ_c' x(s, c')`; on an acyclic MDP ω visits (s, c) with
//! probability exactly x(s, c), so it attains the LP's values. States the
//! optimum never visits ([`UNVISITED`]) take their smallest δ.
//!
//! Constraints hold in the strategy's own exact evaluation, not just in the LP:
//! if the evaluated ω misses a bound by rounding, the LP is solved again with
//! the bound tightened by [`MARGINS`] in turn. A request exactly on the
//! boundary of what the MDP reaches (the highest P_tar under a P_coll bound,
//! read off front.json) cannot be tightened: its optimum is kept when its
//! evaluation misses by no more than the evaluation's own rounding
//! ([`EVALUATION_ROUNDING`]).

use super::policy::{
    DeterministicPolicy, Objectives, RandomisedPolicy, evaluate, mixed_occupation, weighted_optimum,
};
use super::select::SelectError;
use crate::mdp::{CostModel, Mdp, Next};
use good_lp::{
    Expression, Solution, SolverModel, Variable, constraint, microlp, variable, variables,
};

/// What an exact strategy is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LpRequest {
    /// Least energy with `P_tar ≥ min_target` (and `P_coll ≤ max_collision`).
    MinEnergy {
        min_target: f64,
        max_collision: Option<f64>,
    },
    /// Highest `P_tar` with expected energy `≤ max_energy`.
    MaxTarget { max_energy: f64 },
    /// Least `P_coll` with `P_tar ≥ min_target` (for infeasibility reports).
    MinCollision { min_target: f64 },
}

impl std::fmt::Display for LpRequest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::MinEnergy {
                min_target,
                max_collision: Some(c),
            } => write!(f, "P_tar ≥ {min_target} and P_coll ≤ {c}"),
            Self::MinEnergy { min_target, .. } => write!(f, "P_tar ≥ {min_target}"),
            Self::MaxTarget { max_energy } => write!(f, "energy ≤ {max_energy}"),
            Self::MinCollision { min_target } => {
                write!(f, "least P_coll with P_tar ≥ {min_target}")
            }
        }
    }
}

/// Successive tightenings of the request's bounds (absolute for probabilities,
/// relative for energy) tried until the realised strategy meets the request in
/// its own evaluation. The first is the exact request.
pub const MARGINS: [f64; 6] = [0.0, 1e-13, 1e-12, 1e-11, 1e-10, 1e-9];

/// How far the exact evaluation of a strategy may fall short of a bound that
/// sits on the boundary of what the MDP reaches, and still meet it: the
/// evaluation's own rounding (its values are sums over the MDP's transitions
/// in f64, exact to about 1e-15). A miss beyond it is a miss.
pub const EVALUATION_ROUNDING: f64 = 1e-12;

/// A choice whose occupation is below this fraction of its state's is dropped
/// (solver round-off, not a decision).
const NEGLIGIBLE: f64 = 1e-12;

/// How unvisited states are set: their choice with the smallest δ (the one
/// closest to the full Kalman filter, the cautious default should the runtime
/// reach a region the optimum does not expect).
pub const UNVISITED: &str = "smallest δ";

/// The exact optimum of a request.
#[derive(Debug, Clone, PartialEq)]
pub struct OptimalStrategy {
    pub policy: RandomisedPolicy,
    /// Exact evaluation of `policy` (what `strategy.json` predicts).
    pub predicted: Objectives,
    /// The LP's own objective value at the accepted margin.
    pub lp_objective: f64,
    /// The tightening that was needed (0: none).
    pub margin: f64,
    /// States at which ω randomises.
    pub randomised_states: usize,
}

/// The whole-MDP occupation LP of a request: `x(s, c)` and the objective value.
pub fn solve_occupation_lp(
    mdp: &Mdp,
    cost: CostModel,
    request: LpRequest,
) -> Result<(Vec<Vec<f64>>, f64), SelectError> {
    let mut vars = variables!();
    let x: Vec<Vec<Variable>> = mdp
        .states
        .iter()
        .map(|s| {
            s.choices
                .iter()
                .map(|_| vars.add(variable().min(0.0)))
                .collect()
        })
        .collect();
    let mut inflow: Vec<Expression> = vec![Expression::from(0.0); mdp.states.len()];
    inflow[mdp.initial as usize] += 1.0;
    let mut target = Expression::from(0.0);
    let mut collision = Expression::from(0.0);
    let mut energy = Expression::from(0.0);
    for (s, st) in mdp.states.iter().enumerate() {
        for (c, ch) in st.choices.iter().enumerate() {
            energy += ch.cost(cost) * x[s][c];
            for t in &ch.transitions {
                match t.next {
                    Next::State(j) => inflow[j as usize] += t.probability * x[s][c],
                    Next::Target => target += t.probability * x[s][c],
                    Next::Collision => collision += t.probability * x[s][c],
                    Next::Free => {}
                }
            }
        }
    }
    let objective = match request {
        LpRequest::MinEnergy { .. } => energy.clone(),
        LpRequest::MaxTarget { .. } => -target.clone(),
        LpRequest::MinCollision { .. } => collision.clone(),
    };
    let mut problem = vars.minimise(objective.clone()).using(microlp);
    for (s, row) in x.iter().enumerate() {
        let out: Expression = row.iter().copied().sum();
        problem = problem.with(constraint!(out == inflow[s].clone()));
    }
    match request {
        LpRequest::MinEnergy {
            min_target,
            max_collision,
        } => {
            problem = problem.with(constraint!(target >= min_target));
            if let Some(mc) = max_collision {
                problem = problem.with(constraint!(collision <= mc));
            }
        }
        LpRequest::MaxTarget { max_energy } => {
            problem = problem.with(constraint!(energy <= max_energy));
        }
        LpRequest::MinCollision { min_target } => {
            problem = problem.with(constraint!(target >= min_target));
        }
    }
    match problem.solve() {
        Ok(sol) => {
            let values = x
                .iter()
                .map(|row| row.iter().map(|v| sol.value(*v).max(0.0)).collect())
                .collect();
            Ok((values, sol.eval(objective)))
        }
        Err(good_lp::ResolutionError::Infeasible) => Err(infeasible(mdp, cost, request)),
        Err(e) => Err(SelectError::Solver(e.to_string())),
    }
}

/// A column of the master LP: a deterministic policy and its exact values.
struct Column {
    policy: DeterministicPolicy,
    values: Objectives,
}

/// The master LP of a request over columns, as `min w·o` subject to
/// `a_i·o ≤ b_i`, with `o = (energy, P_coll, P_tar)` of a mixture.
struct Master {
    w: [f64; 3],
    rows: Vec<([f64; 3], f64)>,
}

impl Master {
    fn of(request: LpRequest) -> Self {
        match request {
            LpRequest::MinEnergy {
                min_target,
                max_collision,
            } => {
                let mut rows = vec![([0.0, 0.0, -1.0], -min_target)];
                if let Some(c) = max_collision {
                    rows.push(([0.0, 1.0, 0.0], c));
                }
                Self {
                    w: [1.0, 0.0, 0.0],
                    rows,
                }
            }
            LpRequest::MaxTarget { max_energy } => Self {
                w: [0.0, 0.0, -1.0],
                rows: vec![([1.0, 0.0, 0.0], max_energy)],
            },
            LpRequest::MinCollision { min_target } => Self {
                w: [0.0, 1.0, 0.0],
                rows: vec![([0.0, 0.0, -1.0], -min_target)],
            },
        }
    }
}

fn dot3(a: [f64; 3], o: &Objectives) -> f64 {
    a[0] * o.energy + a[1] * o.p_collision + a[2] * o.p_target
}

/// Primal master: convex weights μ of the columns (None: infeasible).
fn master_primal(m: &Master, cols: &[Column]) -> Result<Option<(Vec<f64>, f64)>, SelectError> {
    let mut vars = variables!();
    let mu: Vec<Variable> = cols.iter().map(|_| vars.add(variable().min(0.0))).collect();
    let objective: Expression = mu
        .iter()
        .zip(cols)
        .map(|(v, c)| dot3(m.w, &c.values) * *v)
        .sum();
    let total: Expression = mu.iter().copied().sum();
    let mut problem = vars
        .minimise(objective.clone())
        .using(microlp)
        .with(constraint!(total == 1.0));
    for &(a, b) in &m.rows {
        let lhs: Expression = mu
            .iter()
            .zip(cols)
            .map(|(v, c)| dot3(a, &c.values) * *v)
            .sum();
        problem = problem.with(constraint!(lhs <= b));
    }
    match problem.solve() {
        Ok(sol) => Ok(Some((
            mu.iter().map(|v| sol.value(*v).max(0.0)).collect(),
            sol.eval(objective),
        ))),
        Err(good_lp::ResolutionError::Infeasible) => Ok(None),
        Err(e) => Err(SelectError::Solver(e.to_string())),
    }
}

/// Dual master: `max z − Σ y_i b_i` s.t. `z − Σ y_i a_i·o_k ≤ w·o_k`, `y ≥ 0`
/// (and `y ≤ bound` on a boundary request, see [`boundary_bound`]).
fn master_dual(
    m: &Master,
    cols: &[Column],
    bound: Option<f64>,
) -> Result<(f64, Vec<f64>), SelectError> {
    let mut vars = variables!();
    let z = vars.add(variable());
    let y: Vec<Variable> = m
        .rows
        .iter()
        .map(|_| {
            vars.add(match bound {
                Some(b) => variable().min(0.0).max(b),
                None => variable().min(0.0),
            })
        })
        .collect();
    let objective: Expression = Expression::from(z)
        - y.iter()
            .zip(&m.rows)
            .map(|(v, (_, b))| *b * *v)
            .sum::<Expression>();
    let mut problem = vars.maximise(objective).using(microlp);
    for c in cols {
        let lhs: Expression = Expression::from(z)
            - y.iter()
                .zip(&m.rows)
                .map(|(v, (a, _))| dot3(*a, &c.values) * *v)
                .sum::<Expression>();
        problem = problem.with(constraint!(lhs <= dot3(m.w, &c.values)));
    }
    let sol = problem
        .solve()
        .map_err(|e| SelectError::Solver(format!("dual master: {e}")))?;
    Ok((sol.value(z), y.iter().map(|v| sol.value(*v)).collect()))
}

/// The column of the optimal deterministic policy for `min g·o`, `g` on
/// (energy, P_coll, P_tar), with the exact minimum of `g·o`.
fn price(mdp: &Mdp, cost: CostModel, g: [f64; 3]) -> (Column, f64) {
    // g·o = gE·E + gC·P_coll − gT·(1 − P_tar) + gT.
    let opt = weighted_optimum(mdp, [g[0], g[1], -g[2]], 1.0, cost);
    (
        Column {
            policy: opt.policy,
            values: opt.objectives,
        },
        opt.bound + g[2],
    )
}

/// Add a column unless its policy is already there; whether it was added.
fn add(cols: &mut Vec<Column>, c: Column) -> bool {
    if cols.iter().any(|k| k.policy == c.policy) {
        return false;
    }
    cols.push(c);
    true
}

/// Column generation stops when no policy improves on the master by more
/// than this, relative to the objective's size.
const PRICING_TOLERANCE: f64 = 1e-12;

/// A row's bound this close (relative) to the row's own optimum makes the
/// request a boundary request (see [`boundary_bound`]).
const BOUNDARY: f64 = 1e-9;

/// The bound on the dual prices of a boundary request, relative to the
/// largest objective value of a column.
///
/// Why: when a row's bound `b` equals the best `a·o` of any policy (the
/// request loop asks exactly the highest P_tar when a request is out of
/// reach), only the policies optimal for that row are feasible: the primal
/// master is degenerate and the dual's optimal set is a ray (every price
/// beyond the slope of the face is optimal). microlp's simplex cycles on
/// that ray without end (found on an open-2d stochastic synthesis, `etp
/// strategy --min-target 1.0 --rounds 2`). Bounding the prices makes the
/// dual's set a polytope; a price at the bound prices P_tar lexicographically
/// first, which is what the face asks. Away from the boundary nothing is
/// bounded, so every other request keeps its bits.
const BOUNDARY_PRICE: f64 = 1e8;

/// [`BOUNDARY_PRICE`] in the columns' scale, if some row of `m` is at its
/// own optimum (`best[i]`, the least `a_i·o` of any policy).
fn boundary_bound(m: &Master, best: &[f64], cols: &[Column]) -> Option<f64> {
    let at_boundary = m
        .rows
        .iter()
        .zip(best)
        .any(|(&(_, b), &best)| best >= b - BOUNDARY * b.abs().max(1.0));
    let scale = cols
        .iter()
        .map(|c| dot3(m.w, &c.values).abs())
        .fold(1.0, f64::max);
    at_boundary.then_some(BOUNDARY_PRICE * scale)
}

/// The whole-MDP occupation LP of `request` by column generation:
/// `x(s, c)` of the optimal mixture and the optimum.
pub fn solve_by_columns(
    mdp: &Mdp,
    cost: CostModel,
    request: LpRequest,
) -> Result<(Vec<Vec<f64>>, f64), SelectError> {
    let master = Master::of(request);
    // Start from the single-objective optima (one of them is feasible
    // whenever the request is: max P_tar, min P_coll, min energy) and the
    // objective's own optimum.
    let mut cols: Vec<Column> = Vec::new();
    for g in [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], master.w] {
        let (c, _) = price(mdp, cost, g);
        add(&mut cols, c);
    }
    // Feasibility: each constraint alone is feasible iff its own optimum
    // meets it; jointly, the master with the columns of phase 1 decides.
    let mut bests = Vec::with_capacity(master.rows.len());
    for &(a, b) in &master.rows {
        let (c, best) = price(mdp, cost, a);
        add(&mut cols, c);
        if best > b {
            return Err(infeasible(mdp, cost, request));
        }
        bests.push(best);
    }
    if let Some(&(a2, b2)) = master.rows.get(1) {
        // Two constraints: least a₂·o subject to the first, by columns.
        let phase1 = Master {
            w: a2,
            rows: vec![master.rows[0]],
        };
        let best = generate(mdp, cost, &phase1, &bests[..1], &mut cols)?;
        if best > b2 {
            return Err(infeasible(mdp, cost, request));
        }
    }
    generate(mdp, cost, &master, &bests, &mut cols)?;
    let (mu, value) = master_primal(&master, &cols)?
        .ok_or_else(|| SelectError::Solver("master LP infeasible after phase 1".into()))?;
    let x = mixed_occupation(
        mdp,
        mu.iter()
            .zip(&cols)
            .filter(|(w, _)| **w > 0.0)
            .map(|(w, c)| (*w, &c.policy)),
    );
    Ok((x, value))
}

/// Column generation on `master` from the columns `cols`; returns the optimum.
/// `best[i]`: the least `a_i·o` of any policy (row i's own optimum).
fn generate(
    mdp: &Mdp,
    cost: CostModel,
    master: &Master,
    best: &[f64],
    cols: &mut Vec<Column>,
) -> Result<f64, SelectError> {
    const MAX_ITERATIONS: usize = 10_000;
    for _ in 0..MAX_ITERATIONS {
        let Some((_, primal)) = master_primal(master, cols)? else {
            return Err(SelectError::Solver(
                "master LP infeasible although every constraint is".into(),
            ));
        };
        let (z, y) = master_dual(master, cols, boundary_bound(master, best, cols))?;
        let mut g = master.w;
        for (yi, (a, _)) in y.iter().zip(&master.rows) {
            for k in 0..3 {
                g[k] += yi * a[k];
            }
        }
        let (col, best) = price(mdp, cost, g);
        let reduced = best - z;
        if reduced >= -PRICING_TOLERANCE * primal.abs().max(1.0) || !add(cols, col) {
            return Ok(primal);
        }
    }
    Err(SelectError::Solver(format!(
        "column generation did not converge in {MAX_ITERATIONS} iterations"
    )))
}

/// The infeasibility report: best achievable values by exact backward induction.
fn infeasible(mdp: &Mdp, cost: CostModel, request: LpRequest) -> SelectError {
    let best = |lambda| weighted_optimum(mdp, lambda, 1.0, cost).bound;
    let best_target = 1.0 - best([0.0, 0.0, 1.0]);
    let best_collision = best([0.0, 1.0, 0.0]);
    let best_energy = best([1.0, 0.0, 0.0]);
    let detail = match request {
        LpRequest::MinEnergy {
            min_target,
            max_collision: Some(_),
        } if min_target <= best_target => {
            match solve_by_columns(mdp, cost, LpRequest::MinCollision { min_target }) {
                Ok((_, c)) => format!("; with P_tar ≥ {min_target} the least P_coll is {c:.6}"),
                Err(_) => String::new(),
            }
        }
        _ => String::new(),
    };
    SelectError::Infeasible {
        request: request.to_string(),
        best_target,
        best_collision,
        best_energy,
        detail,
    }
}

/// `ω(s)(c) = x(s, c) / Σ_c' x(s, c')`; unvisited states take their smallest δ.
pub fn realise_occupation(mdp: &Mdp, x: &[Vec<f64>]) -> RandomisedPolicy {
    mdp.states
        .iter()
        .zip(x)
        .map(|(s, row)| {
            let total: f64 = row.iter().sum();
            let kept: Vec<f64> = row
                .iter()
                .map(|&v| if v > NEGLIGIBLE * total { v } else { 0.0 })
                .collect();
            let kept_total: f64 = kept.iter().sum();
            if kept_total > 0.0 {
                kept.iter().map(|v| v / kept_total).collect()
            } else {
                let smallest = (0..s.choices.len())
                    .min_by(|&a, &b| {
                        let (da, db) = (
                            mdp.deltas[s.choices[a].action as usize],
                            mdp.deltas[s.choices[b].action as usize],
                        );
                        da.total_cmp(&db).then(a.cmp(&b))
                    })
                    .unwrap_or(0);
                let mut w = vec![0.0; s.choices.len()];
                w[smallest] = 1.0;
                w
            }
        })
        .collect()
}

/// The request with its bounds tightened by `margin` (absolute for
/// probabilities, relative for energy).
fn tightened(request: LpRequest, margin: f64) -> LpRequest {
    match request {
        LpRequest::MinEnergy {
            min_target,
            max_collision,
        } => LpRequest::MinEnergy {
            min_target: min_target + margin,
            // A probability is never below 0: a bound of 0 (no collision at
            // all) is met exactly or not at all, tightening it only makes the
            // LP infeasible.
            max_collision: max_collision.map(|c| if c > 0.0 { (c - margin).max(0.0) } else { c }),
        },
        LpRequest::MaxTarget { max_energy } => LpRequest::MaxTarget {
            max_energy: max_energy * (1.0 - margin),
        },
        LpRequest::MinCollision { min_target } => LpRequest::MinCollision {
            min_target: min_target + margin,
        },
    }
}

/// Does the exact evaluation meet the request's bounds?
fn meets(request: LpRequest, v: &Objectives) -> bool {
    meets_within(request, v, 0.0)
}

/// Does the exact evaluation meet the request's bounds up to `slack`
/// (absolute for probabilities, relative for energy)?
fn meets_within(request: LpRequest, v: &Objectives, slack: f64) -> bool {
    match request {
        LpRequest::MinEnergy {
            min_target,
            max_collision,
        } => {
            v.p_target >= min_target - slack
                && max_collision.is_none_or(|c| v.p_collision <= c + slack)
        }
        LpRequest::MaxTarget { max_energy } => v.energy <= max_energy * (1.0 + slack),
        LpRequest::MinCollision { min_target } => v.p_target >= min_target - slack,
    }
}

/// The exact optimum of `request`, realised as ω, meeting the request in ω's
/// own evaluation (tightening by [`MARGINS`] if rounding requires it).
pub fn optimal_strategy(
    mdp: &Mdp,
    cost: CostModel,
    request: LpRequest,
) -> Result<OptimalStrategy, SelectError> {
    let mut last: Option<OptimalStrategy> = None;
    for (k, &margin) in MARGINS.iter().enumerate() {
        let (x, lp_objective) = match solve_by_columns(mdp, cost, tightened(request, margin)) {
            Ok(r) => r,
            // The exact request is infeasible: say so with the best values.
            Err(e) if k == 0 => return Err(e),
            // Tightening made it infeasible: the request sits on the boundary,
            // where the exact optimum met it up to the evaluation's rounding
            // or not at all.
            Err(_) => match last {
                Some(l) if meets_within(request, &l.predicted, EVALUATION_ROUNDING) => {
                    return Ok(l);
                }
                _ => break,
            },
        };
        let policy = realise_occupation(mdp, &x);
        let predicted = evaluate(mdp, &policy, cost);
        let randomised_states = policy
            .iter()
            .filter(|w| w.iter().filter(|&&p| p > 0.0).count() > 1)
            .count();
        let found = OptimalStrategy {
            policy,
            predicted,
            lp_objective,
            margin,
            randomised_states,
        };
        if meets(request, &predicted) {
            return Ok(found);
        }
        last = Some(found);
    }
    Err(SelectError::Solver(format!(
        "no strategy meeting {request} in its own evaluation, even with the bounds tightened by {:e}{}",
        MARGINS[MARGINS.len() - 1],
        last.map(|l| format!(
            " (closest: P_tar {:.15}, P_coll {:.15}, energy {:.12})",
            l.predicted.p_target, l.predicted.p_collision, l.predicted.energy
        ))
        .unwrap_or_default()
    )))
}

#[cfg(test)]
mod boundary_tests {
    use super::*;

    fn column(energy: f64, p_target: f64, tag: u16) -> Column {
        Column {
            policy: vec![tag],
            values: Objectives {
                energy,
                p_collision: 0.0,
                p_target,
            },
        }
    }

    /// The dual master that microlp cycled on without end (an open-2d
    /// stochastic synthesis; the request is exactly the highest P_tar, 0.98333…):
    /// with the boundary's bound on the price it returns, with prices that
    /// are dual-feasible and optimal (equal to the primal optimum, the only
    /// feasible column's energy), to the 1e-8 that prices of 1e10 leave of
    /// an energy of 110.
    #[test]
    fn a_request_at_the_highest_p_tar_has_a_bounded_dual_and_returns() {
        let top = 0.983_333_333_333_333_4;
        let cols = [
            column(110.426_107_237_654_3, top, 0),
            column(47.112_630_069_444_44, 0.312_917_692_901_234_6, 1),
        ];
        let m = Master::of(LpRequest::MinEnergy {
            min_target: top,
            max_collision: None,
        });
        // The row's own optimum: −(the highest P_tar).
        let bound = boundary_bound(&m, &[-top], &cols).expect("a boundary request");
        let (z, y) = master_dual(&m, &cols, Some(bound)).expect("the dual solves");
        for c in &cols {
            let lhs = z + y[0] * c.values.p_target;
            assert!(
                lhs <= c.values.energy * (1.0 + 1e-8),
                "{lhs} > {c:?}",
                c = c.values
            );
        }
        let dual_value = z + y[0] * top;
        assert!(
            (dual_value - 110.426_107_237_654_3).abs() < 1e-8 * 110.0,
            "dual {dual_value}"
        );
        // Away from the boundary no bound is put on the prices.
        assert_eq!(boundary_bound(&m, &[-top - 1e-6], &cols), None);
    }
}
