//! Measuring the aggregation error of an abstraction (issue 25, docs/MODEL.md
//! §4.1 "what is not certified"): does a region lump beliefs with different
//! futures?
//!
//! A region stands for every belief in it. If the beliefs of one region
//! behave differently — the leg's outcome (collision, target, free, the next
//! region) depends on where in the region the belief lies — the MDP's pooled
//! estimate is right only for the mix of beliefs it was estimated on, and the
//! closed loop, which reaches the region with another mix, sees another
//! transition. The inverse of the lumping test ([`super::merge`]): there two
//! regions are lumped when no test tells them apart; here one region is
//! flagged when its own beliefs, split by a finer feature, can be told apart.
//!
//! **Samples.** Episodes on the real belief dynamics, each decision point
//! taking a threshold uniformly from Δ (so every (region, action) is reached
//! where the closed loop goes), from their own stream
//! [`AGGREGATION_STREAM`]: independent of the main and held-out samples.
//! At each decision point the belief's region (the MDP's bins), its
//! **features** and the leg's outcome are recorded.
//!
//! **Features** (finer than the region): the descriptor's continuous
//! coordinates — log eigenvalues of the binned matrix (`C_h P C_hᵀ` for the
//! workspace descriptor, P for the per-axis regions), the angle of its leading
//! axis from the nominal one, the log of the rest `tr(Π P Π)` — and the
//! estimate's free drift `C (F − I) x̂` along and across the leg (the carried
//! velocity of a double integrator, which the covariance descriptor does not
//! see; zero for a single integrator, whose split is then skipped).
//!
//! **Test.** Per (decision point, state, action) with enough segments, and per
//! feature: split the segments at the feature's median and test the two
//! halves' outcome counts for homogeneity (the χ² test of the lumping code,
//! sparse categories pooled). All p-values of the run are corrected together
//! by Benjamini–Hochberg at level α (false discovery rate α; under the global
//! null — no region lumps different futures — the chance of flagging any is
//! ≤ α). A flagged region is reported with its largest effect: the total
//! variation distance between its halves' outcome distributions and the
//! distance of each half from the region's pooled estimate.

use super::merge::homogeneity_p;
use crate::mdp::{Mdp, Method, Next};
use etp_shared::discretization::{DecisionPointBins, split_side};
use etp_shared::episode::{AgentState, CompiledScenario, LegEnd, LegMode};
use etp_shared::etkf::{Belief, Threshold};
use etp_shared::linalg::to_dynamic;
use etp_shared::rng::stream_rng;
use etp_shared::scenario::Scenario;
use etp_shared::with_dim;
use rand::RngExt;
use std::collections::BTreeMap;

/// The random stream of the aggregation episodes (its own: the main,
/// held-out and validation samples share no numbers with it).
pub const AGGREGATION_STREAM: u64 = 0xA66E;

/// A region's segments are tested only when each half of a split would hold
/// at least this many (fewer cannot show a difference the χ² test trusts).
pub const MIN_HALF: usize = 40;

/// An arrival in a region the MDP has no state for.
const UNMATCHED: Next = Next::State(u32::MAX);

/// One simulated leg: where it started and how it ended.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Segment {
    pub decision_point: u32,
    /// The MDP state of the start belief (`u32::MAX`: no state).
    pub state: u32,
    pub action: u16,
    pub features: Vec<f64>,
    pub outcome: Next,
}

/// One significant split of a region.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Flag {
    pub decision_point: u32,
    pub state: u32,
    pub action: u16,
    /// The feature the split was made on (index into [`AggregationReport::features`]).
    pub feature: usize,
    /// The median the segments were split at (side 0: below it).
    #[serde(skip)]
    pub threshold: f64,
    pub segments: usize,
    /// Raw and Benjamini–Hochberg adjusted p-values.
    pub p: f64,
    pub p_adjusted: f64,
    /// Total variation distance between the two halves' outcome distributions.
    pub tv_halves: f64,
    /// Largest total variation distance of a half from the region's pooled
    /// estimate (the MDP's main-sample frequencies of the choice).
    pub tv_pooled: f64,
}

