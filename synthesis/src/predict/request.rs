//! The request loop (docs/MODEL.md §7.4): the least-energy strategy whose
//! prediction — the one of its own on-policy rebuilds ([`super::rebuild`]) —
//! meets what the user asked, not only its value on the MDP it was selected
//! on.
//!
//! Each round asks the selection MDP for a request (round 0: the user's own)
//! and predicts the strategy it returns on its rebuilds. The gap between the
//! MDP's value and the prediction is not constant along the front, so one
//! step by the first gap may overshoot (meet, but pay for more than asked)
//! or undershoot. The loop therefore searches the asked level:
//!
//! * **Tighten** while no round has met: each missed bound moves by its gap
//!   and [`TOLERANCE`] of the half-width h (`asked += request − predicted +
//!   TOLERANCE·h`); a request the MDP cannot meet is replaced by the most it
//!   offers on the way to it, and when that is where the loop stands, the
//!   request is out of reach.
//! * **Aim** past a round that met with room to spare: every bound moves by
//!   its gap, either way, so the next round lands at the edge of meeting —
//!   tried only when the MDP's selection there is cheaper by more than
//!   [`BRACKET_TOLERANCE`].
//! * **Bracket**: between the cheapest round that met and the closest round
//!   beyond it that missed, regula falsi on their slacks (kept off the ends
//!   by [`BRACKET_STEP`]), until the two selections' energies on the MDP are
//!   within [`BRACKET_TOLERANCE`] of each other or the rounds run out.
//!
//! Every round is kept in the outcome; the answer is the cheapest round
//! whose prediction meets the request (for `--max-energy`, the highest
//! P_tar within the budget), or, when none did, the one that came closest.
//! A round's first rebuild decides alone when it misses clearly (by more
//! than three of its own held-out half-widths, or by its certified bound):
//! the other rebuilds are made only for a strategy that may be kept.

use super::PredictError;
use super::rebuild::{OnPolicy, Replica, predict, rebuild_one};
use crate::abstraction::AbstractionParams;
use crate::certify::intervals::interval_mdp;
use crate::certify::robust::Certified;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::policy::{Objectives, RandomisedPolicy, evaluate};
use asking::{Candidate, Move, edge, most_transmitting, moved, select, slack};
use etp_shared::scenario::Scenario;
use etp_shared::stats::Z95;
use etp_shared::strategy::Strategy;

mod asking;

/// Rounds of the loop by default.
pub const DEFAULT_ROUNDS: u32 = 8;

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

/// The search ends when the cheapest round that met and the closest round
/// beyond it that missed were selected at MDP energies this close (relative):
/// no strategy the MDP offers between them is cheaper by more.
pub const BRACKET_TOLERANCE: f64 = 0.01;

/// A bracketing round asks at least this fraction of the way from either end
/// of the bracket (regula falsi alone may creep along one end).
const BRACKET_STEP: f64 = 0.2;

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

/// A round and what the loop keeps of it while it may be the answer.
struct Judged {
    index: usize,
    slack: f64,
    candidate: Candidate,
    strategy: Strategy,
    replicas: Vec<Replica>,
}

/// Which way the MDP's selection-time energy goes when the answer improves:
/// down for least energy, up for the highest P_tar within a budget.
fn improving(goal: Goal) -> f64 {
    match goal {
        Goal::MinTarget { .. } => -1.0,
        Goal::MaxEnergy { .. } => 1.0,
    }
}

