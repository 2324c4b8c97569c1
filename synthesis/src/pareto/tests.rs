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
    // Per leg: decision point 0 (state 0) spends its choices' mean energy,
    // the legs add up to the whole.
    let legs = leg_energy(&m, &pol, CostModel::Counted);
    assert_eq!(legs.len(), m.num_decision_points());
    let first: f64 = (0..2)
        .map(|c| pol[0][c] * m.states[0].choices[c].cost_counted)
        .sum();
    assert!((legs[0] - first).abs() < 1e-12, "{legs:?}");
    assert!(
        (legs.iter().sum::<f64>() - v.energy).abs() < 1e-12,
        "{legs:?}"
    );
    let s = to_strategy(&m, &pol, "t".into(), v);
    assert_eq!(s.predictions.leg_energy.as_deref(), Some(legs.as_slice()));
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
        let (_, lp) = super::optimal::solve_occupation_lp(
            &m,
            CostModel::Counted,
            super::optimal::LpRequest::MinEnergy {
                min_target: target,
                max_collision: None,
            },
        )
        .expect("feasible");
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

#[test]
fn the_certified_gap_bounds_every_weighted_optimum() {
    use crate::synthetic::{SyntheticParams, layered_mdp};
    // A coarse tolerance leaves real gaps for the certificate to cover.
    let m = layered_mdp(&SyntheticParams {
        states: 300,
        layers: 6,
        ..SyntheticParams::default()
    });
    let scale = 100.0;
    let en = enumerate::enumerate_front_to(&m, scale, CostModel::Counted, 1e-3).expect("front");
    assert!(en.epsilon > 0.0 && en.epsilon < 2e-3, "ε = {}", en.epsilon);
    // For every weight λ ≥ 0 (Σλ = 1) the exact optimum v_λ is within ε of the
    // best vertex: min_k λ·f_k ≤ v_λ + ε, a consequence of the certificate.
    let mut worst = 0.0_f64;
    let mut rng = etp_shared::rng::stream_rng(9, 99, 0);
    use rand::RngExt;
    for _ in 0..400 {
        let raw: [f64; 3] = [rng.random(), rng.random(), rng.random()];
        let total: f64 = raw.iter().sum();
        let lambda = raw.map(|x| x / total);
        let v = weighted_optimum(&m, lambda, scale, CostModel::Counted).bound;
        let best = en
            .vertices
            .iter()
            .map(|&i| {
                let f = en.points[i].f;
                lambda[0] * f[0] + lambda[1] * f[1] + lambda[2] * f[2]
            })
            .fold(f64::INFINITY, f64::min);
        assert!(best >= v - 1e-12, "a vertex beats the exact optimum");
        worst = worst.max(best - v);
    }
    assert!(
        worst <= en.epsilon + 1e-12,
        "gap {worst} > certified ε {}",
        en.epsilon
    );
    assert!(worst > 0.0, "the coarse front should leave some gap");
}

#[test]
fn the_front_is_reproducible_bit_for_bit() {
    use crate::synthetic::{SyntheticParams, layered_mdp};
    let m = layered_mdp(&SyntheticParams {
        states: 400,
        layers: 8,
        ..SyntheticParams::default()
    });
    let a = compute_front(&m, CostModel::Counted).expect("front");
    let b = compute_front(&m, CostModel::Counted).expect("front");
    assert_eq!(a.to_json(), b.to_json());
}

#[test]
fn exact_strategies_meet_their_request_in_their_own_evaluation() {
    use super::optimal::{LpRequest, optimal_strategy, solve_occupation_lp};
    let m = toy();
    for target in [0.4, 0.6, 0.8, 0.855] {
        let r = LpRequest::MinEnergy {
            min_target: target,
            max_collision: None,
        };
        let s = optimal_strategy(&m, CostModel::Counted, r).expect("feasible");
        assert!(s.predicted.p_target >= target);
        let (_, lp) = solve_occupation_lp(&m, CostModel::Counted, r).expect("lp");
        assert!(
            (s.predicted.energy - lp).abs() <= 1e-9 * lp,
            "{s:?} vs {lp}"
        );
        // No mixture of deterministic policies does better (brute force).
        let f = compute_front(&m, CostModel::Counted).expect("front");
        let sel = select(
            &f,
            Request::MinTarget {
                min_target: target,
                max_collision: None,
            },
        )
        .expect("feasible");
        assert!(s.predicted.energy <= sel.predicted.energy + 1e-9);
    }
    // Beyond the highest P_tar (0.855): infeasible, with the best values.
    let e = optimal_strategy(
        &m,
        CostModel::Counted,
        LpRequest::MinEnergy {
            min_target: 0.9,
            max_collision: None,
        },
    )
    .expect_err("beyond 0.855");
    assert!(e.to_string().contains("0.8550"), "{e}");
}
