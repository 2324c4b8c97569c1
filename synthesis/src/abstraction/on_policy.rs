//! Pools drawn on-policy (`--pool-policy`, docs/MODEL.md §7.3): which
//! (state, action) pairs a layer simulates, the policy's mass of each, the
//! reach it carries to the next layer, and how a state keys its segments'
//! streams so that those choices do not depend on the others.

use crate::mdp::State;
use etp_shared::discretization::Region;
use etp_shared::rng::mix64;

/// Salt of the region keys (on-policy builds).
pub(super) const REGION_SALT: u64 = 0x0B0C_1E5E_6105_0000;

/// How a state names itself in its segments' stream ids: its index in the
/// layer, or in an on-policy build a hash of its region — so that a state's
/// segments do not depend on which *other* regions were reached, and a
/// build on the strategy's own thresholds draws exactly the segments that
/// the build on every threshold draws for them (docs/MODEL.md §7.3).
pub(super) fn state_key(index: usize, region: &Region, by_region: bool) -> u64 {
    if !by_region {
        return index as u64;
    }
    let mut h = mix64(REGION_SALT ^ region.0.len() as u64);
    for &(a, b) in &region.0 {
        h = mix64(h ^ (u64::from(a) << 16 | u64::from(b)));
    }
    h
}

/// The (state, action) pairs a layer simulates, in (state, action) order:
/// every action, or with `policy_only` those the pool policy takes (ω > 0;
/// every action where it takes none, which a distribution cannot do).
pub(super) fn offered_choices(
    states: usize,
    actions: usize,
    omegas: Option<&[Vec<f64>]>,
    policy_only: bool,
) -> Vec<(usize, usize)> {
    let mut out = Vec::with_capacity(states * actions);
    for s in 0..states {
        let takes = |a: usize| {
            omegas
                .and_then(|o| o.get(s))
                .and_then(|w| w.get(a))
                .is_some_and(|&w| w > 0.0)
        };
        if policy_only && (0..actions).any(takes) {
            out.extend((0..actions).filter(|&a| takes(a)).map(|a| (s, a)));
        } else {
            out.extend((0..actions).map(|a| (s, a)));
        }
    }
    out
}

/// ω (over the actions) of the strategy the pools are drawn under.
pub(super) type PoolPolicy<'a> = &'a (dyn Fn(usize, &nalgebra::DMatrix<f64>) -> Vec<f64> + Sync);

/// The pool policy's mass of each offered (state, action) of the layer:
/// reach(s) · ω(s, a).
pub(super) fn on_policy_weights(
    choices: &[(usize, usize)],
    omegas: &[Vec<f64>],
    reach: &[f64],
) -> Vec<f64> {
    choices
        .iter()
        .map(|&(s, a)| {
            let r = reach.get(s).copied().unwrap_or(0.0);
            r * omegas.get(s).and_then(|o| o.get(a)).copied().unwrap_or(0.0)
        })
        .collect()
}

/// The next layer's reach under the policy from this layer's `states` and
/// the masses `w` of their choices (in order, state after state).
pub(super) fn next_reach(
    states: &[State],
    w: &[f64],
    next_offset: usize,
    next_len: usize,
) -> Vec<f64> {
    let mut reach = vec![0.0; next_len];
    let masses = states.iter().flat_map(|st| st.choices.iter()).zip(w);
    for (ch, &m) in masses {
        if m <= 0.0 {
            continue;
        }
        for t in &ch.transitions {
            if let crate::mdp::Next::State(j) = t.next
                && let Some(x) = (j as usize)
                    .checked_sub(next_offset)
                    .and_then(|k| reach.get_mut(k))
            {
                *x += m * t.probability;
            }
        }
    }
    reach
}
