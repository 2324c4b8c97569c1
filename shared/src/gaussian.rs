//! Scalar Gaussian facts the ET-KF needs: φ, Φ, the implicit-information factor
//! β(δ) and the expected transmission rate γ̄(δ).

use std::f64::consts::{FRAC_1_SQRT_2, PI};

/// Standard normal density φ(t).
pub fn normal_pdf(t: f64) -> f64 {
    (-0.5 * t * t).exp() / (2.0 * PI).sqrt()
}

/// Standard normal distribution function Φ(t).
pub fn normal_cdf(t: f64) -> f64 {
    0.5 * libm::erfc(-t * FRAC_1_SQRT_2)
}

/// P(|ε| ≤ δ) = 2Φ(δ) − 1 for ε ~ N(0, 1), computed without cancellation.
pub fn prob_within(delta: f64) -> f64 {
    libm::erf(delta * FRAC_1_SQRT_2)
}

/// β(δ) = 2δφ(δ) / (2Φ(δ) − 1) = 1 − Var[ε | |ε| ≤ δ]: the share of the
/// innovation variance removed by the *absence* of a transmission.
///
/// β(0) = 1 (the limit: silence at δ = 0 would pin the innovation to 0) and
/// β(δ) → 0 as δ → ∞ (silence says nothing).
pub fn beta(delta: f64) -> f64 {
    debug_assert!(delta >= 0.0);
    if delta < 1e-4 {
        // Truncation to [−δ, δ] is nearly uniform: variance δ²/3 (+ O(δ⁴)).
        return 1.0 - delta * delta / 3.0;
    }
    2.0 * delta * normal_pdf(delta) / prob_within(delta)
}

/// Expected transmission rate γ̄(δ) = 1 − (2Φ(δ) − 1)^m of an m-dimensional
/// whitened innovation under the filter's Gaussian assumption.
pub fn expected_rate(delta: f64, m: usize) -> f64 {
    1.0 - prob_within(delta).powi(m as i32)
}

/// The threshold δ whose expected rate is `rate` for dimension m (inverse of
/// [`expected_rate`]), by bisection; useful to build threshold sets.
pub fn delta_for_rate(rate: f64, m: usize) -> f64 {
    let (mut lo, mut hi) = (0.0_f64, 40.0_f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if expected_rate(mid, m) > rate {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beta_limits_and_monotone() {
        assert!((beta(0.0) - 1.0).abs() < 1e-15);
        // The series branch and the closed form agree where they meet.
        let a = beta(0.99e-4);
        let b = 2.0 * 1.01e-4 * normal_pdf(1.01e-4) / prob_within(1.01e-4);
        assert!((a - b).abs() < 1e-8, "{a} vs {b}");
        assert!(beta(10.0) < 1e-20);
        assert!(beta(40.0) == 0.0 || beta(40.0) < 1e-300);
        let mut prev = 1.0;
        for i in 1..200 {
            let b = beta(i as f64 * 0.05);
            assert!(b < prev && b > 0.0, "beta not decreasing at {}", i);
            prev = b;
        }
    }

    #[test]
    fn beta_is_one_minus_truncated_variance() {
        // Var[ε | |ε| ≤ δ] by numerical integration (Simpson) vs 1 − β(δ).
        for &d in &[0.3, 1.0518, 2.2365, 3.5] {
            let n = 20_000;
            let h = 2.0 * d / n as f64;
            let (mut num, mut den) = (0.0, 0.0);
            for i in 0..=n {
                let t = -d + i as f64 * h;
                let w = if i == 0 || i == n {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                num += w * t * t * normal_pdf(t);
                den += w * normal_pdf(t);
            }
            let var = num / den;
            assert!(
                (1.0 - beta(d) - var).abs() < 1e-10,
                "δ={d}: {} vs {var}",
                1.0 - beta(d)
            );
        }
    }

    #[test]
    fn expected_rates_of_builtin_thresholds() {
        // The built-in 2-D thresholds are chosen for rates 1, .5, .25, .1, .05.
        for (d, r) in [
            (0.0, 1.0),
            (1.0518, 0.5),
            (1.4986, 0.25),
            (1.9488, 0.1),
            (2.2365, 0.05),
        ] {
            assert!((expected_rate(d, 2) - r).abs() < 2e-4, "δ={d}");
        }
        for (d, r) in [(1.2638, 0.5), (1.6879, 0.25), (2.1141, 0.1), (2.3877, 0.05)] {
            assert!((expected_rate(d, 3) - r).abs() < 2e-4, "δ={d}");
        }
        assert!((delta_for_rate(0.05, 2) - 2.2365).abs() < 1e-3);
        assert!((normal_cdf(1.959964) - 0.975).abs() < 1e-6);
    }
}
