use super::*;
use crate::mdp::CostModel;
use crate::mdp::tests::toy;
use crate::pareto::policy::{as_randomised, evaluate};
use etp_shared::discretization::Region;

/// The toy MDP with its two decision-point-1 states made identical (state 2
/// a copy of state 1 under another region) and `samples` per choice.
fn twins(samples: u32) -> Mdp {
    let mut m = toy();
    let mut copy = m.states[1].clone();
    copy.region = Region(vec![(5, 0)]);
    m.states[2] = copy;
    for s in &mut m.states {
        for c in &mut s.choices {
            let scale = f64::from(samples) / f64::from(c.samples);
            c.samples = samples;
            for t in &mut c.transitions {
                t.count = (f64::from(t.count) * scale).round() as u32;
            }
        }
    }
    m
}

fn values(m: &Mdp) -> Vec<[f64; 3]> {
    // Every deterministic policy that takes one action everywhere.
    (0..m.deltas.len())
        .map(|a| {
            let p: Vec<u16> = m.states.iter().map(|_| a as u16).collect();
            let o = evaluate(m, &as_randomised(m, &p), CostModel::Counted);
            [o.p_target, o.p_collision, o.energy]
        })
        .collect()
}

#[test]
fn identical_states_are_lumped_and_every_value_is_kept() {
    let m = twins(1000);
    let (merged, report) = merge_equivalent(&m, 0.05).expect("merge");
    assert_eq!(report.before, vec![1, 2]);
    assert_eq!(report.after, vec![1, 1]);
    assert_eq!(merged.states.len(), 2);
    assert_eq!(merged.states[1].merged, vec![Region(vec![(5, 0)])]);
    assert_eq!(merged.states[1].choices[0].samples, 2000);
    // The predecessor's two successors are one now.
    let succ: Vec<Next> = merged.states[0].choices[0]
        .transitions
        .iter()
        .map(|t| t.next)
        .collect();
    assert!(succ.contains(&Next::State(1)));
    assert!(!succ.contains(&Next::State(2)));
    for (a, b) in values(&m).iter().zip(values(&merged)) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-12, "{a:?} vs {b:?}");
        }
    }
    assert_eq!(merged.build.merge_alpha, 0.05);
    assert!(matches!(
        merge_equivalent(&merged, 0.05),
        Err(MergeError::AlreadyMerged(_))
    ));
}

#[test]
fn states_that_differ_beyond_the_noise_stay_apart() {
    // Outcomes 95/5 against 90/10 with 6000 segments each: χ² ≈ 100.
    let mut m = twins(6000);
    let c = &mut m.states[2].choices[0];
    c.transitions[0].count = 5400;
    c.transitions[0].probability = 0.9;
    c.transitions[1].count = 600;
    c.transitions[1].probability = 0.1;
    let (merged, report) = merge_equivalent(&m, 0.05).expect("merge");
    assert_eq!(report.after, vec![1, 2]);
    assert_eq!(merged.states.len(), 3);
    // Equal outcomes but a different, noiseless mean energy: apart as well.
    let mut m = twins(6000);
    m.states[2].choices[1].cost_counted = 2.5;
    m.states[2].choices[1].cost_sq_counted = 6.25;
    assert_eq!(
        merge_equivalent(&m, 0.05).expect("merge").1.after,
        vec![1, 2]
    );
}

#[test]
fn a_difference_inside_the_noise_is_lumped() {
    // 95.0 % against 94.6 % target with 1000 segments each: p ≈ 0.7.
    let mut m = twins(1000);
    let c = &mut m.states[2].choices[0];
    c.transitions[0].count = 946;
    c.transitions[1].count = 54;
    assert_eq!(
        merge_equivalent(&m, 0.05).expect("merge").1.after,
        vec![1, 1]
    );
}

#[test]
fn the_level_must_be_a_probability() {
    for alpha in [0.0, 1.0, -0.1, f64::NAN] {
        assert!(matches!(
            merge_equivalent(&toy(), alpha),
            Err(MergeError::Alpha(_))
        ));
    }
}

#[test]
fn homogeneity_p_is_one_for_equal_counts_and_small_for_different_ones() {
    let map = |v: &[(Next, u32)]| v.iter().copied().collect::<BTreeMap<Next, u32>>();
    let a = map(&[(Next::Target, 900), (Next::Collision, 100)]);
    assert!((homogeneity_p(&a, &a) - 1.0).abs() < 1e-12);
    let b = map(&[(Next::Target, 800), (Next::Collision, 200)]);
    assert!(homogeneity_p(&a, &b) < 1e-6);
    // Rare categories are pooled, not tested on their own.
    let c = map(&[(Next::Target, 998), (Next::Free, 2)]);
    let d = map(&[(Next::Target, 1000)]);
    assert!((homogeneity_p(&c, &d) - 1.0).abs() < 1e-12);
}
