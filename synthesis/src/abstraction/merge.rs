//! Lumping statistically equivalent states (docs/MODEL.md §7.3, "merging").
//!
//! Two states of one decision point are lumped when, for every action, the
//! samples give no evidence that they behave differently: their segments'
//! outcomes (collision, target, free, or the *lumped* successor) pass a χ²
//! test of homogeneity and their mean segment energies a two-sample z-test,
//! each at level α. Decision points are processed from the last to the first,
//! so a successor is compared by its lump, not by its region: this is
//! bisimulation-style lumping with statistical equality.
//!
//! A lump's estimates are its members' counts added up (each member brought
//! its own segments), so a lumped state has more samples and narrower
//! intervals. What lumping costs: a strategy must take the same ω in all
//! regions of a lump, and the lump's transition is the members' average, not
//! the mix a particular predecessor sends there — an aggregation error like
//! that of binning itself, inside the sampling noise by construction, and
//! measured, like all aggregation, by `etp validate`.
//!
//! The test is a *failure to reject*: a small α rejects less and lumps more.
//! Each candidate is tested against every member of a lump (not only against
//! the lump's pooled counts), so a chain of small differences cannot drift a
//! lump away from its first member. Pure and deterministic: states are
//! visited in index order and join the first lump that accepts them.

use super::tally::transitions_of;
use crate::mdp::{Choice, Holdout, Mdp, Next, State};
use etp_shared::gaussian;
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::collections::BTreeMap;

/// Expected count under which outcome categories are pooled (the χ²
/// approximation's usual rule).
const MIN_EXPECTED: f64 = 5.0;

/// Why states could not be lumped.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("the merge level α must lie in (0, 1) (got {0})")]
    Alpha(f64),
    #[error("the MDP is already merged (α = {0})")]
    AlreadyMerged(f64),
}

/// What lumping did, per decision point.
#[derive(Debug, Clone, PartialEq)]
pub struct MergeReport {
    pub alpha: f64,
    /// States per decision point before lumping.
    pub before: Vec<usize>,
    /// States per decision point after lumping.
    pub after: Vec<usize>,
}

/// The outcome of one choice with successors renamed to their lumps.
#[derive(Debug, Clone, Default)]
struct Tally {
    samples: u32,
    counts: BTreeMap<Next, u32>,
    /// Σ over segments of the counted energy and of its square.
    cost_sum: f64,
    cost_sq_sum: f64,
}

impl Tally {
    fn of(c: &Choice, lump_of: &[u32]) -> Self {
        let mut counts = BTreeMap::new();
        for t in &c.transitions {
            *counts.entry(rename(t.next, lump_of)).or_insert(0) += t.count;
        }
        let n = f64::from(c.samples);
        Self {
            samples: c.samples,
            counts,
            cost_sum: c.cost_counted * n,
            cost_sq_sum: c.cost_sq_counted * n,
        }
    }

    fn mean_and_variance(&self) -> (f64, f64) {
        let n = f64::from(self.samples.max(1));
        let mean = self.cost_sum / n;
        (mean, (self.cost_sq_sum / n - mean * mean).max(0.0))
    }
}

fn rename(next: Next, lump_of: &[u32]) -> Next {
    match next {
        Next::State(j) => Next::State(lump_of[j as usize]),
        other => other,
    }
}

