//! Clopper–Pearson intervals for a binomial proportion, from the regularized
//! incomplete beta function (continued fraction, Lentz's method) and its
//! quantile by bisection. Rounding is pushed outwards: the lower end returned
//! is the lower end of the final bisection bracket, the upper end the upper
//! end, so an interval is never narrower than the exact one by rounding.

/// `I_x(a, b)`, the regularized incomplete beta function, for a, b > 0.
pub fn regularized_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front =
        libm::lgamma(a + b) - libm::lgamma(a) - libm::lgamma(b) + a * x.ln() + b * (1.0 - x).ln();
    // The continued fraction converges fast for x < (a + 1) / (a + b + 2).
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * continued_fraction(a, b, x) / a
    } else {
        1.0 - ln_front.exp() * continued_fraction(b, a, 1.0 - x) / b
    }
}

/// The continued fraction of `I_x(a, b)` (modified Lentz).
fn continued_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    const EPS: f64 = 1e-16;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    // One term of the modified Lentz recurrence: updates (c, d), returns
    // the factor d·c of h.
    let step = |aa: f64, c: &mut f64, d: &mut f64| {
        *d = 1.0 + aa * *d;
        if d.abs() < TINY {
            *d = TINY;
        }
        *c = 1.0 + aa / *c;
        if c.abs() < TINY {
            *c = TINY;
        }
        *d = 1.0 / *d;
        *d * *c
    };
    for m in 1..10_000 {
        let m = f64::from(m);
        let m2 = 2.0 * m;
        h *= step(m * (b - m) * x / ((qam + m2) * (a + m2)), &mut c, &mut d);
        let del = step(
            -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)),
            &mut c,
            &mut d,
        );
        h *= del;
        if (del - 1.0).abs() < EPS {
            break;
        }
    }
    h
}

/// The bracket `[lo, hi]` of the `p`-quantile of Beta(a, b) after bisection.
fn beta_quantile_bracket(a: f64, b: f64, p: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if regularized_beta(a, b, mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo, hi)
}

/// The two-sided Clopper–Pearson interval of `k` successes in `n` trials at
/// error level `delta` (each tail `delta / 2`): it contains the true
/// proportion with probability ≥ 1 − delta.
pub fn clopper_pearson(k: u64, n: u64, delta: f64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let k = k.min(n);
    let (kf, nf) = (k as f64, n as f64);
    let lo = if k == 0 {
        0.0
    } else {
        beta_quantile_bracket(kf, nf - kf + 1.0, delta / 2.0).0
    };
    let hi = if k == n {
        1.0
    } else {
        beta_quantile_bracket(kf + 1.0, nf - kf, 1.0 - delta / 2.0).1
    };
    (lo, hi)
}

/// The one-sided Clopper–Pearson upper bound of a proportion observed 0 times
/// in `n` trials at error level `delta`: `1 − delta^(1/n)` (rounded up).
pub fn zero_count_upper(n: u64, delta: f64) -> f64 {
    if n == 0 {
        return 1.0;
    }
    // −expm1(ln δ / n) is 1 − δ^(1/n) without cancellation; nudge outwards.
    (-(delta.ln() / n as f64).exp_m1() * (1.0 + 1e-12)).min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incomplete_beta_matches_closed_forms() {
        // I_x(1, b) = 1 − (1 − x)^b; I_x(a, 1) = x^a.
        for &(x, b) in &[(0.1, 3.0), (0.5, 7.0), (0.93, 2.0)] {
            let want: f64 = 1.0 - (1.0_f64 - x).powf(b);
            assert!((regularized_beta(1.0, b, x) - want).abs() < 1e-13);
            assert!((regularized_beta(b, 1.0, x) - x.powf(b)).abs() < 1e-13);
        }
        // Symmetry I_x(a, b) = 1 − I_{1−x}(b, a).
        let v = regularized_beta(30.0, 5970.0, 0.004);
        let w = regularized_beta(5970.0, 30.0, 0.996);
        assert!((v + w - 1.0).abs() < 1e-12);
    }

    #[test]
    fn clopper_pearson_matches_textbook_values() {
        // 5 of 10 at 95 %: (0.187086, 0.812914) (e.g. R's binom.test).
        let (lo, hi) = clopper_pearson(5, 10, 0.05);
        assert!((lo - 0.187_086).abs() < 1e-6, "{lo}");
        assert!((hi - 0.812_914).abs() < 1e-6, "{hi}");
        // 0 of 20: upper 1 − 0.025^(1/20) = 0.168434.
        let (lo, hi) = clopper_pearson(0, 20, 0.05);
        assert_eq!(lo, 0.0);
        assert!((hi - 0.168_433_8).abs() < 1e-6, "{hi}");
        assert!((zero_count_upper(20, 0.025) - hi).abs() < 1e-9);
        // Large n, tiny level: contains the estimate, ordered.
        let (lo, hi) = clopper_pearson(5700, 6000, 1e-6);
        assert!(lo < 0.95 && 0.95 < hi && hi - lo < 0.03, "{lo} {hi}");
    }
}
