//! Trigger families (docs/MODEL.md §9): how a sensor decides to send, and what
//! its silence tells the agent's estimator.
//!
//! `box` is the paper's trigger (§2, [`crate::etkf::Innovation::triggers`]);
//! the other four are the alternatives a researcher compares it with. Every
//! family reads its parameter δ ≥ 0 from the scenario's `deltas`, δ = 0 always
//! means "send every measurement", and a transmission is always the full
//! Kalman update. What differs is the decision and the silence update:
//!
//! | family | decision (the `*_sends` functions) | silence ([`TriggerFamily::silence`]) |
//! |---|---|---|
//! | [`TriggerFamily::Box`] | `‖ε‖∞ > δ` | shrink by β(δ) (Gaussian approx.) |
//! | [`TriggerFamily::Stochastic`] | `u ≥ exp(−‖ε‖₂²/(2δ²))` | shrink by 1/(1 + δ²) (exact) |
//! | [`TriggerFamily::SendOnDelta`] | `‖L_R⁻¹(y − y_ref)‖∞ > δ` | pseudo-measurement `y_ref`, noise (1 + δ²/3) R |
//! | [`TriggerFamily::Variance`] | `λ_max(L_R⁻¹ H P⁻ Hᵀ L_R⁻ᵀ) > δ²` | none (exact) |
//! | [`TriggerFamily::Periodic`] | `⌊(k+1)γ⌋ > ⌊kγ⌋`, γ the box rate | none (exact) |
//!
//! Pure: the stochastic family's uniform draw `u` is passed in; it comes from
//! a stream of its own ([`crate::rng::trigger_rng`]) so that every other
//! random number of an episode keeps its bits.

use crate::gaussian;
use crate::linalg::{Matrix, Vector, deterministic_eigen_static};
use serde::{Deserialize, Serialize};

/// How a sensor decides to transmit (docs/MODEL.md §9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TriggerFamily {
    /// The paper's innovation ∞-norm trigger (Wu et al. 2013).
    #[default]
    Box,
    /// Han, Mo, Wu, Weerakkody, Sinopoli, Shi (IEEE TAC 2015): silent with
    /// probability exp(−‖ε‖²/(2δ²)); the posterior stays exactly Gaussian.
    Stochastic,
    /// Send-on-delta (Miskowicz 2006): send when the measurement moved more
    /// than δ (in units of its noise) from the last delivered one.
    SendOnDelta,
    /// Variance-based (Trimpe & D'Andrea 2014): send when the predicted
    /// measurement uncertainty exceeds δ² times the noise; known to both sides.
    Variance,
    /// Time-triggered at the box trigger's expected rate for the same δ.
    Periodic,
}

/// A family name that is none of [`TriggerFamily::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown trigger family `{0}` (one of: box, stochastic, send-on-delta, variance, periodic)"
)]
pub struct UnknownFamily(pub String);

/// What silence does to the predicted belief `(x̂⁻, P⁻)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Silence {
    /// `x̂ = x̂⁻`, `P = P⁻ − factor · K H P⁻` (factor 0: no information).
    Shrink(f64),
    /// Treat the last delivered measurement as a new one whose noise is
    /// `scale · R` (send-on-delta): the Kalman update with that noise.
    PseudoMeasurement { scale: f64 },
}

impl TriggerFamily {
    /// Every family, the paper's first.
    pub const ALL: [Self; 5] = [
        Self::Box,
        Self::Stochastic,
        Self::SendOnDelta,
        Self::Variance,
        Self::Periodic,
    ];

