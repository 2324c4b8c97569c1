//! The rounds of the request loop (docs/MODEL.md §7.4): a candidate for
//! what is asked, its judgement on its own rebuilds, which round is kept,
//! where the next round asks, the most-transmitting fallback and the kept
//! strategy's final prediction.

use super::asking::{Candidate, Move, edge, moved, select, slack};
use super::{
    Asked, BRACKET_STEP, BRACKET_TOLERANCE, CLEAR_MISS, Goal, LoopSettings, Outcome, REFINE_LIMIT,
    REFINED_ROUNDS, Round, Verdict,
};
use crate::abstraction::AbstractionParams;
use crate::certify::intervals::IntervalMdp;
use crate::mdp::{CostModel, Mdp};
use crate::pareto::policy::{Objectives, RandomisedPolicy, evaluate};
use crate::predict::PredictError;
use crate::predict::rebuild::{OnPolicy, Replica, predict, rebuild_one};
use etp_shared::scenario::Scenario;
use etp_shared::stats::Z95;
use etp_shared::strategy::Strategy;

/// A round and what the loop keeps of it while it may be the answer.
pub(super) struct Judged {
    pub(super) index: usize,
    pub(super) slack: f64,
    pub(super) candidate: Candidate,
    pub(super) strategy: Strategy,
    pub(super) replicas: Vec<Replica>,
}

/// Which way the MDP's selection-time energy goes when the answer improves:
/// down for least energy, up for the highest P_tar within a budget.
pub(super) fn improving(goal: Goal) -> f64 {
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

/// What every round of one request loop shares.
pub(super) struct RequestLoop<'a> {
    pub(super) mdp: &'a Mdp,
    pub(super) cost: CostModel,
    pub(super) scenario: &'a Scenario,
    pub(super) params: &'a AbstractionParams,
    pub(super) goal: Goal,
    pub(super) settings: LoopSettings,
    pub(super) make: &'a dyn Fn(&RandomisedPolicy, Objectives) -> Strategy,
    pub(super) plan: &'a dyn Fn(u32),
    pub(super) progress: &'a dyn crate::exec::Work,
    /// The interval MDP of certified selection.
    pub(super) selection_im: Option<IntervalMdp>,
}

