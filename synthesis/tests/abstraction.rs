//! The belief abstraction (docs/MODEL.md §4) against cases with known answers, its
//! invariants on the built-in scenarios, and its determinism.

use etp_shared::gaussian::normal_cdf;
use etp_shared::scenario::Scenario;
use etp_synthesis::abstraction::{self, AbstractionParams};
use etp_synthesis::mdp::{Method, Next};
use std::sync::atomic::{AtomicU64, Ordering};

/// A 1-D corridor without obstacles: two legs (0 → 1 → 2), F = G = H = 1,
/// q = r = 0.01, thresholds {0, 1}. `eps_x` is tiny, so every leg runs exactly
/// `k_max` steps, and `u_max` is so large that the prior mean lands on the
/// waypoint at every step; with δ = 0 the
/// filter is the exact Kalman filter, so at the end `x − w ~ N(0, P_KF + q)`.
fn corridor(k_max: u32, half_width: f64) -> Scenario {
    let text = format!(
        r#"
name = "corridor-1d"
description = "analytic test case"
dim = 1

[model]
F = [[1.0]]
G = [[1.0]]
Q = [[0.01]]
x0 = [0.0]
P0 = [[0.01]]

[controller]
u_max = 2.0
eps_x = 1e-12
k_max = {k_max}

[[sensor]]
name = "s0"
position = [1.0]
H = [[1.0]]
R = [[0.01]]
cost = 1.0

[[leg]]
to = [1.0]
sensor = "s0"

[[leg]]
to = [2.0]
sensor = "s0"

[target]
min = [{lo}]
max = [{hi}]

[triggering]
deltas = [0.0, 1.0]
"#,
        lo = 2.0 - half_width,
        hi = 2.0 + half_width,
    );
    Scenario::from_toml(&text).expect("valid test scenario")
}

fn params(samples: u32) -> AbstractionParams {
    AbstractionParams {
        samples,
        seed: 7,
        ..AbstractionParams::default()
    }
}

#[test]
fn corridor_has_known_transitions_and_costs() {
    let (k_max, a) = (40, 0.15);
    let s = corridor(k_max, a);
    let samples = 20_000;
    let mdp = abstraction::build(&s, &params(samples), &|_: u64| {}).expect("builds");
    mdp.check().expect("consistent");
    // The full KF always ends in the same covariance (P_KF, the lowest
    // magnitude bin): one successor with probability 1, no obstacle.
    let d0 = &mdp.states[0].choices[0];
    assert_eq!(d0.action, 0);
    assert_eq!(d0.transitions.len(), 1);
    assert_eq!(d0.transitions[0].probability, 1.0);
    let Next::State(j) = d0.transitions[0].next else {
        panic!("δ = 0 must reach decision point 1");
    };
    let kf_state = &mdp.states[j as usize];
    assert_eq!(kf_state.decision_point, 1);
    assert_eq!(kf_state.region.0, vec![(0, 0)]);
    // δ = 1 ends with larger covariances: other regions exist at decision point 1.
    assert!(mdp.states_per_decision_point()[1] > 1);
    // Every slot transmits at δ = 0 and every leg lasts k_max steps.
    assert_eq!(d0.mean_steps, f64::from(k_max));
    assert_eq!(d0.cost_counted, f64::from(k_max));
    assert_eq!(d0.cost_model, f64::from(k_max));
    // The silent threshold transmits less, and the paper's model is close to the count.
    let d1 = &mdp.states[0].choices[1];
    assert!(
        d1.cost_counted < 0.6 * d0.cost_counted,
        "{}",
        d1.cost_counted
    );

    // Target probability of the last leg: 2Φ(a/σ) − 1 with σ² = P_KF + q.
    let (q, r) = (0.01_f64, 0.01_f64);
    let p_kf = (-q + (q * q + 4.0 * q * r).sqrt()) / 2.0;
    let expected = 2.0 * normal_cdf(a / (p_kf + q).sqrt()) - 1.0;
    let last = &kf_state.choices[0];
    let tar = last
        .transitions
        .iter()
        .find(|t| t.next == Next::Target)
        .expect("target reached");
    assert!(
        tar.ci_low <= expected && expected <= tar.ci_high,
        "P(tar) {} [{}, {}] vs closed form {expected}",
        tar.probability,
        tar.ci_low,
        tar.ci_high
    );
    let free = last
        .transitions
        .iter()
        .find(|t| t.next == Next::Free)
        .expect("free");
    assert_eq!(tar.count + free.count, samples);
    assert!(last.transitions.iter().all(|t| t.next != Next::Collision));
}

