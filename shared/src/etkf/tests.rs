//! Closed-form and statistical checks of the ET-KF (fixed seeds, CI tolerances).

use super::*;
use crate::gaussian::expected_rate;
use crate::rng::{stream_rng, streams};
use crate::scenario::Scenario;
use crate::stats::wilson_interval;

/// A 3-D plant with coupled dynamics, a 2-D sensor with correlated noise and an
/// oblique H: the innovation covariance is a full matrix, so the whitening
/// must use the eigenbasis, not the diagonal shortcut.
const ANISOTROPIC: &str = r#"
name = "aniso"
dim = 3
[model]
F = [[1.0, 0.1, 0.0], [0.0, 0.95, 0.05], [0.0, 0.0, 0.9]]
G = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
Q = [[0.004, 0.001, 0.0], [0.001, 0.003, 0.0005], [0.0, 0.0005, 0.002]]
x0 = [0.0, 0.0, 0.0]
P0 = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]]
[controller]
u_max = 0.05
eps_x = 0.05
k_max = 200
[[sensor]]
name = "s"
position = [0.0, 0.0, 0.0]
H = [[1.0, 0.5, 0.0], [0.0, 1.0, -0.7]]
R = [[0.002, 0.0008], [0.0008, 0.001]]
cost = 1.0
[[leg]]
to = [1.0, 0.0, 0.0]
sensor = "s"
[target]
min = [0.9, -1.0, -1.0]
max = [1.1, 1.0, 1.0]
[triggering]
deltas = [0.0, 1.0]
"#;

fn aniso() -> (Scenario, EtKalmanFilter<3, 2>) {
    let s = Scenario::from_toml(ANISOTROPIC).expect("valid test scenario");
    let f = EtKalmanFilter::<3, 2>::new(&s.plant, &s.sensors[0]);
    (s, f)
}

#[test]
fn riccati_steady_state_matches_the_scalar_closed_form() {
    // The paper's system per axis: F = H = 1, q = 0.07², r = 0.03².
    // Posterior P solves P = (P + q) r / (P + q + r)  ⇔  P² + qP − qr = 0.
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let f = EtKalmanFilter::<2, 2>::new(&s.plant, &s.sensors[0]);
    let (q, r) = (0.0049_f64, 0.0009_f64);
    let closed = (-q + (q * q + 4.0 * q * r).sqrt()) / 2.0;
    assert!((closed - 7.7686e-4).abs() < 1e-7);
    let p = f.steady_state_posterior();
    for i in 0..2 {
        assert!(
            (p[(i, i)] - closed).abs() < 1e-14,
            "P_KF[{i}{i}] = {} vs {closed}",
            p[(i, i)]
        );
    }
    assert_eq!(p[(0, 1)], 0.0);
}

#[test]
fn steady_state_is_a_fixed_point_of_the_full_filter() {
    let (_, f) = aniso();
    let p = f.steady_state_posterior();
    let b = Belief {
        mean: Vector::<3>::zeros(),
        cov: p,
    };
    let prior = f.predict(&b, &Vector::<3>::zeros());
    let inn = f.innovation(&prior);
    let y = inn.predicted; // any y: the covariance update does not depend on it
    let next = f.update_explicit(&prior, &inn, &y);
    assert!((next.cov - p).amax() < 1e-14);
}

#[test]
fn joseph_and_short_form_agree_for_the_optimal_gain() {
    let (_, f) = aniso();
    let prior = Belief {
        mean: Vector::<3>::zeros(),
        cov: Matrix::<3, 3>::identity() * 0.02,
    };
    let inn = f.innovation(&prior);
    let joseph = f.update_explicit(&prior, &inn, &inn.predicted).cov;
    let short = f.update_implicit(&prior, &inn, 1.0).cov;
    assert!((joseph - short).amax() < 1e-15);
}

#[test]
fn silence_at_large_delta_is_prediction_only() {
    let (_, f) = aniso();
    let prior = Belief {
        mean: Vector::<3>::zeros(),
        cov: Matrix::<3, 3>::identity() * 0.02,
    };
    let inn = f.innovation(&prior);
    let post = f.update_implicit(&prior, &inn, gaussian::beta(40.0));
    assert!((post.cov - prior.cov).amax() < 1e-15);
}