/// The result of [`measure`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AggregationReport {
    pub alpha: f64,
    pub episodes: u64,
    pub seed: u64,
    /// Names of the features, in order.
    pub features: Vec<String>,
    /// (decision point, state, action) groups tested / tests run.
    pub groups_tested: usize,
    pub tests: usize,
    /// Groups with too few segments to test.
    pub groups_thin: usize,
    /// Every significant split, strongest first.
    pub flags: Vec<Flag>,
    /// The flagged states (sorted, each once).
    pub flagged_states: Vec<u32>,
}

/// The features of a belief at decision point `dp` (see the module doc):
/// the covariance features of the bins, then the drift along and across the leg.
fn features<const N: usize>(
    bins: &DecisionPointBins,
    scenario: &Scenario,
    dp: usize,
    b: &Belief<N>,
) -> Vec<f64> {
    let mut f = bins.covariance_features(&to_dynamic(&b.cov));
    // The free drift of the estimate in the workspace, along and across the leg.
    let mean = nalgebra::DVector::from_column_slice(b.mean.as_slice());
    let drift_state = &scenario.plant.f * &mean - &mean;
    let drift = scenario.workspace_point(drift_state.as_slice());
    let dir = &scenario.legs[dp].to - scenario.leg_start(dp);
    let along = if dir.norm() > 0.0 {
        drift.dot(&dir) / dir.norm()
    } else {
        0.0
    };
    let across = (drift.norm_squared() - along * along).max(0.0).sqrt();
    f.push(along);
    f.push(across);
    f
}

/// The features after the covariance features (the drift along and across
/// the leg): a split cannot use them (see [`super::split`]).
pub const MEAN_FEATURES: usize = 2;

/// The names of the features of [`Segment::features`], in order.
pub fn feature_names(mdp: &Mdp, scenario: &Scenario) -> Vec<String> {
    let Some(b) = mdp
        .discretization
        .as_ref()
        .and_then(|d| d.decision_points.first())
    else {
        return Vec::new();
    };
    let axes = match &b.workspace {
        Some(w) => w
            .marginal(&nalgebra::DMatrix::identity(scenario.dim, scenario.dim))
            .nrows(),
        None => scenario.dim,
    };
    let mut names: Vec<String> = (1..=axes).map(|j| format!("log λ{j}")).collect();
    names.push("angle of axis 1".into());
    if b.workspace.is_some() {
        names.push("log rest".into());
    }
    names.push("drift along leg".into());
    names.push("drift across leg".into());
    names
}

/// Simulate `episodes` episodes with uniformly random thresholds and record
/// every leg as a [`Segment`]. Deterministic for a seed whatever the thread
/// and rank count (episodes are merged in index order). `None` for Method 1, whose one
/// state per decision point has no region to split.
pub fn sample_segments(
    scenario: &Scenario,
    mdp: &Mdp,
    episodes: u64,
    seed: u64,
    progress: &dyn crate::exec::Work,
) -> Result<Option<Vec<Segment>>, crate::exec::ExecError> {
    sample_segments_on(scenario, mdp, episodes, seed, AGGREGATION_STREAM, progress)
}

