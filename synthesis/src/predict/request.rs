//! The request loop (docs/MODEL.md §7.4): a strategy whose prediction —
//! the one of its own on-policy rebuilds ([`super::rebuild`]) — meets what
//! the user asked, not only its value on the MDP it was selected on.
//!
//! Round k asks the selection MDP for `asked_k` (round 0: the user's
//! request) and predicts the strategy it gives on its rebuilds. Where that
//! prediction misses the user's request (by more than [`TOLERANCE`] of its
//! own 95 % half-width h), each missed bound of the request to the MDP moves
//! by the measured gap and that much more (`asked_{k+1} = asked_k +
//! (request − predicted_k + TOLERANCE·h)`) and the MDP is asked again. A round's first rebuild decides alone when it misses clearly (by
//! more than three of its own held-out half-widths, or by its certified
//! bound, which is the first rebuild's): the other rebuilds are made only
//! for a strategy that may be kept. When the moved request is infeasible on
//! the MDP, the loop asks for the most it offers in that direction; when
//! that is what it just asked, the request is out of reach. Every outcome
//! carries the best strategy the loop could stand behind, with its full
//! prediction.

use super::PredictError;
use super::rebuild::{OnPolicy, Replica, predict, rebuild_one};
use crate::abstraction::AbstractionParams;
use crate::certify::intervals::interval_mdp;
use crate::certify::robust::Certified;
use crate::certify::select::certified_strategy;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::optimal::{LpRequest, optimal_strategy};
use crate::pareto::policy::{Objectives, RandomisedPolicy, evaluate};
use crate::pareto::select::SelectError;
use etp_shared::scenario::Scenario;
use etp_shared::stats::Z95;
use etp_shared::strategy::Strategy;

/// Rounds of the loop by default.
pub const DEFAULT_ROUNDS: u32 = 5;

/// A first rebuild misses clearly when it is this many of its own held-out
/// 95 % half-widths beyond the request (its ± misses about a third of the
/// rebuild's variance, docs/MODEL.md §7.3: 3 is well beyond that).
const CLEAR_MISS: f64 = 3.0;

/// A prediction meets a bound when it is on the right side of it, or short
/// of it by at most this fraction of its own 95 % half-width; a round that
/// misses moves the request by its gap plus as much again, so that the next
/// round's prediction lands inside. Not "within its ±": a prediction whose
/// interval merely straddles the request (e.g. 0.9078 ± 0.0062 against
/// 0.912) leaves about half the risk of missing it in the loop that runs
/// (docs/MODEL.md §7.4).
pub const TOLERANCE: f64 = 0.25;

/// Bisection steps towards the edge of what the MDP offers.
const EDGE_STEPS: usize = 30;

/// What the user asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// Least energy with P_tar ≥ `min_target` (and P_coll ≤ `max_collision`).
    MinTarget {
        min_target: f64,
        max_collision: Option<f64>,
    },
    /// Highest P_tar with expected energy ≤ `max_energy`.
    MaxEnergy { max_energy: f64 },
}

/// A request put to the selection MDP (the user's goal, moved).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Asked {
    MinTarget {
        min_target: f64,
        max_collision: Option<f64>,
    },
    MaxEnergy {
        max_energy: f64,
    },
}

impl Asked {
    fn of(goal: Goal) -> Self {
        match goal {
            Goal::MinTarget {
                min_target,
                max_collision,
            } => Self::MinTarget {
                min_target,
                max_collision,
            },
            Goal::MaxEnergy { max_energy } => Self::MaxEnergy { max_energy },
        }
    }

    /// The bounds of `self` and `other` side by side when the two are
    /// requests of one kind: (main bound of each, their collision bounds
    /// when both have one).
    #[allow(clippy::type_complexity)]
    fn paired(self, other: Self) -> Option<((f64, f64), Option<(f64, f64)>)> {
        match (self, other) {
            (
                Self::MinTarget {
                    min_target: a,
                    max_collision: c,
                },
                Self::MinTarget {
                    min_target: b,
                    max_collision: d,
                },
            ) => Some(((a, b), c.zip(d))),
            (Self::MaxEnergy { max_energy: a }, Self::MaxEnergy { max_energy: b }) => {
                Some(((a, b), None))
            }
            _ => None,
        }
    }