    /// The name used in scenarios (`[triggering] family`), on the command
    /// line (`--trigger`) and in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Box => "box",
            Self::Stochastic => "stochastic",
            Self::SendOnDelta => "send-on-delta",
            Self::Variance => "variance",
            Self::Periodic => "periodic",
        }
    }

    /// Parse a family name.
    pub fn parse(s: &str) -> Result<Self, UnknownFamily> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| UnknownFamily(s.to_owned()))
    }

    /// Whether the silence update is the exact Bayesian posterior under the
    /// filter's model (then NEES/n = 1 is promised, not only reported).
    pub fn exact(self) -> bool {
        !matches!(self, Self::Box | Self::SendOnDelta)
    }

    /// Whether the decision draws a random number (from
    /// [`crate::rng::trigger_rng`]).
    pub fn draws(self) -> bool {
        self == Self::Stochastic
    }

    /// The silence update of this family at threshold δ on an ideal radio.
    pub fn silence(self, delta: f64) -> Silence {
        match self {
            Self::Box => Silence::Shrink(gaussian::beta(delta)),
            Self::Stochastic => Silence::Shrink(stochastic_silence_factor(delta)),
            Self::SendOnDelta => Silence::PseudoMeasurement {
                scale: send_on_delta_noise_scale(delta),
            },
            Self::Variance | Self::Periodic => Silence::Shrink(0.0),
        }
    }

    /// The expected transmission rate per step under the filter's model,
    /// where it has a closed form in δ and m alone (box, stochastic,
    /// periodic); `None` for send-on-delta (none in closed form) and variance
    /// (it is the count of its covariance recursion).
    pub fn expected_rate(self, delta: f64, m: usize) -> Option<f64> {
        match self {
            Self::Box | Self::Periodic => Some(gaussian::expected_rate(delta, m)),
            Self::Stochastic => Some(1.0 - stochastic_silence_probability(delta, m)),
            Self::SendOnDelta | Self::Variance => None,
        }
    }

    /// Whether a slot's expected transmission is a model rate (box and
    /// stochastic: random decisions with a closed-form probability) rather
    /// than the decision itself (variance and periodic decide
    /// deterministically; send-on-delta has no closed form). Periodic's
    /// [`Self::expected_rate`] γ is its long-run rate: a leg of K slots sends
    /// exactly ⌊Kγ⌋ times.
    pub fn has_model_rate(self) -> bool {
        matches!(self, Self::Box | Self::Stochastic)
    }

    /// For the aware estimator on a lossy radio (§8.3 generalised, §9):
    /// `(a, v)`, the probability of no send and the per-axis second moment of
    /// ε given no send, for the families whose silence is informative;
    /// `None` where silence is read as uninformative on a lossy radio
    /// (variance, periodic: a due packet that does not arrive is a loss;
    /// send-on-delta: conservatively dropped).
    pub fn silence_moments(self, delta: f64, m: usize) -> Option<(f64, f64)> {
        match self {
            Self::Box => Some((
                gaussian::prob_within(delta).powi(m as i32),
                1.0 - gaussian::beta(delta),
            )),
            Self::Stochastic => Some((
                stochastic_silence_probability(delta, m),
                1.0 - stochastic_silence_factor(delta),
            )),
            Self::SendOnDelta | Self::Variance | Self::Periodic => None,
        }
    }

    /// The aware silence factor β' = 1 − c on a link that loses a sent
    /// packet with probability q (after retries): §8.3's mixture of "no send"
    /// (probability a, second moment v) and "sent and lost" (q(1 − a), second
    /// moment (1 − a v)/(1 − a)). 0 where [`Self::silence_moments`] is `None`.
    /// At q = 0 it is the ideal radio's factor, bit for bit.
    pub fn lossy_silence_factor(self, delta: f64, m: usize, q: f64) -> f64 {
        let Some((a, v)) = self.silence_moments(delta, m) else {
            return 0.0;
        };
        if q == 0.0 {
            // The ideal radio's factor itself (the quotient is not bit-exact).
            return match self.silence(delta) {
                Silence::Shrink(factor) => factor,
                Silence::PseudoMeasurement { .. } => 0.0,
            };
        }
        if q >= 1.0 || a == 0.0 {
            return 0.0;
        }
        let av = a * v;
        let c = (av + q * (1.0 - av)) / (a + q * (1.0 - a));
        (1.0 - c).max(0.0)
    }
}

