//! Bounded, deterministic particle pools.
//!
//! The pool of decision point i + 1 is a uniform sample (without replacement)
//! of the beliefs that arrived there, drawn separately per region so that every
//! region that was reached keeps at least one particle. It is a *bottom-k*
//! sample: every arrival carries a pseudo-random key (a hash of its segment id),
//! and a region keeps the `cap` arrivals with the smallest keys. The result does
//! not depend on the order in which arrivals are merged, hence not on threads.
//!
//! Pools drawn on-policy (`--pool-policy`) are [`weighted_pool`]s instead.

use etp_shared::rng::{mix64, unit_f64};

/// Salt separating reservoir keys from the segment's random stream.
const KEY_SALT: u64 = 0x5EED_0FB0_770A_1E00;

/// The reservoir key of segment `id`.
#[inline]
pub(super) fn key(id: u64) -> u64 {
    mix64(id ^ KEY_SALT)
}

/// Keep the `cap` items with the smallest keys, in key order.
pub(super) fn bottom_k<T>(mut items: Vec<(u64, T)>, cap: usize) -> Vec<T> {
    let cap = cap.max(1);
    if items.len() > cap {
        items.select_nth_unstable_by_key(cap - 1, |x| x.0);
        items.truncate(cap);
    }
    // Stable sort on the key: equal keys (practically never) keep merge order.
    items.sort_by_key(|x| x.0);
    items.into_iter().map(|x| x.1).collect()
}

/// A pool drawn on-policy: its particles, and where they are not equally
/// likely their cumulative weights (a segment's start is drawn in proportion).
pub(super) struct WeightedPool<T> {
    pub particles: Vec<T>,
    pub cumulative: Option<Vec<f64>>,
}

/// The pool of a region whose arrivals carry the policy's mass `w`
/// (docs/MODEL.md §7.3): a sample of the arrivals in proportion to `w`, *with*
/// replacement, so the pool's law is the weighted mixture whatever the counts.
/// (A weighted sample without replacement is not: with fewer heavy arrivals
/// than `cap` it keeps every one and fills up with light ones.)
///
/// * Arrivals of positive weight, at most `cap`: all kept, in key order, with
///   their cumulative weights — no resampling noise.
/// * More than `cap`: systematic resampling to `cap` particles (points
///   (j + u₀) W / cap on the cumulative weights in key order, u₀ from the
///   smallest key), equally likely: each arrival copied ⌊·⌋ or ⌈·⌉ of
///   cap · w / W times.
/// * No positive weight (only actions the policy never takes arrive): the
///   uniform bottom-k pool, so the region keeps one.
///
/// Key order makes the result independent of merge order, hence of threads.
pub(super) fn weighted_pool<T: Clone>(items: Vec<(u64, f64, T)>, cap: usize) -> WeightedPool<T> {
    let cap = cap.max(1);
    let (mut positive, zero): (Vec<_>, Vec<_>) = items
        .into_iter()
        .partition(|(_, w, _)| *w > 0.0 && w.is_finite());
    if positive.is_empty() {
        return WeightedPool {
            particles: bottom_k(zero.into_iter().map(|(k, _, t)| (k, t)).collect(), cap),
            cumulative: None,
        };
    }
    positive.sort_by_key(|x| x.0);
    let mut cumulative = Vec::with_capacity(positive.len());
    let mut total = 0.0;
    for (_, w, _) in &positive {
        total += w;
        cumulative.push(total);
    }
    if positive.len() <= cap {
        return WeightedPool {
            particles: positive.into_iter().map(|x| x.2).collect(),
            cumulative: Some(cumulative),
        };
    }
    let u0 = unit_f64(mix64(positive[0].0 ^ KEY_SALT));
    let step = total / cap as f64;
    let mut particles = Vec::with_capacity(cap);
    let mut i = 0;
    for j in 0..cap {
        let point = (j as f64 + u0) * step;
        while i + 1 < positive.len() && cumulative[i] <= point {
            i += 1;
        }
        particles.push(positive[i].2.clone());
    }
    WeightedPool {
        particles,
        cumulative: None,
    }
}