/// [`sample_segments`] from random stream `stream` (adaptive splitting draws
/// its own, so the aggregation check after it stays independent of it).
pub fn sample_segments_on(
    scenario: &Scenario,
    mdp: &Mdp,
    episodes: u64,
    seed: u64,
    stream: u64,
    progress: &dyn crate::exec::Work,
) -> Result<Option<Vec<Segment>>, crate::exec::ExecError> {
    if mdp.method != Method::Discretized {
        return Ok(None);
    }
    let Some(disc) = mdp.discretization.as_ref() else {
        return Ok(None);
    };
    let mut state_of: BTreeMap<(u32, &etp_shared::discretization::Region), u32> = BTreeMap::new();
    for (k, s) in mdp.states.iter().enumerate() {
        for r in std::iter::once(&s.region).chain(&s.merged) {
            state_of.insert((s.decision_point, r), k as u32);
        }
    }
    let lookup = |dp: usize, b_cov: &nalgebra::DMatrix<f64>| -> u32 {
        let r = disc.classify_split(dp, b_cov, &mdp.splits);
        state_of.get(&(dp as u32, &r)).copied().unwrap_or(u32::MAX)
    };
    let actions = mdp.deltas.len();
    let segs = with_dim!(scenario.dim, N => {
        let cs = CompiledScenario::<N>::new(scenario);
        let legs = cs.legs.len();
        let episode = |e: usize| {
                let e = e as u64;
                let mut rng = stream_rng(seed, stream, e);
                let mut st: AgentState<N> = cs.initial_state(&mut rng);
                let mut out = Vec::with_capacity(legs);
                // The episode's radio channels (an ideal radio draws nothing).
                let mut channels = cs.channels(seed, stream, e);
                let mut current = lookup(0, &to_dynamic(&st.belief.cov));
                for dp in 0..legs {
                    let a = rng.random_range(0..actions);
                    let feats = features(&disc.decision_points[dp], scenario, dp, &st.belief);
                    let mode = LegMode::<N>::EventTriggered(Threshold::new(mdp.deltas[a]));
                    let r = cs.run_leg(dp, &mut st, &mode, &mut rng, &mut channels, &mut ());
                    let (outcome, next) = match r.end {
                        LegEnd::Collision { .. } => (Next::Collision, None),
                        LegEnd::Terminated if dp + 1 == legs => {
                            (if cs.in_target(&st.x) { Next::Target } else { Next::Free }, None)
                        }
                        LegEnd::Terminated => {
                            let j = lookup(dp + 1, &to_dynamic(&st.belief.cov));
                            (if j == u32::MAX { UNMATCHED } else { Next::State(j) }, Some(j))
                        }
                    };
                    out.push(Segment {
                        decision_point: dp as u32,
                        state: current,
                        action: a as u16,
                        features: feats,
                        outcome,
                    });
                    match next {
                        Some(j) => current = j,
                        None => break,
                    }
                }
                out
            };
        // On the progress's executor: every rank gets every episode's legs.
        crate::exec::map(progress, episodes as usize, episode, |_| 1)
    })?;
    Ok(Some(segs.into_iter().flatten().collect()))
}

fn tv(a: &BTreeMap<Next, u32>, b: &BTreeMap<Next, u32>) -> f64 {
    let (na, nb) = (
        f64::from(a.values().sum::<u32>().max(1)),
        f64::from(b.values().sum::<u32>().max(1)),
    );
    let mut keys: Vec<Next> = a.keys().chain(b.keys()).copied().collect();
    keys.sort();
    keys.dedup();
    0.5 * keys
        .iter()
        .map(|k| {
            (f64::from(a.get(k).copied().unwrap_or(0)) / na
                - f64::from(b.get(k).copied().unwrap_or(0)) / nb)
                .abs()
        })
        .sum::<f64>()
}

fn counts<'a>(segs: impl Iterator<Item = &'a Segment>) -> BTreeMap<Next, u32> {
    let mut m = BTreeMap::new();
    for s in segs {
        *m.entry(s.outcome).or_insert(0) += 1;
    }
    m
}

/// Benjamini–Hochberg adjusted p-values (same order as `p`).
pub fn benjamini_hochberg(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut adj = vec![1.0; m];
    let mut running = 1.0_f64;
    for (rank, &i) in order.iter().enumerate().rev() {
        running = running.min(p[i] * m as f64 / (rank + 1) as f64);
        adj[i] = running.min(1.0);
    }
    adj
}