impl std::str::FromStr for TriggerFamily {
    type Err = UnknownFamily;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}

impl std::fmt::Display for TriggerFamily {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// `1 / (1 + δ²)`: the stochastic family's silence factor, from the
/// pseudo-measurement `Y = δ⁻² Z⁻¹` (`(Z + Y⁻¹)⁻¹ = Z⁻¹ / (1 + δ²)`). At δ = 0
/// the sensor always sends, so the value (1) is never used there.
pub fn stochastic_silence_factor(delta: f64) -> f64 {
    1.0 / (1.0 + delta * delta)
}

/// `1 + δ²/3`: send-on-delta's silence reads the last delivered measurement
/// with noise `(1 + δ²/3) R` (its own noise plus a uniform error on the
/// δ-box in noise units, variance δ²/3 per axis).
pub fn send_on_delta_noise_scale(delta: f64) -> f64 {
    1.0 + delta * delta / 3.0
}

/// `E[exp(−‖ε‖²/(2δ²))] = (1 + δ⁻²)^(−m/2) = (δ²/(1 + δ²))^(m/2)`, the
/// probability that the stochastic trigger stays silent; 0 at δ = 0.
pub fn stochastic_silence_probability(delta: f64, m: usize) -> f64 {
    let d2 = delta * delta;
    (d2 / (1.0 + d2)).powf(0.5 * m as f64)
}

/// The stochastic trigger: transmit iff `u ≥ exp(−‖ε‖₂² / (2δ²))` for a
/// uniform `u ∈ [0, 1)` (so P(send | ε) = 1 − exp(…) exactly, and a
/// vanishing exp(…) always sends); always at δ = 0. `eps_norm2` is `‖ε‖₂² = zᵀ Z⁻¹ z`.
#[inline(always)]
pub fn stochastic_sends(eps_norm2: f64, delta: f64, u: f64) -> bool {
    if delta <= 0.0 {
        return true;
    }
    u >= (-eps_norm2 / (2.0 * delta * delta)).exp()
}

/// Send-on-delta: the first step of a leg (`last = None`) sends; then
/// transmit iff `‖L_R⁻¹ (y − y_last)‖∞ > δ`, `L_R` the lower Cholesky factor
/// of R (δ in units of the measurement noise).
#[inline(always)]
pub fn send_on_delta_sends<const M: usize>(
    y: &Vector<M>,
    last: Option<&Vector<M>>,
    r_chol: &Matrix<M, M>,
    delta: f64,
) -> bool {
    let Some(last) = last else {
        return true;
    };
    let d = y - last;
    match r_chol.solve_lower_triangular(&d) {
        Some(w) => w.amax() > delta,
        // R is SPD by validation; a singular factor cannot arise, and
        // sending is the safe side should it ever.
        None => true,
    }
}

/// Variance-based: transmit iff `λ_max(L_R⁻¹ (H P⁻ Hᵀ) L_R⁻ᵀ) > δ²`, where
/// `hph = H P⁻ Hᵀ`. Depends on the covariance only, which the agent knows.
pub fn variance_sends<const M: usize>(
    hph: &Matrix<M, M>,
    r_chol: &Matrix<M, M>,
    delta: f64,
) -> bool {
    let Some(a) = r_chol.solve_lower_triangular(hph) else {
        return true;
    };
    let Some(s) = r_chol.solve_lower_triangular(&a.transpose()) else {
        return true;
    };
    // Symmetrised inside; eigenvalues in descending order.
    let (values, _) = deterministic_eigen_static(&s);
    values[0] > delta * delta
}

/// Periodic at rate γ: step `k` of a leg (from 0) sends iff
/// `⌊(k + 1) γ⌋ > ⌊k γ⌋`, so the first `K` steps send exactly `⌊K γ⌋` times.
#[inline(always)]
pub fn periodic_sends(k: u64, gamma: f64) -> bool {
    ((k + 1) as f64 * gamma).floor() > (k as f64 * gamma).floor()
}

#[cfg(test)]
mod tests;
