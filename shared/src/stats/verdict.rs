//! THE verdict "prediction outside the measured interval": one function
//! ([`agreement`]) for `etp run`, `etp replay`, `etp validate` and the
//! Python package, over a [`Family`] of checks at a family-wise level.
//!
//! A command that makes m checks at 95 % each fails an honest strategy (one
//! whose every prediction is right) far more often than 5 % of the time:
//! 1 − 0.95⁶ ≈ 26 % for six independent checks. A [`Family`] makes each of
//! its m checks at 1 − α/m (Bonferroni), so that all hold together with
//! probability ≥ 1 − α whatever their dependence. For the verdict "some
//! check fails" Holm's step-down procedure rejects exactly when Bonferroni
//! does (its first step is Bonferroni's test of the smallest p-value); it
//! differs only in which further checks it names, so etp uses Bonferroni
//! and names every check outside its own interval.

use super::{Estimate, MeanAccumulator, Z95, wilson_interval_z, z_two_sided};

/// What was measured, as a check needs it: the interval at any level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measured {
    /// `k` of `n` episodes: the Wilson score interval.
    Proportion { k: u64, n: u64 },
    /// A sample mean and its standard error (`z · se` either side; an
    /// infinite `se` under two samples: no interval, never a zero-width one).
    Mean { value: f64, se: f64 },
}

impl Measured {
    /// The mean of an accumulator (n < 2: no interval; n = 0: NaN).
    pub fn mean(a: &MeanAccumulator) -> Self {
        if a.n == 0 {
            return Self::Mean {
                value: f64::NAN,
                se: f64::NAN,
            };
        }
        Self::from_estimate(a.estimate())
    }

    /// The mean of `xs`, summed in their order.
    pub fn mean_of(xs: &[f64]) -> Self {
        let mut a = MeanAccumulator::default();
        for &x in xs {
            a.push(x);
        }
        Self::mean(&a)
    }

    /// A mean given as its 95 % [`Estimate`] (`se = ci95 / 1.96`).
    pub fn from_estimate(e: Estimate) -> Self {
        Self::Mean {
            value: e.value,
            se: e.ci95 / Z95,
        }
    }

    /// The point estimate (k/n; the mean). No trial: NaN.
    pub fn value(&self) -> f64 {
        match *self {
            Self::Proportion { n: 0, .. } => f64::NAN,
            Self::Proportion { k, n } => k as f64 / n as f64,
            Self::Mean { value, .. } => value,
        }
    }

    /// The two-sided interval `(lo, hi)` at z-value `z`.
    pub fn interval(&self, z: f64) -> (f64, f64) {
        match *self {
            Self::Proportion { k, n } => wilson_interval_z(k, n, z),
            Self::Mean { value, se } => (value - z * se, value + z * se),
        }
    }

    /// The value and its 95 % half-width, as every JSON prints them
    /// (`<key>`, `<key>_ci95`; a proportion's ± is the larger distance to a
    /// Wilson bound, [`super::proportion`]; no episode: NaN, printed null).
    pub fn estimate(&self) -> Estimate {
        match *self {
            Self::Proportion { n: 0, .. } => Estimate {
                value: f64::NAN,
                ci95: f64::NAN,
            },
            Self::Proportion { k, n } => super::proportion(k, n),
            Self::Mean { value, se } => Estimate {
                value,
                ci95: Z95 * se,
            },
        }
    }
}

/// m checks that hold together with probability ≥ `level` for an honest
/// strategy (Bonferroni: each at 1 − (1 − level)/m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Family {
    pub checks: usize,
    /// The family-wise level (0.95).
    pub level: f64,
}

impl Family {
    /// `checks` checks at the family-wise level 95 %.
    pub const fn of(checks: usize) -> Self {
        Self {
            checks,
            level: 0.95,
        }
    }

    /// Each check's two-sided level: 1 − (1 − level)/m.
    pub fn per_check_level(&self) -> f64 {
        1.0 - (1.0 - self.level) / self.checks.max(1) as f64
    }

    /// Each check's z-value (m = 3: 2.394; m = 6: 2.638).
    pub fn z(&self) -> f64 {
        z_two_sided(self.per_check_level())
    }

    /// In words, for a report: `each check at 98.33 % (Bonferroni over 3),
    /// 95 % for the 3 together`.
    pub fn describe(&self) -> String {
        format!(
            "each check at {:.2} % (Bonferroni over {}): {:.0} % that all hold for an honest strategy",
            100.0 * self.per_check_level(),
            self.checks,
            100.0 * self.level
        )
    }
}

/// A prediction against a measurement at one check's z-value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Agreement {
    /// `low ≤ predicted ≤ high`.
    pub inside: bool,
    /// The interval the prediction must lie in: the measurement's interval
    /// at `z`, each side widened in quadrature by the prediction's own
    /// uncertainty at the same z.
    pub low: f64,
    pub high: f64,
}

