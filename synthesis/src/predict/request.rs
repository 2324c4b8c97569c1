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
//! than [`CLEAR_MISS`] of its own half-width, or by its certified bound):
//! the other rebuilds are made only for a strategy that may be kept.

use super::PredictError;
use super::rebuild::OnPolicy;
use crate::abstraction::AbstractionParams;
use crate::certify::intervals::interval_mdp;
use crate::certify::robust::Certified;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::policy::{Objectives, RandomisedPolicy};
use asking::most_transmitting;
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Strategy;
use rounds::{Judged, NextAsk, RequestLoop, improving, keep_better, next_ask};

mod asking;
mod rounds;

/// Rounds of the loop by default.
pub const DEFAULT_ROUNDS: u32 = 8;

/// A first rebuild misses clearly when it is short of the request by more
/// than this fraction of its own one-rebuild 95 % half-width (the held-out ±
/// widened by √1.5, docs/MODEL.md §7.3): the other rebuilds would have to
/// pull the round's mean up by more than that for it to meet.
const CLEAR_MISS: f64 = 0.75;

/// A round's request moves by its gap plus this fraction of the prediction's
/// 95 % half-width, so that the next round's prediction lands inside the
/// request by that much. A prediction meets a bound only when it is on the
/// right side of it (docs/MODEL.md §7.4): a wider interval buys no room, so
/// the loop cannot prefer a noisier prediction of a cheaper strategy.
pub const TOLERANCE: f64 = 0.25;

/// The search ends when the cheapest round that met and the closest round
/// beyond it that missed were selected at MDP energies this close (relative):
/// no strategy the MDP offers between them is cheaper by more.
pub const BRACKET_TOLERANCE: f64 = 0.01;

/// A bracketing round asks at least this fraction of the way from either end
/// of the bracket (regula falsi alone may creep along one end).
const BRACKET_STEP: f64 = 0.2;

/// When no round met the request, the [`REFINED_ROUNDS`] closest rounds and
/// the most-transmitting round are predicted on up to this many times R
/// rebuilds (doubling) while their prediction misses the request and its
/// interval reaches it: at the top of the front a request within the
/// rebuilds' Monte Carlo of what the full KF reaches is otherwise decided by
/// that Monte Carlo, not by the strategy. Refinement happens only when no
/// round met, so a request the rounds meet costs no more rebuilds.
pub const REFINE_LIMIT: u32 = 4;

/// How many of the closest rounds are refined when none met.
pub const REFINED_ROUNDS: usize = 2;

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
    let lp = RequestLoop {
        mdp,
        cost,
        scenario,
        params,
        goal,
        settings,
        make,
        plan,
        progress,
        selection_im: match settings.certified {
            Some(l) => Some(interval_mdp(mdp, l, cost)?),
            None => None,
        },
    };
    let mut asked = Asked::of(goal);
    let mut rounds: Vec<Round> = Vec::new();
    // The answer so far: the best meeting round, else the closest one.
    let mut best: Option<Judged> = None;
    let mut aside: Vec<Judged> = Vec::new();
    // While aiming past a meeting round: the selection-time energy a new
    // candidate must improve on by `BRACKET_TOLERANCE` to be worth rebuilds.
    let mut must_beat: Option<f64> = None;
    let mut verdict = Verdict::RoundsSpent;
    for _ in 0..settings.max_rounds.max(1) {
        let Some((at, candidate)) = lp.candidate(asked, &rounds)? else {
            verdict = Verdict::OutOfReach;
            break;
        };
        asked = at;
        let e = candidate.selection_time.energy;
        if must_beat.is_some_and(|m| improving(goal) * (e - m) <= BRACKET_TOLERANCE * m.abs())
            || rounds
                .iter()
                .any(|r| r.selection_time == candidate.selection_time)
        {
            // Nothing better on offer than what was judged already.
            verdict = Verdict::OutOfReach;
            break;
        }
        let (round, judged) = lp.judge(asked, candidate, rounds.len())?;
        rounds.push(round);
        if let Some(other) = keep_better(goal, &rounds, &mut best, judged) {
            // The closest rounds that missed, for refinement if none meets.
            aside.push(other);
            aside.sort_by(|a, b| b.slack.total_cmp(&a.slack));
            aside.truncate(REFINED_ROUNDS);
        }
        let Some(b) = best.as_ref() else { break };
        match next_ask(goal, &rounds, b) {
            NextAsk::At {
                asked: a,
                must_beat: m,
            } => {
                asked = a;
                must_beat = m;
            }
            NextAsk::Done => break,
            NextAsk::OutOfReach => {
                verdict = Verdict::OutOfReach;
                break;
            }
        }
    }
    if best.as_ref().is_some_and(|b| rounds[b.index].meets)
        || lp.refine_closest(&mut rounds, &mut best, aside)?
    {
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
        && lp.most_transmitting_round(omega, asked, &mut rounds, &mut best)?
    {
        verdict = Verdict::Met;
    }
    lp.finish(
        best,
        rounds,
        verdict,
        settings.certified.unwrap_or(report_level),
    )
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
