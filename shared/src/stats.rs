//! Point estimates with 95 % confidence half-widths.
//!
//! Means use the normal approximation `1.96 s / √n`; proportions use the
//! Wilson score interval (never a zero-width interval at p = 0 or 1); ratios of
//! sums (e.g. transmissions per measurement slot) use the delta method.

use serde::{Deserialize, Serialize};

/// z-value of a two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// An estimate and the half-width of its 95 % confidence interval.
/// `$into.f += $from.f` for each field `f` listed, in order: the field-wise
/// sum of two records of counts (an episode's legs, merged accumulators),
/// written once.
///
/// ```
/// #[derive(Default)]
/// struct Counts { steps: u32, energy: f64 }
/// let (mut total, leg) = (Counts::default(), Counts { steps: 3, energy: 1.5 });
/// etp_shared::add_fields!(total, leg; steps, energy);
/// assert_eq!((total.steps, total.energy), (3, 1.5));
/// ```
#[macro_export]
macro_rules! add_fields {
    ($into:expr, $from:expr; $($field:ident),+ $(,)?) => {
        $( $into.$field += $from.$field; )+
    };
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub value: f64,
    pub ci95: f64,
}

impl Estimate {
    /// Does `x` lie in `value ± ci95`?
    pub fn covers(&self, x: f64) -> bool {
        (x - self.value).abs() <= self.ci95
    }
}

/// Running sums of a scalar sample, for a mean with a confidence interval.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeanAccumulator {
    pub n: u64,
    pub sum: f64,
    pub sum_sq: f64,
}

impl MeanAccumulator {
    pub fn push(&mut self, x: f64) {
        self.n += 1;
        self.sum += x;
        self.sum_sq += x * x;
    }

    pub fn merge(&mut self, other: &Self) {
        self.n += other.n;
        self.sum += other.sum;
        self.sum_sq += other.sum_sq;
    }

    pub fn mean(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.sum / self.n as f64
        }
    }

    /// Unbiased sample variance.
    pub fn variance(&self) -> f64 {
        if self.n < 2 {
            return 0.0;
        }
        let n = self.n as f64;
        ((self.sum_sq - self.sum * self.sum / n) / (n - 1.0)).max(0.0)
    }

    pub fn estimate(&self) -> Estimate {
        let ci95 = if self.n < 2 {
            f64::INFINITY
        } else {
            Z95 * (self.variance() / self.n as f64).sqrt()
        };
        Estimate {
            value: self.mean(),
            ci95,
        }
    }
}

/// An energy or count-like float without the noise of its last bits
/// (`25869.399999999994` → `25869.4`): 10 significant digits.
pub fn round_energy(x: f64) -> f64 {
    round_sig(x, 10)
}

/// `x` rounded to `digits` significant digits (non-finite and 0 unchanged).
pub fn round_sig(x: f64, digits: i32) -> f64 {
    if !x.is_finite() || x == 0.0 {
        return x;
    }
    // Rust's `{:e}` rounds correctly to the digits asked; parsing it back
    // gives the nearest f64 (which prints with those digits only).
    format!("{:.*e}", (digits - 1).max(0) as usize, x)
        .parse()
        .unwrap_or(x)
}

/// Wilson score interval `(lo, hi)` for `k` successes in `n` trials.
pub fn wilson_interval(k: u64, n: u64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let n_f = n as f64;
    let p = k as f64 / n_f;
    let z2 = Z95 * Z95;
    let denom = 1.0 + z2 / n_f;
    let centre = (p + z2 / (2.0 * n_f)) / denom;
    let half = Z95 * (p * (1.0 - p) / n_f + z2 / (4.0 * n_f * n_f)).sqrt() / denom;
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// The proportion `k/n` with the larger distance to a Wilson bound as half-width.
pub fn proportion(k: u64, n: u64) -> Estimate {
    let p = if n == 0 { 0.0 } else { k as f64 / n as f64 };
    let (lo, hi) = wilson_interval(k, n);
    Estimate {
        value: p,
        ci95: (p - lo).max(hi - p),
    }
}

/// Per-unit sums for a ratio estimator `Σa / Σb` (e.g. transmissions per slot
/// over episodes), with a delta-method interval treating episodes as units.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RatioAccumulator {
    pub n: u64,
    pub sum_a: f64,
    pub sum_b: f64,
    pub sum_aa: f64,
    pub sum_bb: f64,
    pub sum_ab: f64,
}