/// Does `predicted` (with its own 95 % half-width `own_ci95`, 0 if it has
/// none) agree with `measured` at the z-value `z`? The measured interval
/// (lo, hi) at `z` is widened on each side in quadrature by the prediction's
/// own half-width rescaled to `z`: low = m − √((m − lo)² + w²),
/// high = m + √((hi − m)² + w²) with w = own_ci95 · z / 1.96 — for a
/// symmetric interval exactly the test |predicted − m| ≤ z·√(se² + se_own²)
/// of the difference of two independent estimates. A measurement without an
/// interval (one episode) contains every prediction; a NaN is outside.
pub fn agreement(predicted: f64, own_ci95: f64, measured: &Measured, z: f64) -> Agreement {
    let (lo, hi) = measured.interval(z);
    let m = measured.value();
    // No stated uncertainty (NaN) counts as none; an infinite one
    // contains everything.
    let w = if own_ci95.is_nan() {
        0.0
    } else {
        own_ci95 / Z95 * z
    };
    let low = m - (m - lo).hypot(w);
    let high = m + (hi - m).hypot(w);
    Agreement {
        inside: predicted >= low && predicted <= high,
        low,
        high,
    }
}

/// P_tar, P_coll and energy per episode as measured (a run, a replay, a
/// simulation); `None` where the measurement is not there (a recording
/// without the channel it needs): no check, not counted in the family.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcomes {
    pub p_target: Option<Measured>,
    pub p_collision: Option<Measured>,
    pub energy: Option<Measured>,
}

impl Outcomes {
    /// `target`, `collision` of `episodes` and the episodes' energies (in
    /// their order: the same sums, the same bits, whoever counts them).
    pub fn count(target: u64, collision: u64, episodes: u64, energies: &[f64]) -> Self {
        Self {
            p_target: Some(Measured::Proportion {
                k: target,
                n: episodes,
            }),
            p_collision: Some(Measured::Proportion {
                k: collision,
                n: episodes,
            }),
            energy: Some(Measured::mean_of(energies)),
        }
    }
}

/// One check of a prediction against a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Check {
    pub name: &'static str,
    /// The quantity's JSON key: `p_target`, `p_collision`, `energy_mean`.
    pub key: &'static str,
    /// The value checked (the prediction, the bound).
    pub value: f64,
    pub holds: bool,
    /// The interval the checked value had to lie in (a one-sided check:
    /// the other end infinite).
    pub low: f64,
    pub high: f64,
}

/// Every prediction a strategy stands by against what was measured, as one
/// family at 95 % family-wise: `predicted` P_tar, P_coll and energy inside
/// the measured interval joined with their own ± ([`agreement`]); the
/// certified bounds (when there are) on the right side of the measured
/// interval: P_tar's lower bound ≤ the interval's upper end, P_coll's and
/// the energy's upper bounds ≥ its lower end. No prediction or no
/// measurement: no check (the family counts the checks made).
pub fn prediction_checks(
    predicted: Option<&crate::strategy::Prediction>,
    own_ci95: Option<&crate::strategy::PredictionCi95>,
    certified: Option<&crate::strategy::CertifiedPrediction>,
    m: &Outcomes,
) -> (Family, Vec<Check>) {
    let quantities = [
        ("p_target", m.p_target),
        ("p_collision", m.p_collision),
        ("energy_mean", m.energy),
    ];
    let measured = quantities.iter().filter(|(_, q)| q.is_some()).count();
    let family = Family::of(
        measured * (usize::from(predicted.is_some()) + usize::from(certified.is_some())),
    );
    let z = family.z();
    let mut v = Vec::new();
    if let Some(p) = predicted {
        let own = own_ci95.copied().unwrap_or_default();
        let names = ["predicted P_tar", "predicted P_coll", "predicted energy"];
        let values = [
            (p.p_target, own.p_target),
            (p.p_collision, own.p_collision),
            (p.energy_mean, own.energy_mean),
        ];
        for (((key, q), name), (value, w)) in quantities.iter().zip(names).zip(values) {
            if let Some(q) = q {
                let a = agreement(value, w, q, z);
                v.push(Check {
                    name,
                    key,
                    value,
                    holds: a.inside,
                    low: a.low,
                    high: a.high,
                });
            }
        }
    }
    if let Some(c) = certified {
        let (inf, minus_inf) = (f64::INFINITY, f64::NEG_INFINITY);
        let one_sided = [
            // (name, bound, its side: a lower bound must not pass the upper end)
            (
                "certified P_tar ≤ simulated (upper end)",
                c.p_target_low,
                true,
            ),
            (
                "certified P_coll ≥ simulated (lower end)",
                c.p_collision_high,
                false,
            ),
            (
                "certified energy ≥ simulated (lower end)",
                c.energy_high,
                false,
            ),
        ];
        for ((key, q), (name, value, lower_bound)) in quantities.iter().zip(one_sided) {
            if let Some(q) = q {
                let (lo, hi) = q.interval(z);
                let (low, high) = if lower_bound {
                    (minus_inf, hi)
                } else {
                    (lo, inf)
                };
                v.push(Check {
                    name,
                    key,
                    value,
                    holds: value >= low && value <= high,
                    low,
                    high,
                });
            }
        }
    }
    (family, v)
}

#[cfg(test)]
mod tests;
