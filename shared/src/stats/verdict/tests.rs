//! The verdict against closed forms, and its family-wise coverage on
//! simulated honest strategies (known truth, seeded).

use super::*;
use crate::rng::stream_rng;
use crate::strategy::{CertifiedPrediction, Prediction, PredictionCi95};
use rand::RngExt;
use rand_distr::{Distribution, Exp, Normal};

#[test]
fn bonferroni_z_values_match_the_normal_quantiles() {
    // Φ⁻¹(1 − 0.05/(2m)) (Python: statistics.NormalDist().inv_cdf).
    assert!((Family::of(1).z() - 1.959_963_984_540_053_6).abs() < 1e-9);
    assert!((Family::of(3).z() - 2.393_979_799_818_510_4).abs() < 1e-9);
    assert!((Family::of(6).z() - 2.638_257_273_476_751).abs() < 1e-9);
    assert!((Family::of(6).per_check_level() - (1.0 - 0.05 / 6.0)).abs() < 1e-15);
}

#[test]
fn a_symmetric_interval_joins_the_predictions_own_in_quadrature() {
    // Mean 10, se 1; prediction's own ± 1.96 (se 1) → |x − 10| ≤ z √2.
    let m = Measured::Mean {
        value: 10.0,
        se: 1.0,
    };
    let z = Family::of(3).z();
    let edge = 10.0 + z * 2f64.sqrt();
    assert!(agreement(edge - 1e-9, Z95, &m, z).inside);
    assert!(!agreement(edge + 1e-9, Z95, &m, z).inside);
    assert!(!agreement(20.0 - edge - 1e-9, Z95, &m, z).inside);
    // One episode: no interval, nothing judged outside; NaN never inside.
    let one = Measured::mean(&{
        let mut a = MeanAccumulator::default();
        a.push(3.0);
        a
    });
    assert!(agreement(1e9, 0.0, &one, z).inside);
    assert!(!agreement(f64::NAN, 0.0, &m, z).inside);
}

#[test]
fn a_family_counts_only_what_was_measured() {
    let p = Prediction {
        p_target: 0.9,
        p_collision: 0.02,
        p_free: 0.08,
        energy_mean: 50.0,
    };
    let mut m = Outcomes::count(90, 2, 100, &[49.0, 51.0, 50.0]);
    let (f, checks) = prediction_checks(Some(&p), None, None, &m);
    assert_eq!((f.checks, checks.len()), (3, 3));
    assert!(checks.iter().all(|c| c.holds), "{checks:?}");
    m.energy = None;
    let (f, checks) = prediction_checks(Some(&p), None, None, &m);
    assert_eq!(f.checks, 2);
    assert_eq!(
        checks.iter().map(|c| c.key).collect::<Vec<_>>(),
        ["p_target", "p_collision"]
    );
    assert_eq!(prediction_checks(None, None, None, &m).1, vec![]);
}

#[test]
fn ten_of_ten_is_not_one_plus_minus_zero() {
    // `run`: P_tar 1.0000 [0.7225, 1.0000] on 10 episodes; a prediction of
    // 0.89958 lies inside (a normal approximation said 1 ± 0: outside).
    let m = Measured::Proportion { k: 10, n: 10 };
    let (lo, hi) = m.interval(Z95);
    assert!((lo - 0.722_467_200_137_110_9).abs() < 1e-12 && hi == 1.0);
    assert!(agreement(0.89958, 0.0, &m, Z95).inside);
    let e = m.estimate();
    assert_eq!(e.value, 1.0);
    assert!((e.ci95 - (1.0 - lo)).abs() < 1e-15);
}

