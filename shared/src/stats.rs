//! THE statistics of etp: every interval a command, a figure or the Python
//! package shows comes from here (docs/MODEL.md §"Statistics").
//!
//! * proportions (P_tar, P_coll, P_free: k of n episodes): the Wilson score
//!   interval ([`wilson_interval`], [`proportion`]) — never zero width at
//!   k = 0 or k = n, never outside [0, 1];
//! * means (energy per episode): `z s / √n` ([`mean_of`],
//!   [`MeanAccumulator`]); no interval (infinite) under two samples;
//! * ratios of sums (e.g. transmissions per measurement slot): the delta
//!   method ([`RatioAccumulator`], [`ratio`]);
//! * the verdict "prediction outside the measured interval", one check or a
//!   family of checks at a family-wise level ([`verdict`]).
//!
//! Signs: an error is always predicted − simulated (measured).

use serde::{Deserialize, Serialize};

/// z-value of a two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;

pub mod verdict;

/// The z-value of a two-sided interval at `level` (0.95 → [`Z95`]):
/// Φ⁻¹(1 − (1 − level)/2). `level` outside (0, 1) gives NaN or ±∞.
pub fn z_two_sided(level: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    Normal::standard().inverse_cdf(0.5 + level / 2.0)
}

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

/// Wilson score 95 % interval `(lo, hi)` for `k` successes in `n` trials.
pub fn wilson_interval(k: u64, n: u64) -> (f64, f64) {
    wilson_interval_z(k, n, Z95)
}

/// Wilson score interval `(lo, hi)` for `k` successes in `n` trials at the
/// two-sided z-value `z`: the p₀ whose score test |p̂ − p₀| / √(p₀(1 − p₀)/n)
/// stays within `z` (Wilson 1927; Newcombe 1998, method 3). At k = 0 its
/// upper bound is z²/(n + z²) > 0, at k = n its lower bound n/(n + z²) < 1:
/// unlike p̂ ± z√(p̂(1 − p̂)/n), never a zero-width interval at 0 or 1, and
/// never outside [0, 1]. No trial: (0, 1).
pub fn wilson_interval_z(k: u64, n: u64, z: f64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let n_f = n as f64;
    let p = k.min(n) as f64 / n_f;
    let z2 = z * z;
    let denom = 1.0 + z2 / n_f;
    let centre = (p + z2 / (2.0 * n_f)) / denom;
    let half = z * (p * (1.0 - p) / n_f + z2 / (4.0 * n_f * n_f)).sqrt() / denom;
    // At k = 0 (k = n) the bound is 0 (1) exactly, not a rounding below.
    let lo = if k == 0 {
        0.0
    } else {
        (centre - half).max(0.0)
    };
    let hi = if k >= n {
        1.0
    } else {
        (centre + half).min(1.0)
    };
    (lo, hi)
}

/// The mean of `xs` with its 95 % half-width `1.96 s / √n` (the sums of
/// [`MeanAccumulator`], in the order given): no sample → NaN; one sample →
/// an infinite half-width (no interval, never a zero-width one).
pub fn mean_of(xs: &[f64]) -> Estimate {
    let mut a = MeanAccumulator::default();
    for &x in xs {
        a.push(x);
    }
    if a.n == 0 {
        return Estimate {
            value: f64::NAN,
            ci95: f64::NAN,
        };
    }
    a.estimate()
}

/// The proportion `k/n` with the larger distance to a Wilson bound as
/// half-width (the `_ci95` of every JSON: a symmetric ± that contains the
/// Wilson interval).
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
mod tests;