    /// `self` moved a fraction `lambda` of the way to `to`.
    fn towards(self, to: Self, lambda: f64) -> Self {
        let mix = |(a, b): (f64, f64)| a + lambda * (b - a);
        match (to, self.paired(to)) {
            (Self::MinTarget { .. }, Some((main, collision))) => Self::MinTarget {
                min_target: mix(main),
                max_collision: collision.map(mix),
            },
            (Self::MaxEnergy { .. }, Some((main, _))) => Self::MaxEnergy {
                max_energy: mix(main),
            },
            _ => to,
        }
    }

    /// The largest move of any bound from `self` to `other` (energy
    /// relative to its size).
    fn distance(self, other: Self) -> f64 {
        match (other, self.paired(other)) {
            (Self::MinTarget { .. }, Some(((a, b), collision))) => (a - b)
                .abs()
                .max(collision.map_or(0.0, |(c, d)| (c - d).abs())),
            (Self::MaxEnergy { .. }, Some(((a, b), _))) => {
                (a - b).abs() / a.abs().max(b.abs()).max(1e-12)
            }
            _ => f64::INFINITY,
        }
    }
}

/// How the loop selects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopSettings {
    /// Rebuilds of a prediction (≥ 2).
    pub replicates: u32,
    /// Rounds at most (≥ 1).
    pub max_rounds: u32,
    /// Select on certified bounds at this level (a [`Goal::MinTarget`]
    /// only): a round meets the request when the bounds certified on its
    /// first rebuild do.
    pub certified: Option<f64>,
}

/// One round.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Round {
    pub asked: Asked,
    /// The selected strategy's exact value on the selection MDP.
    pub selection_time: Objectives,
    /// Its prediction from this round's rebuilds and its 95 % half-width
    /// (one rebuild: the held-out ± widened by √1.5, docs/MODEL.md §7.3).
    pub predicted: Objectives,
    pub ci95: Objectives,
    pub rebuilds: u32,
    /// Bounds certified on the first rebuild (certified selection only).
    pub certified: Option<Certified>,
    pub meets: bool,
    /// Not selected for `asked` but the most transmitting policy, tried
    /// after the MDP's edge missed a P_tar request ([`most_transmitting`]).
    pub most_transmitting: bool,
}

/// How the loop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The returned strategy's prediction meets the request.
    Met,
    /// The MDP offers nothing further in the direction the request needs:
    /// the returned strategy is the round that came closest.
    OutOfReach,
    /// The rounds ran out before a prediction met the request: the returned
    /// strategy is the round that came closest.
    RoundsSpent,
}

/// The loop's result: the strategy kept, its prediction and the rounds.
pub struct Outcome {
    /// The kept strategy's ω on the selection MDP's states and its exact
    /// value there.
    pub omega: RandomisedPolicy,
    pub selection_time: Objectives,
    pub strategy: Strategy,
    pub on_policy: OnPolicy,
    /// Certified bounds of the kept strategy on its first rebuild (at the
    /// level asked, or at `report_level` without certified selection).
    pub certified: Certified,
    pub rounds: Vec<Round>,
    /// Index of the kept round in `rounds`.
    pub kept: usize,
    pub verdict: Verdict,
}

/// A strategy selected on the MDP, before its rebuilds.
struct Candidate {
    omega: RandomisedPolicy,
    selection_time: Objectives,
}

fn select(
    mdp: &Mdp,
    cost: CostModel,
    asked: Asked,
    certified: Option<&crate::certify::intervals::IntervalMdp>,
) -> Result<Result<Candidate, PredictError>, PredictError> {
    match (asked, certified) {
        (
            Asked::MinTarget {
                min_target,
                max_collision,
            },
            Some(im),
        ) => match certified_strategy(mdp, im, cost, min_target.min(1.0), max_collision) {
            Ok(c) => Ok(Ok(Candidate {
                omega: c.strategy.policy,
                selection_time: c.strategy.predicted,
            })),
            Err(e @ crate::certify::CertifyError::Infeasible { .. }) => Ok(Err(e.into())),
            Err(e) => Err(e.into()),
        },
        (asked, _) => {
            let request = match asked {
                Asked::MinTarget {
                    min_target,
                    max_collision,
                } => LpRequest::MinEnergy {
                    min_target: min_target.min(1.0),
                    max_collision: max_collision.map(|c| c.max(0.0)),
                },
                Asked::MaxEnergy { max_energy } => LpRequest::MaxTarget {
                    max_energy: max_energy.max(0.0),
                },
            };
            match optimal_strategy(mdp, cost, request) {
                Ok(o) => Ok(Ok(Candidate {
                    omega: o.policy,
                    selection_time: o.predicted,
                })),
                Err(e @ SelectError::Infeasible { .. }) => Ok(Err(e.into())),
                Err(e) => Err(e.into()),
            }
        }
    }
}