/// Index of a segment's start particle: uniform, or in proportion to the
/// pool's weights (`u` uniform on [0, 1)).
#[inline]
pub(super) fn weighted_index(cumulative: &[f64], u: f64) -> usize {
    let total = cumulative.last().copied().unwrap_or(0.0);
    cumulative
        .partition_point(|&c| c <= u * total)
        .min(cumulative.len().saturating_sub(1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_shared::etkf::Belief;
    use etp_shared::etkf::{Matrix, Vector};

    fn b(v: f64) -> Belief<1> {
        Belief {
            mean: Vector::<1>::new(v),
            cov: Matrix::<1, 1>::new(1.0),
        }
    }

    #[test]
    fn keeps_the_smallest_keys_whatever_the_order() {
        let items: Vec<(u64, Belief<1>)> = (0..100u64).map(|i| (key(i), b(i as f64))).collect();
        let mut reversed = items.clone();
        reversed.reverse();
        let a = bottom_k(items.clone(), 10);
        let r = bottom_k(reversed, 10);
        assert_eq!(a, r);
        assert_eq!(a.len(), 10);
        let mut keys: Vec<u64> = items.iter().map(|x| x.0).collect();
        keys.sort_unstable();
        let kept: Vec<u64> = a.iter().map(|p| key(p.mean[0] as u64)).collect();
        assert_eq!(kept, keys[..10].to_vec());
        assert_eq!(bottom_k(items[..3].to_vec(), 10).len(), 3);
    }

    /// Arrivals of two sources: `heavy` of weight 3 (tagged 1), `light` of
    /// weight 1 (tagged 0), keys in a shuffled order.
    fn two_sources(heavy: u64, light: u64) -> Vec<(u64, f64, u8)> {
        (0..heavy + light)
            .map(|i| {
                let (w, tag) = if i < heavy { (3.0, 1) } else { (1.0, 0) };
                (key(i), w, tag)
            })
            .collect()
    }

    /// The probability that a start is drawn from the heavy source.
    fn heavy_mass(p: &WeightedPool<u8>) -> f64 {
        match &p.cumulative {
            Some(c) => {
                let mut prev = 0.0;
                let mut heavy = 0.0;
                for (x, &cum) in p.particles.iter().zip(c) {
                    if *x == 1 {
                        heavy += cum - prev;
                    }
                    prev = cum;
                }
                heavy / c.last().copied().unwrap_or(1.0)
            }
            None => {
                p.particles.iter().filter(|&&x| x == 1).count() as f64 / p.particles.len() as f64
            }
        }
    }

    #[test]
    fn a_weighted_pool_has_the_weighted_law_whatever_the_counts() {
        // 50 heavy (weight 3) and 950 light (weight 1) arrivals: the law puts
        // 150 / 1100 on the heavy source. A sample without replacement of
        // 500 would keep all 50 heavy ones and 450 light ones (0.1).
        let exact = 150.0 / 1100.0;
        let kept = weighted_pool(two_sources(50, 950), 2000);
        assert_eq!(kept.particles.len(), 1000);
        assert!((heavy_mass(&kept) - exact).abs() < 1e-12);
        // Resampled (more arrivals than the cap): every arrival copied
        // ⌊cap · w / W⌋ or ⌈cap · w / W⌉ times, cap particles in all.
        for cap in [500, 64] {
            let items: Vec<(u64, f64, u64)> = (0..1000u64)
                .map(|i| (key(i), if i < 50 { 3.0 } else { 1.0 }, i))
                .collect();
            let p = weighted_pool(items, cap);
            assert_eq!(p.particles.len(), cap);
            assert!(p.cumulative.is_none());
            for i in 0..1000u64 {
                let copies = p.particles.iter().filter(|&&x| x == i).count() as f64;
                let e = cap as f64 * if i < 50 { 3.0 } else { 1.0 } / 1100.0;
                assert!(
                    copies >= e.floor() && copies <= e.ceil(),
                    "cap {cap}, arrival {i}: {copies} copies, {e} expected"
                );
            }
        }
        // Starts drawn by weighted_index follow the weights.
        let p = weighted_pool(two_sources(50, 950), 2000);
        let c = p.cumulative.as_ref().expect("kept with weights");
        let draws = 200_000;
        let heavy = (0..draws)
            .filter(|&i| {
                let u = unit_f64(mix64(i));
                p.particles[weighted_index(c, u)] == 1
            })
            .count() as f64
            / draws as f64;
        // Binomial 5σ at 200 000 draws: ±0.0039.
        assert!((heavy - exact).abs() < 0.0039, "{heavy}");
    }

    #[test]
    fn weight_zero_arrivals_only_where_nothing_else_arrived() {
        let mut items = two_sources(0, 10);
        for x in &mut items {
            x.1 = 0.0;
        }
        let only_zero = weighted_pool(items.clone(), 4);
        assert_eq!(only_zero.particles.len(), 4);
        assert!(only_zero.cumulative.is_none());
        items.push((key(99), 2.0, 1));
        let p = weighted_pool(items, 4);
        assert_eq!(p.particles, vec![1]);
    }

    #[test]
    fn a_weighted_pool_does_not_depend_on_the_merge_order() {
        let items = two_sources(300, 700);
        let mut reversed = items.clone();
        reversed.reverse();
        for cap in [2000, 100] {
            let (a, b) = (
                weighted_pool(items.clone(), cap),
                weighted_pool(reversed.clone(), cap),
            );
            assert_eq!(a.particles, b.particles);
            assert_eq!(a.cumulative, b.cumulative);
        }
    }
}