#[test]
fn every_choice_is_a_distribution_with_counted_cost() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let p = params(150);
    let units = AtomicU64::new(0);
    let mdp = abstraction::build(&s, &p, &|k| {
        units.fetch_add(k, Ordering::Relaxed);
    })
    .expect("builds");
    assert_eq!(
        units.load(Ordering::Relaxed),
        abstraction::progress_total(&s, &p)
    );
    mdp.check().expect("consistent");
    assert_eq!(mdp.num_decision_points(), s.num_legs());
    let mut segments = 0u64;
    for st in &mdp.states {
        assert_eq!(st.choices.len(), s.deltas.len());
        for c in &st.choices {
            let sum: f64 = c.transitions.iter().map(|t| t.probability).sum();
            assert!((sum - 1.0).abs() < 1e-12, "sum {sum}");
            let counts: u32 = c.transitions.iter().map(|t| t.count).sum();
            assert_eq!(counts, c.samples);
            assert_eq!(c.samples, p.samples);
            for t in &c.transitions {
                assert!(t.ci_low <= t.probability && t.probability <= t.ci_high);
            }
            // Counted cost: transmissions per segment are integers ≤ steps (c_m = 1).
            assert!(c.cost_counted <= c.mean_steps + 1e-9);
            let total = c.cost_counted * f64::from(c.samples);
            assert!((total - total.round()).abs() < 1e-6, "{total}");
            segments += u64::from(c.samples);
        }
    }
    assert_eq!(segments, mdp.total_segments);
    // Every segment leaving decision point i either arrives in a state of
    // decision point i + 1 or ends: the arrivals balance the departures.
    let arrivals = mdp.arrivals_per_state();
    assert_eq!(arrivals[mdp.initial as usize], 0);
    for dp in 0..mdp.num_decision_points() as u32 {
        let leaving: u64 = mdp
            .states
            .iter()
            .filter(|st| st.decision_point == dp)
            .flat_map(|st| &st.choices)
            .flat_map(|c| &c.transitions)
            .filter(|t| matches!(t.next, Next::State(_)))
            .map(|t| u64::from(t.count))
            .sum();
        let arriving: u64 = mdp
            .states
            .iter()
            .zip(&arrivals)
            .filter(|(st, _)| st.decision_point == dp + 1)
            .map(|(_, &a)| a)
            .sum();
        assert_eq!(leaving, arriving, "decision point {dp}");
    }
    // The full KF (δ = 0) transmits in every slot: cost = slots ≈ steps.
    for st in &mdp.states {
        let c = &st.choices[0];
        assert!(c.cost_counted > 0.95 * c.mean_steps && c.cost_model == c.cost_counted);
    }
}

#[test]
fn isotropic_system_uses_magnitudes_only() {
    for name in ["winding-2d", "superg-3d"] {
        let s = Scenario::builtin(name).expect("built-in");
        let mdp = abstraction::build(&s, &params(60), &|_: u64| {}).expect("builds");
        let d = mdp.discretization.as_ref().expect("Method 2 has bins");
        assert_eq!(d.decision_points.len(), s.num_legs());
        for st in &mdp.states {
            assert_eq!(st.region.0.len(), s.dim);
            let m0 = st.region.0[0].0;
            for &(m, a) in &st.region.0 {
                assert_eq!(a, 0, "{name}: angle bin in {}", st.region);
                assert_eq!(m, m0, "{name}: a multiple of I has equal magnitudes");
            }
        }
        assert!(
            mdp.states.len() > s.num_legs(),
            "{name}: more than one region somewhere"
        );
    }
}

#[test]
fn method_one_has_one_state_per_decision_point() {
    let s = Scenario::builtin("open-2d").expect("built-in");
    let p = AbstractionParams {
        method: Method::KfConvergence,
        ..params(100)
    };
    let mdp = abstraction::build(&s, &p, &|_: u64| {}).expect("builds");
    mdp.check().expect("consistent");
    // |S| = N + 3 with the three terminals.
    assert_eq!(mdp.states.len() + 3, s.num_legs() + 3);
    assert!(mdp.discretization.is_none());
    let kf = mdp.kf_convergence.expect("parameters stored");
    assert!(kf.eps_kf > 0.0 && kf.eps_p > 0.0);
    for (i, st) in mdp.states.iter().enumerate() {
        assert_eq!(st.decision_point as usize, i);
        // Costs include the enforced full-KF slots: even the largest δ pays for them.
        let last = st.choices.last().expect("choices");
        assert!(last.cost_counted >= 1.0, "{}", last.cost_counted);
    }
}

#[test]
fn same_seed_same_bytes_any_thread_count() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let p = params(80);
    let a = abstraction::build(&s, &p, &|_: u64| {})
        .expect("builds")
        .encode();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool")
        .install(|| {
            abstraction::build(&s, &p, &|_: u64| {})
                .expect("builds")
                .encode()
        });
    assert!(a == one, "1 thread vs all threads differ");
    let other = abstraction::build(&s, &AbstractionParams { seed: 8, ..p }, &|_: u64| {})
        .expect("builds")
        .encode();
    assert!(a != other, "another seed gives another MDP");
}

#[test]
fn bad_parameters_are_refused() {
    let s = corridor(10, 0.1);
    assert!(abstraction::build(&s, &params(0), &|_: u64| {}).is_err());
    let bins = AbstractionParams {
        bins: etp_shared::discretization::BinCounts {
            magnitude: 0,
            angle: 1,
        },
        ..params(10)
    };
    assert!(abstraction::build(&s, &bins, &|_: u64| {}).is_err());
}

