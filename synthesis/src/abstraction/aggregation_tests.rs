//! The aggregation test on regions whose truth is known.

use super::*;
use etp_shared::rng::stream_rng;

/// `n` segments of one region (dp 1, state 3, action 0). Each belief belongs
/// to cluster 0 or 1 (equally likely); its features are the cluster centre
/// (0 or `gap` on the first two, nothing on the third) plus uniform noise on [−1, 1], and
/// its outcome is collision with probability `p_coll[cluster]`, else one of
/// two successor states evenly.
fn region(n: usize, gap: f64, p_coll: [f64; 2], seed: u64) -> Vec<Segment> {
    let mut rng = stream_rng(seed, 99, 0);
    (0..n)
        .map(|_| {
            let c = usize::from(rng.random_bool(0.5));
            let centre = if c == 1 { gap } else { 0.0 };
            let mut f = Vec::new();
            for k in 0..3 {
                let z: f64 = rng.random_range(-1.0..1.0);
                f.push(if k < 2 { centre + z } else { z });
            }
            let outcome = if rng.random_bool(p_coll[c]) {
                Next::Collision
            } else if rng.random_bool(0.5) {
                Next::State(10)
            } else {
                Next::State(11)
            };
            Segment {
                decision_point: 1,
                state: 3,
                action: 0,
                features: f,
                outcome,
            }
        })
        .collect()
}

fn no_pool(_: u32, _: u16) -> Option<BTreeMap<Next, u32>> {
    None
}

/// Two clusters with collision probabilities 5 % and 15 %, 2000 segments:
/// the split on a cluster feature is flagged; on the pure-noise feature not.
#[test]
fn a_region_of_two_different_clusters_is_flagged() {
    let segs = region(2000, 4.0, [0.05, 0.15], 1);
    let (flags, tested, tests, thin) = test_segments(&segs, 0.05, &no_pool);
    assert_eq!((tested, tests, thin), (1, 3, 0));
    let features: Vec<usize> = flags.iter().map(|f| f.feature).collect();
    assert!(features.contains(&0) && features.contains(&1), "{flags:?}");
    assert!(!features.contains(&2), "{flags:?}");
    // the halves differ by ≈ 10 pt of collision (the clusters do not overlap at gap 4)
    assert!(
        flags.iter().all(|f| (0.06..0.14).contains(&f.tv_halves)),
        "{flags:?}"
    );
}

/// One cluster (the outcome does not depend on the features): over 200
/// seeds, a region is flagged at FDR 5 % in at most 20 (expected ≤ 10 — under
/// the global null BH's chance of any flag is ≤ α; 20 is 3 σ above 10 of a
/// binomial(200, 0.05)).
#[test]
fn a_region_of_one_cluster_is_not_flagged_beyond_the_false_positive_rate() {
    let mut flagged = 0;
    for seed in 0..200 {
        let segs = region(2000, 4.0, [0.1, 0.1], 1000 + seed);
        let (flags, ..) = test_segments(&segs, 0.05, &no_pool);
        flagged += usize::from(!flags.is_empty());
    }
    assert!(flagged <= 20, "{flagged} of 200 null regions flagged");
}

/// Too few segments: nothing is tested, the group counts as thin.
#[test]
fn a_thin_region_is_not_tested() {
    let segs = region(2 * MIN_HALF - 1, 4.0, [0.0, 1.0], 5);
    let (flags, tested, tests, thin) = test_segments(&segs, 0.05, &no_pool);
    assert!(flags.is_empty());
    assert_eq!((tested, tests, thin), (0, 0, 1));
}

#[test]
fn benjamini_hochberg_matches_a_hand_computation() {
    // sorted p 0.01, 0.02, 0.03, 0.5 with m = 4: 0.04, 0.04, 0.04, 0.5
    let adj = benjamini_hochberg(&[0.5, 0.01, 0.03, 0.02]);
    let want = [0.5, 0.04, 0.04, 0.04];
    for (a, w) in adj.iter().zip(want) {
        assert!((a - w).abs() < 1e-12, "{adj:?}");
    }
}