/// Test every (decision point, state, action) group of `segments` (see the
/// module doc). `pooled(state, action)` is the region's pooled estimate (the
/// MDP's counts of the choice), used for the effect size only.
pub fn test_segments(
    segments: &[Segment],
    alpha: f64,
    pooled: &dyn Fn(u32, u16) -> Option<BTreeMap<Next, u32>>,
) -> (Vec<Flag>, usize, usize, usize) {
    let mut groups: BTreeMap<(u32, u32, u16), Vec<&Segment>> = BTreeMap::new();
    for s in segments.iter().filter(|s| s.state != u32::MAX) {
        groups
            .entry((s.decision_point, s.state, s.action))
            .or_default()
            .push(s);
    }
    let (mut tested, mut thin) = (0, 0);
    let mut candidates: Vec<Flag> = Vec::new();
    for (&(dp, state, action), segs) in &groups {
        if segs.len() < 2 * MIN_HALF {
            thin += 1;
            continue;
        }
        tested += 1;
        let nf = segs[0].features.len();
        let pool = pooled(state, action);
        for k in 0..nf {
            let mut vals: Vec<f64> = segs.iter().map(|s| s.features[k]).collect();
            vals.sort_by(f64::total_cmp);
            let median = vals[vals.len() / 2];
            let (lo, hi): (Vec<&Segment>, Vec<&Segment>) = segs
                .iter()
                .partition(|s| split_side(s.features[k], median) == 0);
            if lo.len() < MIN_HALF || hi.len() < MIN_HALF {
                continue; // a (nearly) constant feature cannot be split
            }
            let (a, b) = (counts(lo.into_iter()), counts(hi.into_iter()));
            let p = homogeneity_p(&a, &b);
            let tv_pooled = pool.as_ref().map_or(f64::NAN, |q| tv(&a, q).max(tv(&b, q)));
            candidates.push(Flag {
                decision_point: dp,
                state,
                action,
                feature: k,
                threshold: median,
                segments: segs.len(),
                p,
                p_adjusted: 1.0,
                tv_halves: tv(&a, &b),
                tv_pooled,
            });
        }
    }
    let tests = candidates.len();
    let adj = benjamini_hochberg(&candidates.iter().map(|f| f.p).collect::<Vec<_>>());
    let mut flags: Vec<Flag> = candidates
        .into_iter()
        .zip(adj)
        .filter(|(_, q)| *q <= alpha)
        .map(|(mut f, q)| {
            f.p_adjusted = q;
            f
        })
        .collect();
    flags.sort_by(|a, b| a.p.total_cmp(&b.p));
    (flags, tested, tests, thin)
}

/// Sample `episodes` episodes and test every region of `mdp` at FDR `alpha`.
pub fn measure(
    scenario: &Scenario,
    mdp: &Mdp,
    episodes: u64,
    seed: u64,
    alpha: f64,
    progress: &dyn crate::exec::Work,
) -> Result<Option<AggregationReport>, crate::exec::ExecError> {
    let Some(segments) = sample_segments(scenario, mdp, episodes, seed, progress)? else {
        return Ok(None);
    };
    let pooled = |state: u32, action: u16| {
        let c = mdp
            .states
            .get(state as usize)?
            .choices
            .iter()
            .find(|c| c.action == action)?;
        let mut m = BTreeMap::new();
        for t in &c.transitions {
            *m.entry(t.next).or_insert(0) += t.count;
        }
        Some(m)
    };
    let (flags, groups_tested, tests, groups_thin) = test_segments(&segments, alpha, &pooled);
    let mut flagged_states: Vec<u32> = flags.iter().map(|f| f.state).collect();
    flagged_states.sort_unstable();
    flagged_states.dedup();
    Ok(Some(AggregationReport {
        alpha,
        episodes,
        seed,
        features: feature_names(mdp, scenario),
        groups_tested,
        tests,
        groups_thin,
        flags,
        flagged_states,
    }))
}

#[cfg(test)]
#[path = "aggregation_tests.rs"]
mod tests;
