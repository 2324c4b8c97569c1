use super::policy::*;
use super::select::*;
use super::*;
use crate::mdp::tests::toy;

#[test]
fn backward_induction_on_the_toy_mdp() {
    let m = toy();
    // Max target: δ0 then δ0 (0.9·0.95 = 0.855) vs δ1 then δ0 (0.7·0.9 = 0.63).
    let (p, v) = backward_induction(&m, [0.0, 0.0, 1.0], 1.0, CostModel::Counted);
    assert_eq!(p[0], 0);
    assert!((v.p_target - 0.855).abs() < 1e-12);
    assert!((v.energy - (10.0 + 0.9 * 10.0)).abs() < 1e-12);
    // Min energy: δ1 everywhere: 2 + 0.7·2.
    let (_, v) = backward_induction(&m, [1.0, 0.0, 0.0], 1.0, CostModel::Counted);
    assert!((v.energy - 3.4).abs() < 1e-12);
    assert!((v.p_collision - (0.3 + 0.7 * 0.5)).abs() < 1e-12);
}

#[test]
fn occupation_of_a_policy_reproduces_its_values() {
    let m = toy();
    let pol = vec![vec![0.5, 0.5], vec![0.2, 0.8], vec![1.0, 0.0]];
    let v = evaluate(&m, &pol, CostModel::Counted);
    let x = occupation(&m, &pol);
    let energy: f64 = (0..3)
        .flat_map(|s| (0..2).map(move |c| (s, c)))
        .map(|(s, c)| x[s][c] * m.states[s].choices[c].cost_counted)
        .sum();
    assert!((energy - v.energy).abs() < 1e-12);
    assert!((x[1].iter().sum::<f64>() - 0.45).abs() < 1e-12);
}

#[test]
fn front_contains_every_deterministic_pareto_point_and_dominates_baselines() {
    let m = toy();
    let f = compute_front(&m, CostModel::Counted).expect("front");
    assert!(f.vertices.len() >= 2);
    // Every deterministic policy is weakly above the front: for each, some
    // convex combination of vertices is at least as good in all objectives —
    // checked with the vertex LP (least energy at its P_tar and P_coll).
    for a in 0..2_u16 {
        for b in 0..2_u16 {
            for c in 0..2_u16 {
                let pol = as_randomised(&m, &vec![a, b, c]);
                let o = evaluate(&m, &pol, CostModel::Counted);
                let sel = select(
                    &f,
                    Request::MinTarget {
                        min_target: o.p_target - 1e-9,
                        max_collision: Some(o.p_collision + 1e-9),
                    },
                )
                .expect("feasible");
                assert!(
                    sel.predicted.energy <= o.energy + 1e-7,
                    "policy {a}{b}{c}: {o:?} vs {:?}",
                    sel.predicted
                );
            }
        }
    }
    for b in &f.baselines {
        let sel = select(
            &f,
            Request::MinTarget {
                min_target: b.objectives.p_target - 1e-9,
                max_collision: Some(b.objectives.p_collision + 1e-9),
            },
        )
        .expect("feasible");
        assert!(sel.predicted.energy <= b.objectives.energy + 1e-7);
    }
}

#[test]
fn realised_strategy_attains_the_mixture_and_matches_the_occupation_lp() {
    let m = toy();
    let f = compute_front(&m, CostModel::Counted).expect("front");
    for target in [0.4, 0.5, 0.6, 0.7, 0.8, 0.85] {
        let sel = select(
            &f,
            Request::MinTarget {
                min_target: target,
                max_collision: None,
            },
        )
        .expect("feasible");
        let omega = realise(&m, &f, &sel);
        let v = evaluate(&m, &omega, CostModel::Counted);
        assert!(
            (v.energy - sel.predicted.energy).abs() < 1e-9,
            "{v:?} vs {:?}",
            sel.predicted
        );
        assert!((v.p_target - sel.predicted.p_target).abs() < 1e-9);
        let lp = occupation_lp_min_energy(&m, CostModel::Counted, target, None).expect("feasible");
        assert!(
            (lp - sel.predicted.energy).abs() < 1e-6,
            "occupation LP {lp} vs vertex LP {}",
            sel.predicted.energy
        );
    }
}

#[test]
fn infeasible_requests_name_the_best_achievable() {
    let m = toy();
    let f = compute_front(&m, CostModel::Counted).expect("front");
    let e = select(
        &f,
        Request::MinTarget {
            min_target: 0.99,
            max_collision: None,
        },
    )
    .expect_err("P_tar 0.99 is beyond 0.855");
    let msg = e.to_string();
    assert!(
        msg.contains("infeasible") && msg.contains("0.8550"),
        "{msg}"
    );
    assert!(matches!(
        select(&f, Request::Vertex(99)),
        Err(SelectError::NoSuchVertex(99, _))
    ));
}