/// One honest strategy's validation on `n` episodes: the truth drawn, the
/// prediction = truth + its own stated noise, the certified bounds at the
/// truth (the tightest honest bound), the episodes simulated. Whether all
/// the family's checks hold, and whether all would at 95 % each.
fn honest_validation(index: u64, n: u64, certified: bool) -> (bool, bool) {
    let mut rng = stream_rng(52, 0xC0FE, index);
    let p_target: f64 = rng.random_range(0.80..0.97);
    let p_collision: f64 = rng.random_range(0.005..0.03);
    let energy_mean: f64 = rng.random_range(40.0..160.0);
    let (mut target, mut collision) = (0u64, 0u64);
    let mut energies = Vec::with_capacity(n as usize);
    let exp = Exp::new(1.0 / energy_mean).expect("rate");
    for _ in 0..n {
        let u: f64 = rng.random();
        if u < p_target {
            target += 1;
        } else if u < p_target + p_collision {
            collision += 1;
        }
        energies.push(exp.sample(&mut rng));
    }
    let m = Outcomes::count(target, collision, n, &energies);
    // The prediction's own 95 % ±: up to twice the simulation's.
    let sim = |x: f64| Z95 * (x * (1.0 - x) / n as f64).sqrt();
    let own = PredictionCi95 {
        p_target: rng.random_range(0.0..2.0) * sim(p_target),
        p_collision: rng.random_range(0.0..2.0) * sim(p_collision),
        energy_mean: rng.random_range(0.0..2.0) * Z95 * energy_mean / (n as f64).sqrt(),
    };
    let noisy = |rng: &mut crate::rng::SimRng, x: f64, ci: f64| {
        x + Normal::new(0.0, ci / Z95).expect("sd").sample(rng)
    };
    let predicted = Prediction {
        p_target: noisy(&mut rng, p_target, own.p_target),
        p_collision: noisy(&mut rng, p_collision, own.p_collision),
        p_free: 0.0,
        energy_mean: noisy(&mut rng, energy_mean, own.energy_mean),
    };
    let bounds = CertifiedPrediction {
        confidence: 0.95,
        p_target_low: p_target,
        p_collision_high: p_collision,
        energy_high: energy_mean,
        covers_aggregation: true,
    };
    let (_, checks) = prediction_checks(
        Some(&predicted),
        Some(&own),
        certified.then_some(&bounds),
        &m,
    );
    let each_at_95 = [
        (predicted.p_target, own.p_target, m.p_target),
        (predicted.p_collision, own.p_collision, m.p_collision),
        (predicted.energy_mean, own.energy_mean, m.energy),
    ]
    .iter()
    .all(|(x, w, measured)| agreement(*x, *w, &measured.expect("measured"), Z95).inside);
    (checks.iter().all(|c| c.holds), each_at_95)
}

/// Coverage `k` of `n` with its Wilson 99 % interval.
fn coverage(k: u64, n: u64) -> (f64, f64, f64) {
    let (lo, hi) = wilson_interval_z(k, n, z_two_sided(0.99));
    (k as f64 / n as f64, lo, hi)
}

#[test]
fn an_honest_strategy_passes_the_family_95_percent_of_the_time() {
    // 1000 honest strategies' validations of 3000 episodes each.
    let (runs, n) = (1000u64, 3000u64);
    let (mut all3, mut all6, mut each95) = (0u64, 0u64, 0u64);
    for i in 0..runs {
        let (holds3, at95) = honest_validation(i, n, false);
        all3 += u64::from(holds3);
        each95 += u64::from(at95);
        all6 += u64::from(honest_validation(runs + i, n, true).0);
    }
    // Three two-sided checks (`run`, `replay`, a --quick-free validation):
    // Bonferroni over nearly independent checks is nearly exact: 95 % lies in
    // the 99 % interval of the coverage measured.
    let (c3, lo3, hi3) = coverage(all3, runs);
    assert!(lo3 <= 0.95 && 0.95 <= hi3, "3 checks: {c3} [{lo3}, {hi3}]");
    // Six (with certified bounds at the truth, one-sided): at least 95 %,
    // and not uselessly wide (at most 97.5 %).
    let (c6, lo6, hi6) = coverage(all6, runs);
    assert!(hi6 >= 0.95 && lo6 <= 0.975, "6 checks: {c6} [{lo6}, {hi6}]");
    // The same three checks at 95 % each fail an honest strategy far more
    // often than 5 % of the time: what the family corrects.
    let (c1, _, hi1) = coverage(each95, runs);
    assert!(hi1 < 0.93, "95 % each: {c1}");
    eprintln!(
        "honest validations: all 3 checks hold in {c3} [{lo3:.4}, {hi3:.4}], all 6 in {c6} [{lo6:.4}, {hi6:.4}], 3 at 95 % each in {c1}"
    );
}