/// Whether the round `new` (meeting the request) is a better answer than
/// the kept round `old`: cheaper, or a higher P_tar within the budget, by
/// their predictions.
fn better(goal: Goal, new: &Objectives, old: &Objectives) -> bool {
    match goal {
        Goal::MinTarget { .. } => new.energy < old.energy,
        Goal::MaxEnergy { .. } => new.p_target > old.p_target,
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
    // One round: the candidate's first rebuild, and the others unless it
    // misses clearly.
    let judge = |asked: Asked,
                 candidate: Candidate,
                 index: usize|
     -> Result<(Round, Judged), PredictError> {
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
        let round = Round {
            asked,
            selection_time: candidate.selection_time,
            predicted: q,
            ci95: h,
            rebuilds,
            certified: cert_for_goal,
            meets: s >= 0.0,
            most_transmitting: false,
        };
        Ok((
            round,
            Judged {
                index,
                slack: s,
                candidate,
                strategy,
                replicas,
            },
        ))
    };
    let sign = improving(goal);
    let mut asked = Asked::of(goal);
    let mut rounds: Vec<Round> = Vec::new();
    // The answer so far: the best meeting round, else the closest one.
    let mut best: Option<Judged> = None;
    // While aiming past a meeting round: the selection-time energy a new
    // candidate must improve on by `BRACKET_TOLERANCE` to be worth rebuilds.
    let mut must_beat: Option<f64> = None;
    let mut verdict = Verdict::RoundsSpent;
    for _ in 0..settings.max_rounds.max(1) {
        let candidate = match select(mdp, cost, asked, selection_im.as_ref())? {
            Ok(c) => c,
            Err(infeasible) => {
                // The request is infeasible on the MDP: ask for the most it
                // offers between the last request and it — or, for the
                // user's own request, from the loosest one. (The MDP may be
                // pessimistic for the strategy at its edge: its rebuild
                // judges.)
                let first_round = rounds.is_empty();
                match edge(
                    mdp,
                    cost,
                    rounds.last().map(|r| r.asked),
                    asked,
                    selection_im.as_ref(),
                )? {
                    None if first_round => return Err(infeasible),
                    Some((at, c, from)) if first_round || at.distance(from) > 1e-6 => {
                        asked = at;
                        c
                    }
                    _ => {
                        verdict = Verdict::OutOfReach;
                        break;
                    }
                }
            }
        };
        let e = candidate.selection_time.energy;
        if must_beat.is_some_and(|m| sign * (e - m) <= BRACKET_TOLERANCE * m.abs())
            || rounds
                .iter()
                .any(|r| r.selection_time == candidate.selection_time)
        {
            // Nothing better on offer than what was judged already.
            verdict = Verdict::OutOfReach;
            break;
        }
        let (round, judged) = judge(asked, candidate, rounds.len())?;
        let meets = round.meets;
        rounds.push(round);
        let replace = match &best {
            None => true,
            Some(b) if rounds[b.index].meets => {
                meets
                    && better(
                        goal,
                        &rounds[judged.index].predicted,
                        &rounds[b.index].predicted,
                    )
            }
            Some(b) => meets || judged.slack > b.slack,
        };
        if replace {
            best = Some(judged);
        }
        let Some(b) = best.as_ref() else { break };
        let kept = &rounds[b.index];
        if kept.meets {
            // Bracket the edge of meeting: the kept round and the closest
            // round beyond it (cheaper on the MDP, or richer within the
            // budget) that missed.
            let m = kept.selection_time.energy;
            let beyond = rounds
                .iter()
                .filter(|r| !r.meets && sign * (r.selection_time.energy - m) > 0.0)
                .min_by(|a, b| {
                    (a.selection_time.energy - m)
                        .abs()
                        .total_cmp(&(b.selection_time.energy - m).abs())
                });
            match beyond {
                Some(x) => {
                    let gap = (x.selection_time.energy - m).abs();
                    if gap <= BRACKET_TOLERANCE * m.abs().max(x.selection_time.energy.abs()) {
                        break;
                    }
                    // Regula falsi on the slacks, kept off the ends.
                    let sx = slack(goal, &x.predicted, &x.ci95, x.certified.as_ref());
                    let lambda = (sx / (sx - b.slack)).clamp(BRACKET_STEP, 1.0 - BRACKET_STEP);
                    asked = x.asked.towards(kept.asked, lambda);
                    must_beat = None;
                }
                None => {
                    // Every round met: aim at the edge past the kept one.
                    let next = moved(
                        goal,
                        kept.asked,
                        &kept.predicted,
                        &kept.ci95,
                        kept.certified.as_ref(),
                        Move::Aim,
                    );
                    if next.distance(kept.asked) <= 1e-9 {
                        break;
                    }
                    asked = next;
                    must_beat = Some(m);
                }
            }
        } else {
            let last = &rounds[rounds.len() - 1];
            let next = moved(
                goal,
                last.asked,
                &last.predicted,
                &last.ci95,
                last.certified.as_ref(),
                Move::Tighten,
            );
            if next.distance(last.asked) <= 1e-9 {
                // Nothing left to move (a bound already at its limit).
                verdict = Verdict::OutOfReach;
                break;
            }
            asked = next;
            must_beat = None;
        }
    }
    if best.as_ref().is_some_and(|b| rounds[b.index].meets) {
        verdict = Verdict::Met;
    }
    // The MDP is pessimistic at its P_tar edge (its pools hold other
    // strategies' beliefs, docs/MODEL.md §7.4): when the loop could not meet
    // a P_tar request, the policy that transmits most (the smallest δ at
    // every state, the full KF where δ = 0 is an action) is predicted on its
    // own rebuilds too, and kept if it meets the request or comes closer.
    if verdict != Verdict::Met
        && matches!(goal, Goal::MinTarget { .. })
        && let omega = most_transmitting(mdp)
        && best.as_ref().is_none_or(|b| b.candidate.omega != omega)
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
        if best.as_ref().is_none_or(|b| s > b.slack || meets) {
            best = Some(Judged {
                index: rounds.len() - 1,
                slack: s,
                candidate: Candidate {
                    omega,
                    selection_time,
                },
                strategy,
                replicas: all.replicas,
            });
        }
        if meets {
            verdict = Verdict::Met;
        }
    }
    let Some(Judged {
        index: kept,
        candidate,
        strategy,
        replicas,
        ..
    }) = best
    else {
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

    /// The verdict of a name in `--json` (and `front.json`).
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Met, Self::OutOfReach, Self::RoundsSpent]
            .into_iter()
            .find(|v| v.name() == name)
    }
}
