//! Adaptive splitting (docs/MODEL.md §7.3) end to end on a built-in: the
//! re-estimation on given bins reproduces the first build, a split region's
//! states carry the split, and the split survives `mdp.bin` and
//! `strategy.json`.

use etp_shared::discretization::{RegionSplit, SPLIT_MARK};
use etp_shared::scenario::Scenario;
use etp_shared::strategy::Strategy;
use etp_synthesis::abstraction::{self, AbstractionParams, aggregation};
use etp_synthesis::mdp::Mdp;
use etp_synthesis::pareto::policy::Objectives;

fn params() -> AbstractionParams {
    AbstractionParams {
        samples: 300,
        holdout_samples: 100,
        seed: 11,
        ..AbstractionParams::default()
    }
}

#[test]
fn given_bins_without_splits_reproduce_the_build_bit_for_bit() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let first = abstraction::build(&s, &params(), &|_: u64| {}).expect("builds");
    let bins = first.discretization.clone().expect("Method 2");
    let again = abstraction::build_split(&s, &params(), &bins, &[], &|_: u64| {}).expect("builds");
    assert_eq!(first.encode(), again.encode());
}

#[test]
fn a_split_region_becomes_two_states_and_survives_the_files() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let first = abstraction::build(&s, &params(), &|_: u64| {}).expect("builds");
    let bins = first.discretization.clone().expect("Method 2");
    // The most visited state of decision point 1, cut on its beliefs'
    // leading log eigenvalue (as the aggregation episodes see them) between
    // the smallest value and the next one: a single integrator's covariance
    // after a leg takes few values (the filter's recursion is deterministic
    // given the transmissions), so a median can coincide with the smallest
    // and leave one side empty.
    let segs = aggregation::sample_segments(&s, &first, 2000, 5, &|_: u64| {})
        .expect("samples")
        .expect("Method 2");
    let at = |k: u32| {
        segs.iter()
            .filter(move |g| g.decision_point == 1 && g.state == k)
    };
    let state = (0..first.states.len() as u32)
        .filter(|&k| first.states[k as usize].decision_point == 1)
        .max_by_key(|&k| at(k).count())
        .expect("a state at decision point 1");
    let mut v: Vec<f64> = at(state).map(|g| g.features[0]).collect();
    v.sort_by(f64::total_cmp);
    assert!(v.len() >= 100, "{} beliefs", v.len());
    let next = v
        .iter()
        .copied()
        .find(|&x| x > v[0])
        .expect("more than one covariance in the region");
    let parent = first.states[state as usize].region.clone();
    let split = RegionSplit {
        decision_point: 1,
        region: parent.clone(),
        feature: 0,
        threshold: 0.5 * (v[0] + next),
    };
    let mdp = abstraction::build_split(
        &s,
        &params(),
        &bins,
        std::slice::from_ref(&split),
        &|_: u64| {},
    )
    .expect("builds");
    mdp.check().expect("consistent");
    assert_eq!(mdp.splits, vec![split.clone()]);
    let regions_at_1: Vec<_> = mdp
        .states
        .iter()
        .filter(|st| st.decision_point == 1)
        .map(|st| st.region.clone())
        .collect();
    assert!(!regions_at_1.contains(&parent), "the parent is no state");
    for side in 0..2 {
        let mut child = parent.clone();
        child.0.push((SPLIT_MARK, side));
        assert!(regions_at_1.contains(&child), "child {side} is a state");
    }
    let per_dp = |m: &Mdp| m.states_per_decision_point();
    assert_eq!(per_dp(&mdp)[1], per_dp(&first)[1] + 1);
    // mdp.bin round trip.
    assert_eq!(Mdp::decode(&mdp.encode()).expect("decodes"), mdp);
    // strategy.json round trip: the splits come along and classify alike.
    let uniform: Vec<Vec<f64>> = mdp
        .states
        .iter()
        .map(|st| vec![1.0 / st.choices.len() as f64; st.choices.len()])
        .collect();
    let strategy = etp_synthesis::pareto::to_strategy(
        &mdp,
        &uniform,
        "uniform".into(),
        Objectives {
            energy: 1.0,
            p_collision: 0.1,
            p_target: 0.9,
        },
    );
    let back = Strategy::from_sealed_json(&strategy.to_json()).expect("loads");
    assert_eq!(back.policy.splits, vec![split]);
    assert_eq!(back.policy.states, strategy.policy.states);
    assert_eq!(back.policy.discretization, strategy.policy.discretization);
}