impl RequestLoop<'_> {
    /// A strategy's prediction on `settings.replicates` rebuilds, those in
    /// `done` (drawn already) kept.
    fn rebuilt(&self, strategy: &Strategy, done: Vec<Replica>) -> Result<OnPolicy, PredictError> {
        self.rebuilt_to(strategy, self.settings.replicates, done)
    }

    /// A strategy's prediction on `n` rebuilds, those in `done` kept.
    fn rebuilt_to(
        &self,
        strategy: &Strategy,
        n: u32,
        done: Vec<Replica>,
    ) -> Result<OnPolicy, PredictError> {
        predict(
            self.scenario,
            self.params,
            &strategy.policy,
            n,
            self.cost,
            done,
            self.progress,
        )
    }

    /// `all` with more rebuilds while its prediction misses the request
    /// and its interval reaches it (the rebuilds' Monte Carlo alone may
    /// decide): doubling, up to [`REFINE_LIMIT`] × R. Certified selection
    /// judges on the first rebuild's bounds, which more rebuilds leave as
    /// they are: `all` unchanged.
    fn refined(&self, strategy: &Strategy, mut all: OnPolicy) -> Result<OnPolicy, PredictError> {
        if self.settings.certified.is_some() {
            return Ok(all);
        }
        let limit = REFINE_LIMIT * self.settings.replicates;
        loop {
            let (q, h) = (&all.combined.mean, &all.combined.ci95);
            let n = all.replicas.len() as u32;
            let meets = slack(self.goal, q, &Objectives::default(), None) >= 0.0;
            let reaches = slack(self.goal, q, h, None) >= 0.0;
            if meets || !reaches || n >= limit {
                return Ok(all);
            }
            let more = (2 * n).min(limit);
            (self.plan)(more - n);
            all = self.rebuilt_to(strategy, more, all.replicas)?;
        }
    }

    /// When no round met: the [`REFINED_ROUNDS`] closest rounds (`best`
    /// and those set `aside`, by slack), each completed to R rebuilds and
    /// [`Self::refined`], judged again (their records in `rounds` updated);
    /// `best` becomes the first that now meets, else the closest. Whether
    /// one meets.
    pub(super) fn refine_closest(
        &self,
        rounds: &mut [Round],
        best: &mut Option<Judged>,
        aside: Vec<Judged>,
    ) -> Result<bool, PredictError> {
        if self.settings.certified.is_some() || best.is_none() {
            return Ok(false);
        }
        let mut closest: Vec<Judged> = best.take().into_iter().chain(aside).collect();
        closest.sort_by(|a, b| b.slack.total_cmp(&a.slack));
        for j in closest.iter_mut().take(REFINED_ROUNDS) {
            let missing = self
                .settings
                .replicates
                .saturating_sub(j.replicas.len() as u32);
            (self.plan)(missing);
            let done = std::mem::take(&mut j.replicas);
            let all = self.refined(&j.strategy, self.rebuilt(&j.strategy, done)?)?;
            let (q, h) = (all.combined.mean, all.combined.ci95);
            j.slack = slack(self.goal, &q, &Objectives::default(), None);
            j.replicas = all.replicas;
            let round = &mut rounds[j.index];
            round.predicted = q;
            round.ci95 = h;
            round.rebuilds = j.replicas.len() as u32;
            round.meets = j.slack >= 0.0;
            if round.meets {
                break;
            }
        }
        let kept = closest.into_iter().max_by(|a, b| {
            let (ra, rb) = (&rounds[a.index], &rounds[b.index]);
            ra.meets.cmp(&rb.meets).then(a.slack.total_cmp(&b.slack))
        });
        let met = kept.as_ref().is_some_and(|k| rounds[k.index].meets);
        *best = kept;
        Ok(met)
    }

    /// The MDP's candidate for `asked` and the request it answers. When
    /// `asked` is infeasible on the MDP: the most it offers between the last
    /// round's request and it — or, for the user's own request, from the
    /// loosest one (the MDP may be pessimistic for the strategy at its edge:
    /// its rebuild judges). `None`: nothing further on offer.
    pub(super) fn candidate(
        &self,
        asked: Asked,
        rounds: &[Round],
    ) -> Result<Option<(Asked, Candidate)>, PredictError> {
        let infeasible = match select(self.mdp, self.cost, asked, self.selection_im.as_ref())? {
            Ok(c) => return Ok(Some((asked, c))),
            Err(infeasible) => infeasible,
        };
        let first_round = rounds.is_empty();
        match edge(
            self.mdp,
            self.cost,
            rounds.last().map(|r| r.asked),
            asked,
            self.selection_im.as_ref(),
        )? {
            None if first_round => Err(infeasible),
            Some((at, c, from)) if first_round || at.distance(from) > 1e-6 => Ok(Some((at, c))),
            _ => Ok(None),
        }
    }

    /// One round: the candidate's first rebuild, and the others unless it
    /// misses clearly.
    pub(super) fn judge(
        &self,
        asked: Asked,
        candidate: Candidate,
        index: usize,
    ) -> Result<(Round, Judged), PredictError> {
        let (goal, settings, cost) = (self.goal, self.settings, self.cost);
        let strategy = (self.make)(&candidate.omega, candidate.selection_time);
        (self.plan)(1);
        let first = rebuild_one(
            self.scenario,
            self.params,
            &strategy.policy,
            0,
            cost,
            self.progress,
        )?;
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
            (self.plan)(settings.replicates.saturating_sub(1));
            let all = self.rebuilt(&strategy, vec![first])?;
            let (q, h) = (all.combined.mean, all.combined.ci95);
            (q, h, all.replicas, settings.replicates)
        };
        let s = slack(goal, &q, &Objectives::default(), cert_for_goal.as_ref());
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
    }

    /// The most-transmitting policy `omega` predicted on its own rebuilds
    /// ([`Self::refined`]) as one more round (asked at `asked`), kept in
    /// `best` if it meets the request or comes closer; whether it meets.
    pub(super) fn most_transmitting_round(
        &self,
        omega: RandomisedPolicy,
        asked: Asked,
        rounds: &mut Vec<Round>,
        best: &mut Option<Judged>,
    ) -> Result<bool, PredictError> {
        let (goal, settings, cost) = (self.goal, self.settings, self.cost);
        let selection_time = evaluate(self.mdp, &omega, cost);
        let strategy = (self.make)(&omega, selection_time);
        (self.plan)(settings.replicates);
        let all = self.refined(&strategy, self.rebuilt(&strategy, Vec::new())?)?;
        let cert_for_goal = match (settings.certified, all.replicas.first()) {
            (Some(l), Some(first)) => Some(first.certify(l, cost)?),
            _ => None,
        };
        let (q, h) = (all.combined.mean, all.combined.ci95);
        let s = slack(goal, &q, &Objectives::default(), cert_for_goal.as_ref());
        let meets = s >= 0.0;
        rounds.push(Round {
            asked,
            selection_time,
            predicted: q,
            ci95: h,
            rebuilds: all.replicas.len() as u32,
            certified: cert_for_goal,
            meets,
            most_transmitting: true,
        });
        if best.as_ref().is_none_or(|b| s > b.slack || meets) {
            *best = Some(Judged {
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
        Ok(meets)
    }

    /// The kept round's strategy on all its rebuilds, certified at `level`.
    pub(super) fn finish(
        &self,
        best: Option<Judged>,
        rounds: Vec<Round>,
        verdict: Verdict,
        level: f64,
    ) -> Result<Outcome, PredictError> {
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
        let missing = self
            .settings
            .replicates
            .saturating_sub(replicas.len() as u32);
        (self.plan)(missing);
        let on_policy = self.rebuilt(&strategy, replicas)?;
        let certified = on_policy.certify_first(level, self.cost)?;
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
}

/// Keep `judged` (the last of `rounds`) in `best` if it is the better
/// answer: a meeting round that is better than a kept meeting one, else the
/// one that meets or comes closer. The round not kept is returned.
pub(super) fn keep_better(
    goal: Goal,
    rounds: &[Round],
    best: &mut Option<Judged>,
    judged: Judged,
) -> Option<Judged> {
    let meets = rounds[judged.index].meets;
    let replace = match best.as_ref() {
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
        best.replace(judged)
    } else {
        Some(judged)
    }
}

/// Where the loop goes after a round.
pub(super) enum NextAsk {
    /// Ask this next (`must_beat`: the selection-time energy a candidate
    /// must improve on while aiming past a meeting round).
    At {
        asked: Asked,
        must_beat: Option<f64>,
    },
    /// The kept round is the answer.
    Done,
    /// Nothing left to move (a bound already at its limit).
    OutOfReach,
}

/// The next request given the kept round `b`: with a meeting round, bracket
/// the edge of meeting — the kept round and the closest round beyond it
/// (cheaper on the MDP, or richer within the budget) that missed; without
/// one, tighten the last round's request by its gap.
pub(super) fn next_ask(goal: Goal, rounds: &[Round], b: &Judged) -> NextAsk {
    let sign = improving(goal);
    let kept = &rounds[b.index];
    if !kept.meets {
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
            return NextAsk::OutOfReach;
        }
        return NextAsk::At {
            asked: next,
            must_beat: None,
        };
    }
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
                return NextAsk::Done;
            }
            // Regula falsi on the slacks, kept off the ends.
            let sx = slack(
                goal,
                &x.predicted,
                &Objectives::default(),
                x.certified.as_ref(),
            );
            let lambda = (sx / (sx - b.slack)).clamp(BRACKET_STEP, 1.0 - BRACKET_STEP);
            NextAsk::At {
                asked: x.asked.towards(kept.asked, lambda),
                must_beat: None,
            }
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
                return NextAsk::Done;
            }
            NextAsk::At {
                asked: next,
                must_beat: Some(m),
            }
        }
    }
}