#[test]
fn whitened_innovation_of_the_full_filter_has_identity_covariance() {
    // Run the full KF (δ = 0) on the anisotropic system; ε_k are i.i.d. N(0, I).
    let (s, f) = aniso();
    let mut rng = stream_rng(11, streams::SIMULATE, 0);
    let mut b = LinearPlant::<3>::initial_belief(&s.plant);
    let mut x = sample_belief(&b, &mut rng);
    let n = 200_000;
    let mut sum = Vector::<2>::zeros();
    let mut outer = Matrix::<2, 2>::zeros();
    let u = Vector::<3>::zeros();
    for _ in 0..n {
        x = f.plant.step(&x, &u, &mut rng);
        let y = f.sensor.measure(&x, &mut rng);
        let prior = f.predict(&b, &u);
        let inn = f.innovation(&prior);
        assert!(
            matches!(inn.whitener(), Whitener::Basis(_)),
            "full Z must use the eigenbasis"
        );
        let e = inn.whitened(&y);
        sum += e;
        outer += e * e.transpose();
        b = f.update_explicit(&prior, &inn, &y);
    }
    let nf = n as f64;
    let mean = sum / nf;
    let cov = outer / nf - mean * mean.transpose();
    // Sampling sd of a mean: 1/√n ≈ 0.0022; of a variance: √(2/n) ≈ 0.0032;
    // of a covariance: 1/√n. Tolerance 4.5 sd.
    for i in 0..2 {
        assert!(mean[i].abs() < 4.5 / nf.sqrt(), "mean {mean}");
        assert!(
            (cov[(i, i)] - 1.0).abs() < 4.5 * (2.0 / nf).sqrt(),
            "cov {cov}"
        );
    }
    assert!(cov[(0, 1)].abs() < 4.5 / nf.sqrt(), "cov {cov}");
}

#[test]
fn first_step_trigger_frequency_matches_expected_rate() {
    // At the first step the prior is exactly Gaussian, so P(‖ε‖∞ > δ) = γ̄(δ).
    let (s, f) = aniso();
    let b0 = LinearPlant::<3>::initial_belief(&s.plant);
    let u = Vector::<3>::zeros();
    let n = 100_000_u64;
    for (i, delta) in [0.0, 0.5, 1.0518, 1.9488, 2.2365].into_iter().enumerate() {
        let mut rng = stream_rng(12, streams::SIMULATE, i as u64);
        let prior = f.predict(&b0, &u);
        let inn = f.innovation(&prior);
        let mut hits = 0_u64;
        for _ in 0..n {
            let x0 = sample_belief(&b0, &mut rng);
            let x1 = f.plant.step(&x0, &u, &mut rng);
            let y = f.sensor.measure(&x1, &mut rng);
            hits += u64::from(inn.triggers(&y, delta));
        }
        let expected = expected_rate(delta, 2);
        let (lo, hi) = wilson_interval(hits, n);
        // 95 % Wilson interval, widened by half its width for multiple comparisons.
        let slack = 0.5 * (hi - lo);
        assert!(
            lo - slack <= expected && expected <= hi + slack,
            "δ = {delta}: measured {hits}/{n}, expected rate {expected}"
        );
    }
}

#[test]
fn whitening_is_basis_independent_in_distribution_but_deterministic() {
    let z = Matrix::<2, 2>::new(2.0, 0.5, 0.5, 1.0);
    let w1 = Whitener::new(&z);
    let w2 = Whitener::new(&z);
    let v = Vector::<2>::new(0.3, -0.7);
    assert_eq!(w1.whiten(&v), w2.whiten(&v));
    // ε = W z has Cov = W Z Wᵀ = I.
    if let Whitener::Basis(w) = w1 {
        let c = w * z * w.transpose();
        assert!((c - Matrix::<2, 2>::identity()).amax() < 1e-12);
    } else {
        panic!("full matrix must not take the diagonal path");
    }
}

#[test]
fn position_only_whitening_gives_identity_covariance() {
    // MODEL.md §7: a double integrator seen through H = [I 0] with a rotated
    // anisotropic R. Draw x ~ N(x̂⁻, P⁻) and y ~ N(Hx, R): ε = W(y − Hx̂⁻) must
    // have identity covariance. 20 000 draws: each entry of the sample
    // covariance has standard error ≤ √(2/20000) = 0.01; tolerance 5 s.e.
    let s = Scenario::from_toml(include_str!("../testdata/double-integrator.toml")).expect("valid");
    let f = EtKalmanFilter::<4, 2>::new(&s.plant, &s.sensors[0]);
    let mut prior = f.predict(
        &Belief {
            mean: Vector::<4>::new(1.0, 2.0, 0.3, -0.1),
            cov: f.steady_state_posterior(),
        },
        &Vector::<4>::zeros(),
    );
    // Correlate position and velocity more strongly than the filter would.
    prior.cov[(0, 3)] += 2e-4;
    prior.cov[(3, 0)] += 2e-4;
    let inn = f.innovation(&prior);
    assert!(
        matches!(inn.whitener(), Whitener::Basis(_)),
        "Z is a full matrix"
    );
    let mut rng = stream_rng(11, streams::SIMULATE, 0);
    let n = 20_000;
    let mut acc = Matrix::<2, 2>::zeros();
    let mut mean = Vector::<2>::zeros();
    for _ in 0..n {
        let x = sample_belief(&prior, &mut rng);
        let y = f.sensor.measure(&x, &mut rng);
        let e = inn.whitened(&y);
        acc += e * e.transpose();
        mean += e;
    }
    let cov = acc / f64::from(n);
    assert!((cov - Matrix::<2, 2>::identity()).amax() < 0.05, "{cov}");
    assert!((mean / f64::from(n)).amax() < 0.05);
}