/// p-value of the χ² test that two count vectors come from one distribution.
/// Categories with an expected count under [`MIN_EXPECTED`] in either row are
/// pooled into one (folded into the smallest other if still sparse); a
/// single category left means no evidence (p = 1).
pub(super) fn homogeneity_p(a: &BTreeMap<Next, u32>, b: &BTreeMap<Next, u32>) -> f64 {
    let (na, nb) = (
        a.values().map(|&v| f64::from(v)).sum::<f64>(),
        b.values().map(|&v| f64::from(v)).sum::<f64>(),
    );
    if na == 0.0 || nb == 0.0 {
        return 1.0;
    }
    let total = na + nb;
    let mut keys: Vec<Next> = a.keys().chain(b.keys()).copied().collect();
    keys.sort();
    keys.dedup();
    let sparse_col = |col: f64| col * na.min(nb) / total < MIN_EXPECTED;
    let mut cells: Vec<(f64, f64)> = Vec::new();
    let mut pooled = (0.0, 0.0);
    for k in keys {
        let (x, y) = (
            f64::from(a.get(&k).copied().unwrap_or(0)),
            f64::from(b.get(&k).copied().unwrap_or(0)),
        );
        if sparse_col(x + y) {
            pooled.0 += x;
            pooled.1 += y;
        } else {
            cells.push((x, y));
        }
    }
    if pooled.0 + pooled.1 > 0.0 {
        // Still sparse once pooled: fold it into the smallest category.
        match cells
            .iter_mut()
            .min_by(|x, y| (x.0 + x.1).total_cmp(&(y.0 + y.1)))
        {
            Some(c) if sparse_col(pooled.0 + pooled.1) => {
                c.0 += pooled.0;
                c.1 += pooled.1;
            }
            _ => cells.push(pooled),
        }
    }
    if cells.len() < 2 {
        return 1.0;
    }
    let stat: f64 = cells
        .iter()
        .map(|&(x, y)| {
            let col = x + y;
            let (ea, eb) = (col * na / total, col * nb / total);
            (x - ea).powi(2) / ea + (y - eb).powi(2) / eb
        })
        .sum();
    match ChiSquared::new((cells.len() - 1) as f64) {
        Ok(d) => 1.0 - d.cdf(stat),
        Err(_) => 1.0,
    }
}

/// Two-sided p-value of the z-test that two mean segment energies are equal.
fn mean_p(a: &Tally, b: &Tally) -> f64 {
    let ((ma, va), (mb, vb)) = (a.mean_and_variance(), b.mean_and_variance());
    let se2 = va / f64::from(a.samples.max(1)) + vb / f64::from(b.samples.max(1));
    if se2 <= 0.0 {
        return if (ma - mb).abs() <= 1e-12 * ma.abs().max(mb.abs()).max(1.0) {
            1.0
        } else {
            0.0
        };
    }
    let z = (ma - mb).abs() / se2.sqrt();
    2.0 * (1.0 - gaussian::normal_cdf(z))
}

/// May `a` and `b` (choices of two states, same order of actions) be lumped?
fn equivalent(a: &[Tally], b: &[Tally], alpha: f64) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| homogeneity_p(&x.counts, &y.counts) >= alpha && mean_p(x, y) >= alpha)
}

/// Lump the statistically equivalent states of `mdp` at level `alpha`.
pub fn merge_equivalent(mdp: &Mdp, alpha: f64) -> Result<(Mdp, MergeReport), MergeError> {
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(MergeError::Alpha(alpha));
    }
    if mdp.build.merge_alpha > 0.0 {
        return Err(MergeError::AlreadyMerged(mdp.build.merge_alpha));
    }
    let n = mdp.states.len();
    let dps = mdp
        .states
        .iter()
        .map(|s| s.decision_point as usize + 1)
        .max()
        .unwrap_or(0);
    let mut at_dp: Vec<Vec<usize>> = vec![Vec::new(); dps];
    for (i, s) in mdp.states.iter().enumerate() {
        at_dp[s.decision_point as usize].push(i);
    }
    // lump_of[i]: a provisional lump id (the index of the lump's first member)
    // until renumbering; successors at dp + 1 are final when dp is processed.
    let mut lump_of: Vec<u32> = (0..n as u32).collect();
    for states in at_dp.iter().rev() {
        let tallies: Vec<Vec<Tally>> = states
            .iter()
            .map(|&i| {
                mdp.states[i]
                    .choices
                    .iter()
                    .map(|c| Tally::of(c, &lump_of))
                    .collect()
            })
            .collect();
        // Lumps as lists of positions in `states`.
        let mut lumps: Vec<Vec<usize>> = Vec::new();
        for (k, t) in tallies.iter().enumerate() {
            let actions_match = |l: &Vec<usize>| {
                let first = &mdp.states[states[l[0]]].choices;
                let mine = &mdp.states[states[k]].choices;
                first.len() == mine.len()
                    && first.iter().zip(mine).all(|(x, y)| x.action == y.action)
            };
            match lumps
                .iter_mut()
                .find(|l| actions_match(l) && l.iter().all(|&m| equivalent(&tallies[m], t, alpha)))
            {
                Some(l) => l.push(k),
                None => lumps.push(vec![k]),
            }
        }
        for l in &lumps {
            let id = states[l[0]] as u32;
            for &m in l {
                lump_of[states[m]] = id;
            }
        }
    }
    // Renumber: lumps in the order of their first member (keeps decision
    // points ascending and the initial state's lump first).
    let mut new_index: BTreeMap<u32, u32> = BTreeMap::new();
    for &l in &lump_of {
        let next = new_index.len() as u32;
        new_index.entry(l).or_insert(next);
    }
    let final_of: Vec<u32> = lump_of.iter().map(|l| new_index[l]).collect();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); new_index.len()];
    for (i, &f) in final_of.iter().enumerate() {
        members[f as usize].push(i);
    }
    let states: Vec<State> = members
        .iter()
        .map(|m| lumped_state(mdp, m, &final_of))
        .collect();
    let count = |states: &[State]| {
        let mut v = vec![0usize; dps];
        for s in states {
            v[s.decision_point as usize] += 1;
        }
        v
    };
    let report = MergeReport {
        alpha,
        before: count(&mdp.states),
        after: count(&states),
    };
    let mut out = Mdp {
        states,
        initial: final_of[mdp.initial as usize],
        ..mdp.clone()
    };
    out.build.merge_alpha = alpha;
    Ok((out, report))
}