/// The policy that transmits most: at every state the choice with the
/// smallest threshold δ.
fn most_transmitting(mdp: &Mdp) -> RandomisedPolicy {
    mdp.states
        .iter()
        .map(|st| {
            let delta = |a: u16| mdp.deltas.get(a as usize).copied().unwrap_or(f64::INFINITY);
            let least = (0..st.choices.len())
                .min_by(|&i, &j| {
                    delta(st.choices[i].action).total_cmp(&delta(st.choices[j].action))
                })
                .unwrap_or(0);
            (0..st.choices.len())
                .map(|i| if i == least { 1.0 } else { 0.0 })
                .collect()
        })
        .collect()
}

/// A feasible request of the kind of `asked` to bisect from: no P_tar bound
/// (its P_coll bound kept), or the MDP's least energy (a hair above).
fn loosest(mdp: &Mdp, cost: CostModel, asked: Asked) -> Asked {
    match asked {
        Asked::MinTarget { max_collision, .. } => Asked::MinTarget {
            min_target: 0.0,
            max_collision,
        },
        Asked::MaxEnergy { max_energy } => {
            let least = LpRequest::MinEnergy {
                min_target: 0.0,
                max_collision: None,
            };
            let e = optimal_strategy(mdp, cost, least).map_or(max_energy, |o| o.predicted.energy);
            Asked::MaxEnergy {
                max_energy: e * (1.0 + 1e-9) + 1e-12,
            }
        }
    }
}

/// How far a prediction is from missing the request: ≥ 0 meets it (each
/// bound within `TOLERANCE` of the half-width `h`); the least of its bounds'
/// slacks (energy relative to the request).
fn slack(goal: Goal, q: &Objectives, h: &Objectives, cert: Option<&Certified>) -> f64 {
    let h = Objectives {
        p_target: TOLERANCE * h.p_target,
        p_collision: TOLERANCE * h.p_collision,
        energy: TOLERANCE * h.energy,
    };
    match (goal, cert) {
        (
            Goal::MinTarget {
                min_target,
                max_collision,
            },
            Some(c),
        ) => (c.p_target_low - min_target)
            .min(max_collision.map_or(f64::INFINITY, |m| m - c.p_collision_high)),
        (
            Goal::MinTarget {
                min_target,
                max_collision,
            },
            None,
        ) => (q.p_target + h.p_target - min_target)
            .min(max_collision.map_or(f64::INFINITY, |m| m - (q.p_collision - h.p_collision))),
        (Goal::MaxEnergy { max_energy }, _) => {
            (max_energy - (q.energy - h.energy)) / max_energy.abs().max(1e-12)
        }
    }
}

/// The request to the MDP moved by the gaps between `goal` and what the
/// round measured (point values plus `TOLERANCE` of their half-widths `h`,
/// or the certified bounds).
fn moved(
    goal: Goal,
    asked: Asked,
    q: &Objectives,
    h: &Objectives,
    cert: Option<&Certified>,
) -> Asked {
    match (goal, asked) {
        (
            Goal::MinTarget {
                min_target,
                max_collision,
            },
            Asked::MinTarget {
                min_target: t,
                max_collision: c,
            },
        ) => {
            let (got_t, got_c) = match cert {
                Some(x) => (x.p_target_low, x.p_collision_high),
                None => (
                    q.p_target - TOLERANCE * h.p_target,
                    q.p_collision + TOLERANCE * h.p_collision,
                ),
            };
            Asked::MinTarget {
                min_target: (t + (min_target - got_t).max(0.0)).min(1.0),
                max_collision: c
                    .zip(max_collision)
                    .map(|(c, m)| (c - (got_c - m).max(0.0)).max(0.0)),
            }
        }
        (Goal::MaxEnergy { max_energy }, Asked::MaxEnergy { max_energy: e }) => Asked::MaxEnergy {
            max_energy: (e - (q.energy + TOLERANCE * h.energy - max_energy).max(0.0)).max(0.0),
        },
        (_, a) => a,
    }
}

