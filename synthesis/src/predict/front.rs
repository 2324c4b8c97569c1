//! The predicted front (docs/MODEL.md §7.5): for requests spread over the
//! P_tar range the MDP reaches (under each P_coll bound), the strategy the
//! request loop ([`super::request::meet_request`]) returns for that request
//! and its prediction — the trade-offs of strategies that run, beside the
//! MDP's front, whose selection-time values are biased low in energy (and
//! high in P_tar) for the strategy that runs.
//!
//! A point is exactly what `etp strategy DIR --min-target P [--max-collision
//! C]` prints for its request with the same settings: the same loop on the
//! same MDP with the same rebuild seeds. Pure: the loop's progress through
//! callbacks.

use super::PredictError;
use super::request::{Goal, LoopSettings, Outcome, meet_request};
use crate::abstraction::AbstractionParams;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::optimal::{LpRequest, optimal_strategy};
use crate::pareto::policy::{Objectives, RandomisedPolicy};
use crate::pareto::select::SelectError;
use crate::pareto::{PredictedFront, PredictedPoint};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Strategy;

/// Requests per curve by default.
pub const DEFAULT_POINTS: usize = 6;

/// Bisection steps for the top of the P_tar range under a P_coll bound.
const RANGE_STEPS: usize = 40;

/// The P_tar range the MDP offers under `max_collision`: the P_tar of its
/// least-energy strategy and its highest P_tar.
pub fn target_range(
    mdp: &Mdp,
    cost: CostModel,
    max_collision: Option<f64>,
) -> Result<[f64; 2], PredictError> {
    let least = |min_target: f64| {
        optimal_strategy(
            mdp,
            cost,
            LpRequest::MinEnergy {
                min_target,
                max_collision,
            },
        )
    };
    let lo = least(0.0)?.predicted.p_target;
    let (mut ok, mut bad) = (lo, 1.0_f64);
    match least(bad) {
        Ok(o) => return Ok([lo, o.predicted.p_target]),
        Err(SelectError::Infeasible { .. }) => {}
        Err(e) => return Err(e.into()),
    }
    for _ in 0..RANGE_STEPS {
        let mid = 0.5 * (ok + bad);
        match least(mid) {
            Ok(_) => ok = mid,
            Err(SelectError::Infeasible { .. }) => bad = mid,
            Err(e) => return Err(e.into()),
        }
    }
    Ok([lo, ok])
}

/// The point of a request loop's outcome.
pub fn point_of(min_target: f64, o: &Outcome) -> PredictedPoint {
    PredictedPoint {
        min_target,
        verdict: o.verdict.name().to_string(),
        predicted: o.on_policy.combined.mean,
        predicted_ci95: o.on_policy.combined.ci95,
        selection_time: o.selection_time,
        rounds: o.rounds.len(),
        rebuilds: o.rounds.iter().map(|r| r.rebuilds).sum(),
    }
}