/// `(E[energy], P_coll, P_tar)` of the constant action `a` on the MDP, by one
/// backward pass (states are sorted by decision point, transitions go forward).
fn constant_action_values(mdp: &etp_synthesis::mdp::Mdp, a: u16) -> (f64, f64, f64) {
    let mut v = vec![(0.0, 0.0, 0.0); mdp.states.len()];
    for i in (0..mdp.states.len()).rev() {
        let c = mdp.states[i]
            .choices
            .iter()
            .find(|c| c.action == a)
            .expect("action available");
        let mut acc = (c.cost_counted, 0.0, 0.0);
        for t in &c.transitions {
            let (e, pc, pt) = match t.next {
                Next::State(j) => v[j as usize],
                Next::Collision => (0.0, 1.0, 0.0),
                Next::Target => (0.0, 0.0, 1.0),
                Next::Free => (0.0, 0.0, 0.0),
            };
            acc.0 += t.probability * e;
            acc.1 += t.probability * pc;
            acc.2 += t.probability * pt;
        }
        v[i] = acc;
    }
    v[mdp.initial as usize]
}

#[test]
fn constant_threshold_prediction_matches_simulation() {
    use etp_shared::episode::{CompiledScenario, LegMode};
    use etp_shared::etkf::Threshold;
    use etp_shared::rng::streams;
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let mdp = abstraction::build(&s, &params(1500), &|_: u64| {}).expect("builds");
    let cs = CompiledScenario::<2>::new(&s);
    for a in [0u16, 2, 4] {
        let (energy, p_coll, p_tar) = constant_action_values(&mdp, a);
        let t = Threshold::new(s.deltas[a as usize]);
        let policy = move |_: usize, _: &_, _: &mut _| LegMode::<2>::EventTriggered(t);
        let sim = etp_synthesis::simulate::simulate(
            &cs,
            &policy,
            4000,
            11,
            streams::VALIDATE,
            &|_: u64| {},
        )
        .expect("simulates")
        .summary();
        let e_err = (energy - sim.energy_mean.value).abs() / sim.energy_mean.value;
        eprintln!(
            "δ#{a}: MDP (E {energy:.2}, P_coll {p_coll:.4}, P_tar {p_tar:.4}) vs simulated (E {:.2} ± {:.2}, P_coll {:.4} ± {:.4}, P_tar {:.4} ± {:.4})",
            sim.energy_mean.value,
            sim.energy_mean.ci95,
            sim.p_collision.value,
            sim.p_collision.ci95,
            sim.p_target.value,
            sim.p_target.ci95
        );
        assert!(
            e_err < 0.04,
            "δ#{a}: energy {energy} vs simulated {:?}",
            sim.energy_mean
        );
        assert!(
            (p_coll - sim.p_collision.value).abs() < sim.p_collision.ci95 + 0.015,
            "δ#{a}: P_coll {p_coll} vs simulated {:?}",
            sim.p_collision
        );
        assert!(
            (p_tar - sim.p_target.value).abs() < sim.p_target.ci95 + 0.015,
            "δ#{a}: P_tar {p_tar} vs simulated {:?}",
            sim.p_target
        );
    }
}

#[test]
fn arrival_range_puts_the_workspace_bins_where_the_beliefs_are() {
    // MODEL.md §7.3: a double integrator's silent propagation grows without
    // bound, so the propagation range reaches far past any arrival; the
    // arrivals rule closes each decision point's range at the 99.5 %
    // quantile of what arrived, inside the propagation range.
    let s = Scenario::from_toml(include_str!(
        "../../shared/src/testdata/double-integrator.toml"
    ))
    .expect("valid");
    let build = |range| {
        let p = AbstractionParams {
            range,
            ..params(200)
        };
        abstraction::build(&s, &p, &|_: u64| {}).expect("builds")
    };
    let arrivals = build(abstraction::RangeRule::Arrivals);
    let propagation = build(abstraction::RangeRule::Propagation);
    let (a, p) = (
        arrivals.discretization.as_ref().expect("Method 2"),
        propagation.discretization.as_ref().expect("Method 2"),
    );
    assert!(a.decision_points.len() > 1, "needs a second decision point");
    for (dp, (ba, bp)) in a
        .decision_points
        .iter()
        .zip(&p.decision_points)
        .enumerate()
        .skip(1)
    {
        assert!(ba.workspace.is_some(), "the workspace descriptor");
        assert!(
            bp.lambda_lo <= ba.lambda_lo && ba.lambda_hi < bp.lambda_hi,
            "dp {dp}: arrivals [{}, {}] inside propagation [{}, {}]",
            ba.lambda_lo,
            ba.lambda_hi,
            bp.lambda_lo,
            bp.lambda_hi
        );
    }
    // The rule is recorded, and a rebuild from the file's parameters repeats it.
    assert_eq!(arrivals.build.range, 1);
    assert_eq!(
        abstraction::params_of(&arrivals).range,
        abstraction::RangeRule::Arrivals
    );
}