/// Run the loop on the selection MDP `mdp` (its settings and seed are the
/// rebuilds'). `make` packages a policy on `mdp` with its exact value as a
/// strategy file (scenario text and channel included); `progress` counts
/// rebuild units, `plan` announces units about to be spent.
#[allow(clippy::too_many_arguments)]
pub fn meet_request(
    mdp: &Mdp,
    cost: CostModel,
    scenario: &Scenario,
    params: &AbstractionParams,
    goal: Goal,
    settings: LoopSettings,
    report_level: f64,
    make: &dyn Fn(&RandomisedPolicy, Objectives) -> Strategy,
    plan: &dyn Fn(u32),
    progress: &dyn crate::exec::Work,
) -> Result<Outcome, PredictError> {
    let level = settings.certified.unwrap_or(report_level);
    // A strategy's prediction on `settings.replicates` rebuilds, those in
    // `done` (drawn already) kept.
    let rebuilt = |strategy: &Strategy, done: Vec<Replica>| {
        predict(
            scenario,
            params,
            &strategy.policy,
            settings.replicates,
            cost,
            done,
            progress,
        )
    };
    let selection_im = match settings.certified {
        Some(l) => Some(interval_mdp(mdp, l, cost)?),
        None => None,
    };
    let mut asked = Asked::of(goal);
    let mut rounds: Vec<Round> = Vec::new();
    // The closest round so far: its index, slack, candidate, rebuild(s).
    let mut best: Option<(usize, f64, Candidate, Strategy, Vec<Replica>)> = None;
    let mut verdict = Verdict::RoundsSpent;
    for _ in 0..settings.max_rounds.max(1) {
        let candidate = match select(mdp, cost, asked, selection_im.as_ref())? {
            Ok(c) => c,
            Err(infeasible) => {
                // The request is infeasible on the MDP: ask for the most it
                // offers between the last feasible request and it — or, for
                // the user's own request, from the loosest one. (The MDP may
                // be pessimistic for the strategy at its edge: its rebuild
                // judges.)
                let first_round = rounds.is_empty();
                let last = match rounds.last() {
                    Some(r) => r.asked,
                    None => loosest(mdp, cost, asked),
                };
                if first_round && select(mdp, cost, last, selection_im.as_ref())?.is_err() {
                    return Err(infeasible);
                }
                let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
                let mut found = None;
                for _ in 0..EDGE_STEPS {
                    let mid = 0.5 * (lo + hi);
                    match select(mdp, cost, last.towards(asked, mid), selection_im.as_ref())? {
                        Ok(c) => {
                            lo = mid;
                            found = Some(c);
                        }
                        Err(_) => hi = mid,
                    }
                }
                let edge = last.towards(asked, lo);
                match found {
                    Some(c) if first_round || edge.distance(last) > 1e-6 => {
                        asked = edge;
                        c
                    }
                    _ => {
                        verdict = Verdict::OutOfReach;
                        break;
                    }
                }
            }
        };
        let strategy = make(&candidate.omega, candidate.selection_time);
        plan(1);
        let first = rebuild_one(scenario, params, &strategy.policy, 0, cost, progress)?;
        // Certified selection judges a round by the bounds of its first
        // rebuild; otherwise only the kept strategy is certified, at the end.
        let cert_for_goal = match settings.certified {
            Some(l) => Some(first.certify(l, cost)?),
            None => None,
        };
        // One rebuild's ±: the held-out half-width widened by √1.5 (the
        // variance it misses, docs/MODEL.md §7.3).
        let one = first.prediction();
        let one_ci = first.crossfit.as_ref().map_or(Objectives::default(), |c| {
            let w = Z95 * 1.5_f64.sqrt();
            Objectives {
                p_target: w * c.standard_error.p_target,
                p_collision: w * c.standard_error.p_collision,
                energy: w * c.standard_error.energy,
            }
        });
        let clear_ci = Objectives {
            p_target: CLEAR_MISS * one_ci.p_target,
            p_collision: CLEAR_MISS * one_ci.p_collision,
            energy: CLEAR_MISS * one_ci.energy,
        };
        let clear_miss = slack(goal, &one, &clear_ci, cert_for_goal.as_ref()) < 0.0;
        let (q, h, replicas, rebuilds) = if clear_miss {
            (one, one_ci, vec![first], 1)
        } else {
            plan(settings.replicates.saturating_sub(1));
            let all = rebuilt(&strategy, vec![first])?;
            let (q, h) = (all.combined.mean, all.combined.ci95);
            (q, h, all.replicas, settings.replicates)
        };
        let s = slack(goal, &q, &h, cert_for_goal.as_ref());
        let meets = s >= 0.0;
        rounds.push(Round {
            asked,
            selection_time: candidate.selection_time,
            predicted: q,
            ci95: h,
            rebuilds,
            certified: cert_for_goal,
            meets,
            most_transmitting: false,
        });
        let next = moved(goal, asked, &q, &h, cert_for_goal.as_ref());
        if best.as_ref().is_none_or(|b| s > b.1 || meets) {
            best = Some((rounds.len() - 1, s, candidate, strategy, replicas));
        }
        if meets {
            verdict = Verdict::Met;
            break;
        }
        if next.distance(asked) <= 1e-9 {
            // Nothing left to move (a bound already at its limit).
            verdict = Verdict::OutOfReach;
            break;
        }
        asked = next;
    }
    // The MDP is pessimistic at its P_tar edge (its pools hold other
    // strategies' beliefs, docs/MODEL.md §7.4): when the loop could not meet
    // a P_tar request, the policy that transmits most (the smallest δ at
    // every state, the full KF where δ = 0 is an action) is predicted on its
    // own rebuilds too, and kept if it meets the request or comes closer.
    if verdict != Verdict::Met
        && matches!(goal, Goal::MinTarget { .. })
        && let omega = most_transmitting(mdp)
        && best.as_ref().is_none_or(|b| b.2.omega != omega)
    {
        let selection_time = evaluate(mdp, &omega, cost);
        let strategy = make(&omega, selection_time);
        plan(settings.replicates);
        let all = rebuilt(&strategy, Vec::new())?;
        let cert_for_goal = match (settings.certified, all.replicas.first()) {
            (Some(l), Some(first)) => Some(first.certify(l, cost)?),
            _ => None,
        };
        let (q, h) = (all.combined.mean, all.combined.ci95);
        let s = slack(goal, &q, &h, cert_for_goal.as_ref());
        let meets = s >= 0.0;
        rounds.push(Round {
            asked,
            selection_time,
            predicted: q,
            ci95: h,
            rebuilds: settings.replicates,
            certified: cert_for_goal,
            meets,
            most_transmitting: true,
        });
        if best.as_ref().is_none_or(|b| s > b.1 || meets) {
            let candidate = Candidate {
                omega,
                selection_time,
            };
            best = Some((rounds.len() - 1, s, candidate, strategy, all.replicas));
        }
        if meets {
            verdict = Verdict::Met;
        }
    }
    let Some((kept, _, candidate, strategy, replicas)) = best else {
        return Err(PredictError::Inconsistent(
            "the request loop ended without a round (a bug)".into(),
        ));
    };
    let missing = settings.replicates.saturating_sub(replicas.len() as u32);
    plan(missing);
    let on_policy = rebuilt(&strategy, replicas)?;
    let certified = on_policy.certify_first(level, cost)?;
    Ok(Outcome {
        omega: candidate.omega,
        selection_time: candidate.selection_time,
        strategy,
        on_policy,
        certified,
        rounds,
        kept,
        verdict,
    })
}

impl Round {
    /// As a strategy file records it.
    pub fn record(&self) -> etp_shared::strategy::RequestRound {
        let (t, c, e) = match self.asked {
            Asked::MinTarget {
                min_target,
                max_collision,
            } => (Some(min_target), max_collision, None),
            Asked::MaxEnergy { max_energy } => (None, None, Some(max_energy)),
        };
        etp_shared::strategy::RequestRound {
            asked_p_target: t,
            asked_p_collision: c,
            asked_energy: e,
            selection_time: self.selection_time.prediction(),
            predicted: self.predicted.prediction(),
            predicted_ci95: self.ci95.ci95(),
            rebuilds: self.rebuilds,
            meets: self.meets,
            most_transmitting: self.most_transmitting,
        }
    }
}

impl Verdict {
    /// The verdict's name in `--json`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Met => "met",
            Self::OutOfReach => "out-of-reach",
            Self::RoundsSpent => "rounds-spent",
        }
    }
}
