//! The splitting rule on regions whose truth is known.

use super::*;
use crate::abstraction::aggregation::{MIN_HALF, Segment};
use crate::mdp::Next;
use etp_shared::discretization::split_side;
use etp_shared::rng::stream_rng;
use rand::RngExt;

/// `n` segments of one region (dp 1, state 3, action 0) with their cluster:
/// each belief belongs to cluster 0 or 1 (equally likely); its features are
/// the cluster centre (0 or `gap` on the first two, nothing on the third)
/// plus uniform noise on [−1, 1]; its outcome is collision with probability
/// `p_coll[cluster]`, else one of two successor states evenly.
fn region(n: usize, gap: f64, p_coll: [f64; 2], seed: u64) -> (Vec<Segment>, Vec<usize>) {
    let mut rng = stream_rng(seed, 98, 0);
    (0..n)
        .map(|_| {
            let c = usize::from(rng.random_bool(0.5));
            let centre = if c == 1 { gap } else { 0.0 };
            let features: Vec<f64> = (0..3)
                .map(|k| {
                    let z: f64 = rng.random_range(-1.0..1.0);
                    if k < 2 { centre + z } else { z }
                })
                .collect();
            let outcome = if rng.random_bool(p_coll[c]) {
                Next::Collision
            } else if rng.random_bool(0.5) {
                Next::State(10)
            } else {
                Next::State(11)
            };
            let s = Segment {
                decision_point: 1,
                state: 3,
                action: 0,
                features,
                outcome,
            };
            (s, c)
        })
        .unzip()
}

fn the_region(state: u32) -> Option<(u32, Region)> {
    (state == 3).then(|| (1, Region(vec![(2, 0), (1, 1)])))
}

/// Two clusters with collision probabilities 5 % and 15 %: the region is
/// split once, on a cluster feature, and the split separates the clusters
/// (the median of equally likely clusters lies at their boundary: ≥ 90 % of
/// the beliefs on their cluster's side; ≈ 97 % expected, the shortfall being
/// |#cluster 1 − n/2| ≈ 22 of 2000).
#[test]
fn a_region_of_two_clusters_is_split_between_them() {
    let (segs, cluster) = region(2000, 4.0, [0.05, 0.15], 1);
    let (flags, ..) = test_segments(&segs, 0.05, &|_, _| None);
    let splits = splits_from_flags(&flags, &the_region, 10);
    assert_eq!(splits.len(), 1, "one split per flagged state: {splits:?}");
    let s = &splits[0];
    assert_eq!(
        (s.decision_point, &s.region),
        (1, &the_region(3).expect("state 3").1)
    );
    assert!(s.feature < 2, "split on a cluster feature: {s:?}");
    let agree = segs
        .iter()
        .zip(&cluster)
        .filter(|(seg, c)| {
            usize::from(split_side(
                seg.features[usize::from(s.feature)],
                s.threshold,
            )) == **c
        })
        .count();
    assert!(agree >= 1800, "{agree} of 2000 on their cluster's side");
    // A budget of 0 splits nothing; an unknown state is skipped.
    assert!(splits_from_flags(&flags, &the_region, 0).is_empty());
    assert!(splits_from_flags(&flags, &|_| None, 10).is_empty());
}

/// One cluster (the outcome does not depend on the features): over 200
/// seeds, a split is asked for in at most 20 (expected ≤ 10: under the
/// global null BH's chance of any flag is ≤ α = 5 %; 20 is 3 σ above 10 of a
/// binomial(200, 0.05)).
#[test]
fn a_region_of_one_cluster_is_not_split_beyond_the_false_positive_rate() {
    let mut split = 0;
    for seed in 0..200 {
        let (segs, _) = region(2000, 4.0, [0.1, 0.1], 2000 + seed);
        let (flags, ..) = test_segments(&segs, 0.05, &|_, _| None);
        split += usize::from(!splits_from_flags(&flags, &the_region, 10).is_empty());
    }
    assert!(split <= 20, "{split} of 200 one-cluster regions split");
}

/// Too few segments to split: nothing is asked for however different the
/// clusters are.
#[test]
fn a_thin_region_is_not_split() {
    let (segs, _) = region(2 * MIN_HALF - 1, 4.0, [0.0, 1.0], 5);
    let (flags, ..) = test_segments(&segs, 0.05, &|_, _| None);
    assert!(splits_from_flags(&flags, &the_region, 10).is_empty());
}