impl RatioAccumulator {
    pub fn push(&mut self, a: f64, b: f64) {
        self.n += 1;
        self.sum_a += a;
        self.sum_b += b;
        self.sum_aa += a * a;
        self.sum_bb += b * b;
        self.sum_ab += a * b;
    }

    pub fn merge(&mut self, o: &Self) {
        crate::add_fields!(self, o; n, sum_a, sum_b, sum_aa, sum_bb, sum_ab);
    }

    pub fn estimate(&self) -> Estimate {
        if self.sum_b <= 0.0 || self.n < 2 {
            return Estimate {
                value: 0.0,
                ci95: f64::INFINITY,
            };
        }
        let n = self.n as f64;
        let r = self.sum_a / self.sum_b;
        let b_mean = self.sum_b / n;
        // Var of residuals d_i = a_i − r b_i.
        let ss = self.sum_aa - 2.0 * r * self.sum_ab + r * r * self.sum_bb;
        let var_d = (ss / (n - 1.0)).max(0.0);
        Estimate {
            value: r,
            ci95: Z95 * (var_d / n).sqrt() / b_mean,
        }
    }
}

/// The ratio `a / b` of two independent estimates with its 95 % half-width
/// by the delta method: `|a/b| · √((h_a/a)² + (h_b/b)²)`. `None` when `b`
/// is not positive (no ratio) — a ratio of energies, e.g. a family's least
/// energy to the paper's trigger's (`etp compare`).
pub fn ratio(a: Estimate, b: Estimate) -> Option<Estimate> {
    if b.value.is_nan() || b.value <= 0.0 || !a.value.is_finite() {
        return None;
    }
    let r = a.value / b.value;
    let rel_a = if a.value != 0.0 {
        a.ci95 / a.value
    } else {
        0.0
    };
    let rel_b = b.ci95 / b.value;
    let rel = (rel_a * rel_a + rel_b * rel_b).sqrt();
    // A zero numerator: its own ± over b.
    let ci95 = if a.value != 0.0 {
        r.abs() * rel
    } else {
        a.ci95 / b.value
    };
    Some(Estimate { value: r, ci95 })
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_ratio_by_the_delta_method() {
        let e = |value, ci95| super::Estimate { value, ci95 };
        let r = super::ratio(e(200.0, 6.0), e(100.0, 4.0)).expect("ratio");
        assert!((r.value - 2.0).abs() < 1e-12);
        assert!((r.ci95 - 2.0 * (0.03f64.powi(2) + 0.04f64.powi(2)).sqrt()).abs() < 1e-12);
        assert_eq!(
            super::ratio(e(1.0, 0.1), e(1.0, 0.0)).map(|r| r.ci95),
            Some(0.1)
        );
        assert!(super::ratio(e(1.0, 0.1), e(0.0, 0.1)).is_none());
    }

    use super::*;

    #[test]
    fn mean_of_constant_has_zero_width() {
        let mut a = MeanAccumulator::default();
        for _ in 0..10 {
            a.push(2.5);
        }
        let e = a.estimate();
        assert_eq!(e.value, 2.5);
        assert!(e.ci95.abs() < 1e-12);
    }

    #[test]
    fn wilson_matches_textbook_value() {
        // 5 of 10: Wilson 95 % interval (0.2366, 0.7634).
        let (lo, hi) = wilson_interval(5, 10);
        assert!(
            (lo - 0.2366).abs() < 1e-4 && (hi - 0.7634).abs() < 1e-4,
            "{lo} {hi}"
        );
        let e = proportion(0, 100);
        assert_eq!(e.value, 0.0);
        assert!(e.ci95 > 0.03 && e.ci95 < 0.04, "{}", e.ci95);
    }

    #[test]
    fn ratio_of_proportional_sums_is_exact() {
        let mut r = RatioAccumulator::default();
        for b in [10.0, 20.0, 30.0] {
            r.push(0.25 * b, b);
        }
        let e = r.estimate();
        assert!((e.value - 0.25).abs() < 1e-12 && e.ci95 < 1e-9);
    }
}