/// `points` requests over `range`, both ends included, evenly spaced along
/// the MDP's front `curve` ((energy, P_tar) points, any order) with both
/// axes scaled to their span: where the front is flat (energy rising for
/// little P_tar, near its top) the requests are as dense as where it is
/// steep. Without a usable curve: evenly spaced in P_tar.
pub fn requests(range: [f64; 2], points: usize, curve: &[(f64, f64)]) -> Vec<f64> {
    let [lo, hi] = range;
    let even = |n: usize| -> Vec<f64> {
        (0..n)
            .map(|k| lo + (hi - lo) * k as f64 / (n - 1) as f64)
            .collect()
    };
    if points < 2 {
        return if points == 1 { vec![hi] } else { Vec::new() };
    }
    // The frontier within the range: by energy, P_tar increasing.
    let mut c: Vec<(f64, f64)> = curve
        .iter()
        .copied()
        .filter(|&(e, t)| e.is_finite() && t >= lo - 1e-12 && t <= hi + 1e-12)
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
    let mut f: Vec<(f64, f64)> = Vec::new();
    for q in c {
        if f.last().is_none_or(|l| q.1 > l.1) {
            f.push(q);
        }
    }
    let (Some(first), Some(last)) = (f.first().copied(), f.last().copied()) else {
        return even(points);
    };
    let (de, dt) = (last.0 - first.0, hi - lo);
    if f.len() < 2 || de <= 0.0 || dt <= 0.0 {
        return even(points);
    }
    let mut arc = vec![0.0];
    for w in f.windows(2) {
        let step = ((w[1].0 - w[0].0) / de).hypot((w[1].1 - w[0].1) / dt);
        arc.push(arc[arc.len() - 1] + step);
    }
    let total = arc[arc.len() - 1];
    let mut out = Vec::with_capacity(points);
    for k in 0..points {
        let s = total * k as f64 / (points - 1) as f64;
        let i = arc.partition_point(|&a| a < s).clamp(1, arc.len() - 1);
        let (a0, a1) = (arc[i - 1], arc[i]);
        let w = if a1 > a0 { (s - a0) / (a1 - a0) } else { 1.0 };
        out.push(f[i - 1].1 + w * (f[i].1 - f[i - 1].1));
    }
    // The ends are the range's own (the curve's vertices may stop short).
    out[0] = lo;
    out[points - 1] = hi;
    out.dedup_by(|a, b| (*a - *b).abs() <= 1e-12);
    out
}

/// The predicted front under `max_collision`: the request loop for each of
/// `points` requests over the MDP's range, spread along its front `curve`
/// ([`requests`]). `make`, `plan` and `progress` as for [`meet_request`];
/// `each` is given every point's outcome as it is done.
#[allow(clippy::too_many_arguments)]
pub fn predicted_front(
    mdp: &Mdp,
    cost: CostModel,
    scenario: &Scenario,
    params: &AbstractionParams,
    max_collision: Option<f64>,
    points: usize,
    curve: &[(f64, f64)],
    settings: LoopSettings,
    report_level: f64,
    make: &dyn Fn(Goal, &RandomisedPolicy, Objectives) -> Strategy,
    plan: &dyn Fn(u32),
    progress: &dyn crate::exec::Work,
    each: &mut dyn FnMut(Goal, &Outcome, &PredictedPoint),
) -> Result<PredictedFront, PredictError> {
    let range = target_range(mdp, cost, max_collision)?;
    let mut out = Vec::new();
    for min_target in requests(range, points, curve) {
        let goal = Goal::MinTarget {
            min_target,
            max_collision,
        };
        let outcome = meet_request(
            mdp,
            cost,
            scenario,
            params,
            goal,
            settings,
            report_level,
            &|omega, value| make(goal, omega, value),
            plan,
            progress,
        )?;
        let point = point_of(min_target, &outcome);
        each(goal, &outcome, &point);
        out.push(point);
    }
    Ok(PredictedFront {
        max_collision,
        replicates: settings.replicates,
        max_rounds: settings.max_rounds,
        range,
        points: out,
    })
}

#[cfg(test)]
mod tests {
    use super::requests;

    #[test]
    fn requests_span_the_range_and_follow_the_front() {
        // Steep then flat: P_tar 0.2 → 0.8 for energy 10 → 20, then 0.8 →
        // 0.9 for 20 → 100.
        let curve = [(10.0, 0.2), (20.0, 0.8), (100.0, 0.9)];
        let r = requests([0.2, 0.9], 5, &curve);
        assert_eq!(r.len(), 5);
        assert_eq!(r[0], 0.2);
        assert_eq!(r[4], 0.9);
        assert!(r.windows(2).all(|w| w[0] < w[1]), "{r:?}");
        // Arc lengths: the steep part ≈ 0.86 + 0.13 i.e. ~0.87, the flat
        // part ≈ 1.0: at least two requests above 0.8.
        assert!(r.iter().filter(|&&t| t > 0.8 + 1e-9).count() >= 2, "{r:?}");
        // Without a curve: even in P_tar.
        let even = requests([0.0, 1.0], 3, &[]);
        assert_eq!(even, vec![0.0, 0.5, 1.0]);
        assert_eq!(requests([0.3, 0.6], 1, &curve), vec![0.6]);
    }
}