/// One state from the members of a lump: counts and sums added up.
fn lumped_state(mdp: &Mdp, members: &[usize], final_of: &[u32]) -> State {
    let first = &mdp.states[members[0]];
    let choices = (0..first.choices.len())
        .map(|a| {
            let cs: Vec<&Choice> = members.iter().map(|&i| &mdp.states[i].choices[a]).collect();
            lumped_choice(&cs, final_of)
        })
        .collect();
    let mut merged: Vec<_> = members[1..]
        .iter()
        .map(|&i| mdp.states[i].region.clone())
        .collect();
    merged.extend(
        members
            .iter()
            .flat_map(|&i| mdp.states[i].merged.iter().cloned()),
    );
    State {
        decision_point: first.decision_point,
        region: first.region.clone(),
        merged,
        choices,
    }
}

fn lumped_choice(cs: &[&Choice], final_of: &[u32]) -> Choice {
    let samples: u32 = cs.iter().map(|c| c.samples).sum();
    let unmatched: u32 = cs.iter().map(|c| c.unmatched).sum();
    let weighted = |f: &dyn Fn(&Choice) -> f64| {
        cs.iter().map(|c| f(c) * f64::from(c.samples)).sum::<f64>() / f64::from(samples.max(1))
    };
    let mut counts: BTreeMap<Next, u32> = BTreeMap::new();
    for c in cs {
        for t in &c.transitions {
            *counts.entry(rename(t.next, final_of)).or_insert(0) += t.count;
        }
    }
    let transitions = transitions_of(counts, samples, unmatched);
    let holdout = cs
        .iter()
        .map(|c| c.holdout.as_ref())
        .collect::<Option<Vec<&Holdout>>>()
        .map(|hs| {
            let hn: u32 = hs.iter().map(|h| h.samples).sum();
            let w = |f: &dyn Fn(&Holdout) -> f64| {
                hs.iter().map(|h| f(h) * f64::from(h.samples)).sum::<f64>() / f64::from(hn.max(1))
            };
            let mut counts: BTreeMap<Next, u32> = BTreeMap::new();
            for h in &hs {
                for &(next, k) in &h.counts {
                    *counts.entry(rename(next, final_of)).or_insert(0) += k;
                }
            }
            Holdout {
                samples: hn,
                cost_counted: w(&|h| h.cost_counted),
                cost_model: w(&|h| h.cost_model),
                counts: counts.into_iter().collect(),
                unmatched: hs.iter().map(|h| h.unmatched).sum(),
            }
        });
    Choice {
        action: cs[0].action,
        samples,
        cost_counted: weighted(&|c| c.cost_counted),
        cost_model: weighted(&|c| c.cost_model),
        mean_steps: weighted(&|c| c.mean_steps),
        transitions,
        unmatched,
        cost_sq_counted: weighted(&|c| c.cost_sq_counted),
        cost_sq_model: weighted(&|c| c.cost_sq_model),
        cost_range: cs.iter().map(|c| c.cost_range).fold(0.0, f64::max),
        holdout,
    }
}

#[cfg(test)]
mod tests;
