//! The event-triggered Kalman filter of Wu et al. (2013), docs/MODEL.md §2.
//!
//! Fixed-size (`const N` state, `const M` measurement) so the per-step work is a
//! few dozen flops on the stack. Pure: no I/O, no clock; randomness only through
//! the `Rng` passed in.

use crate::dense::{mul, mul_transpose};
use crate::gaussian;
use crate::linalg::{
    cholesky_lower, deterministic_eigen_static, symmetrize, to_static, to_static_padded,
    to_static_vec,
};
use crate::scenario::{Plant, Sensor};
use crate::structured::Selection;
use rand::{Rng, RngExt};
use rand_distr::StandardNormal;

// The fixed-size aliases live in `linalg` (geometry needs them without
// depending on the filter); re-exported here where most callers look.
pub use crate::linalg::{Matrix, Vector};

/// A Gaussian belief `N(mean, cov)` over the state.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Belief<const N: usize> {
    pub mean: Vector<N>,
    pub cov: Matrix<N, N>,
}

/// A sample of `N(0, I)` of dimension D.
pub fn standard_normal<const D: usize, R: Rng + ?Sized>(rng: &mut R) -> Vector<D> {
    Vector::<D>::from_fn(|_, _| rng.sample(StandardNormal))
}

/// The linear-Gaussian plant `x' = F x + G u + w`, `w ~ N(0, Q)`.
#[derive(Debug, Clone, Copy)]
pub struct LinearPlant<const N: usize> {
    pub f: Matrix<N, N>,
    /// G (n×p, MODEL.md §7) padded with zero columns past p; inputs carry zeros there.
    pub g: Matrix<N, N>,
    pub q: Matrix<N, N>,
    q_chol: Matrix<N, N>,
}

impl<const N: usize> LinearPlant<N> {
    pub fn new(p: &Plant) -> Self {
        let q = to_static::<N, N>(&p.q);
        Self {
            f: to_static(&p.f),
            g: to_static_padded(&p.g),
            q,
            q_chol: cholesky_lower(&q),
        }
    }

    /// The initial belief `N(x̂0, P0)` of a scenario.
    pub fn initial_belief(p: &Plant) -> Belief<N> {
        Belief {
            mean: to_static_vec(&p.x0),
            cov: to_static(&p.p0),
        }
    }

    /// One step of the true dynamics.
    #[inline(always)]
    pub fn step<R: Rng + ?Sized>(&self, x: &Vector<N>, u: &Vector<N>, rng: &mut R) -> Vector<N> {
        mul(&self.f, x) + mul(&self.g, u) + mul(&self.q_chol, &standard_normal::<N, R>(rng))
    }

    /// Prediction: `x̂⁻ = F x̂ + G u`, `P⁻ = F P Fᵀ + Q`.
    #[inline(always)]
    pub fn predict(&self, post: &Belief<N>, u: &Vector<N>) -> Belief<N> {
        Belief {
            mean: mul(&self.f, &post.mean) + mul(&self.g, u),
            cov: mul_transpose(&mul(&self.f, &post.cov), &self.f) + self.q,
        }
    }
}

/// Draw a state from a Gaussian belief.
pub fn sample_belief<const N: usize, R: Rng + ?Sized>(b: &Belief<N>, rng: &mut R) -> Vector<N> {
    b.mean + cholesky_lower(&b.cov) * standard_normal::<N, R>(rng)
}

/// A sensor `y = H x + v`, `v ~ N(0, R)`.
#[derive(Debug, Clone, Copy)]
pub struct SensorModel<const N: usize, const M: usize> {
    pub h: Matrix<M, N>,
    pub r: Matrix<M, M>,
    r_chol: Matrix<M, M>,
    /// `Some` when H only picks state entries (position-only, or H = I): the
    /// products with H become gathers (same bits, `structured`).
    selection: Option<Selection<M>>,
    /// Energy per transmitted measurement.
    pub cost: f64,
}

impl<const N: usize, const M: usize> SensorModel<N, M> {
    pub fn new(s: &Sensor) -> Self {
        let r = to_static::<M, M>(&s.r);
        let h = to_static(&s.h);
        Self {
            h,
            r,
            r_chol: cholesky_lower(&r),
            selection: Selection::of(&h),
            cost: s.cost,
        }
    }

    /// A noisy measurement of the true state.
    #[inline(always)]
    pub fn measure<R: Rng + ?Sized>(&self, x: &Vector<N>, rng: &mut R) -> Vector<M> {
        self.observe(x) + mul(&self.r_chol, &standard_normal::<M, R>(rng))
    }

    /// The lower Cholesky factor `L_R` of R (`R = L_R L_Rᵀ`).
    pub fn r_chol(&self) -> &Matrix<M, M> {
        &self.r_chol
    }

    /// `H x`.
    #[inline(always)]
    pub fn observe(&self, x: &Vector<N>) -> Vector<M> {
        match &self.selection {
            Some(s) => s.pick(x),
            None => mul(&self.h, x),
        }
    }

    /// `H P` (M×N).
    #[inline(always)]
    fn h_times(&self, p: &Matrix<N, N>) -> Matrix<M, N> {
        match &self.selection {
            Some(s) => s.rows(p),
            None => mul(&self.h, p),
        }
    }

    /// `H P Hᵀ + R` and `P Hᵀ`.
    #[inline(always)]
    fn innovation_cov(&self, p: &Matrix<N, N>) -> (Matrix<M, M>, Matrix<N, M>) {
        match &self.selection {
            Some(s) => {
                let pht = s.columns_of(p);
                (s.rows_of_tall(&pht) + self.r, pht)
            }
            None => {
                let pht = mul_transpose(p, &self.h);
                (mul(&self.h, &pht) + self.r, pht)
            }
        }
    }

    /// `K H` (N×N) for a gain K (N×M).
    #[inline(always)]
    fn gain_times_h(&self, k: &Matrix<N, M>) -> Matrix<N, N> {
        match &self.selection {
            Some(s) => s.scatter(k),
            None => mul(k, &self.h),
        }
    }
}

/// `ε = Λ^{-1/2} Vᵀ z` for the innovation covariance `Z = V Λ Vᵀ`.
#[derive(Debug, Clone, Copy)]
pub enum Whitener<const M: usize> {
    /// Z is diagonal (the common case, every built-in scenario): V = I, so ε_i = z_i / √Z_ii.
    Diagonal(Vector<M>),
    /// General Z: the rows of `Λ^{-1/2} Vᵀ` with the deterministic basis of
    /// [`deterministic_eigen_static`].
    Basis(Matrix<M, M>),
}

impl<const M: usize> Whitener<M> {
    /// The whitening transform of an innovation covariance.
    pub fn new(z: &Matrix<M, M>) -> Self {
        if is_diagonal(z) {
            // Coordinate axes are eigenvectors; order and sign do not change ‖ε‖∞.
            return Self::Diagonal(Vector::<M>::from_fn(|i, _| 1.0 / z[(i, i)].sqrt()));
        }
        let (values, v) = deterministic_eigen_static(z);
        let inv_sqrt = Matrix::<M, M>::from_diagonal(&Vector::<M>::from_fn(|i, _| {
            1.0 / values[i].max(f64::MIN_POSITIVE).sqrt()
        }));
        Self::Basis(inv_sqrt * v.transpose())
    }

    /// The whitened innovation ε (identity covariance under the Gaussian assumption).
    #[inline(always)]
    pub fn whiten(&self, z: &Vector<M>) -> Vector<M> {
        match self {
            Self::Diagonal(s) => z.component_mul(s),
            Self::Basis(w) => w * z,
        }
    }
}

/// The innovation's statistics at one step, shared by trigger and update.
#[derive(Debug, Clone, Copy)]
pub struct Innovation<const N: usize, const M: usize> {
    /// Predicted measurement `H x̂⁻`.
    pub predicted: Vector<M>,
    /// Its covariance `Z = H P⁻ Hᵀ + R`.
    pub cov: Matrix<M, M>,
    /// Kalman gain `K = P⁻ Hᵀ Z⁻¹`.
    pub gain: Matrix<N, M>,
    /// `Z⁻¹`, `None` if rounding made Z singular (then the gain is zero).
    pub cov_inv: Option<Matrix<M, M>>,
}

impl<const N: usize, const M: usize> Innovation<N, M> {
    /// The whitening transform of Z (an eigen-decomposition unless Z is
    /// diagonal; computed on demand — the trigger rarely needs it).
    pub fn whitener(&self) -> Whitener<M> {
        Whitener::new(&self.cov)
    }

    /// Whitened innovation of a measurement.
    #[inline(always)]
    pub fn whitened(&self, y: &Vector<M>) -> Vector<M> {
        self.whitener().whiten(&(y - self.predicted))
    }

    /// The trigger: transmit iff ‖ε‖∞ > δ.
    ///
    /// For a non-diagonal Z the eigenbasis costs more than the rest of the
    /// step, and most innovations are decided without it: with
    /// `d² = zᵀ Z⁻¹ z = ‖ε‖₂²` and `‖ε‖₂/√M ≤ ‖ε‖∞ ≤ ‖ε‖₂`, `d² < δ²` means
    /// silent and `d² > M δ²` means transmit, whatever the basis. Only the band
    /// between needs the basis. The margins (1e-9 relative, far above the
    /// rounding of either side) keep every decision the one the basis gives.
    #[inline(always)]
    pub fn triggers(&self, y: &Vector<M>, delta: f64) -> bool {
        let z = y - self.predicted;
        if let (Some(z_inv), false) = (&self.cov_inv, is_diagonal(&self.cov)) {
            let d2 = z.dot(&(z_inv * z));
            let d2_delta = delta * delta;
            if d2 < d2_delta * (1.0 - 1e-9) {
                return false;
            }
            if d2 > (M as f64) * d2_delta * (1.0 + 1e-9) {
                return true;
            }
        }
        self.whitener().whiten(&z).amax() > delta
    }
}

fn is_diagonal<const M: usize>(z: &Matrix<M, M>) -> bool {
    (0..M).all(|i| (0..M).all(|j| i == j || z[(i, j)] == 0.0))
}

/// A threshold together with its precomputed implicit-information factor β(δ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Threshold {
    pub delta: f64,
    pub beta: f64,
}

impl Threshold {
    pub fn new(delta: f64) -> Self {
        Self {
            delta,
            beta: gaussian::beta(delta),
        }
    }
}

/// ET-KF for one (plant, sensor) pair.
#[derive(Debug, Clone, Copy)]
pub struct EtKalmanFilter<const N: usize, const M: usize> {
    pub plant: LinearPlant<N>,
    pub sensor: SensorModel<N, M>,
}

impl<const N: usize, const M: usize> EtKalmanFilter<N, M> {
    pub fn new(plant: &Plant, sensor: &Sensor) -> Self {
        Self {
            plant: LinearPlant::new(plant),
            sensor: SensorModel::new(sensor),
        }
    }

    /// Innovation statistics for a prior.
    #[inline(always)]
    pub fn innovation(&self, prior: &Belief<N>) -> Innovation<N, M> {
        let (cov, pht) = self.sensor.innovation_cov(&prior.cov);
        // Z ⪰ R is SPD by validation, so the inverse exists; a zero gain (no
        // update) is the safe fallback should rounding ever make it singular.
        let cov_inv = cov.try_inverse();
        Innovation {
            predicted: self.sensor.observe(&prior.mean),
            cov,
            gain: mul(&pht, &cov_inv.unwrap_or_else(Matrix::<M, M>::zeros)),
            cov_inv,
        }
    }

    /// Explicit update with a received measurement (Joseph form).
    #[inline(always)]
    pub fn update_explicit(
        &self,
        prior: &Belief<N>,
        inn: &Innovation<N, M>,
        y: &Vector<M>,
    ) -> Belief<N> {
        let k = &inn.gain;
        let ikh = Matrix::<N, N>::identity() - self.sensor.gain_times_h(k);
        let cov =
            mul_transpose(&mul(&ikh, &prior.cov), &ikh) + mul_transpose(&mul(k, &self.sensor.r), k);
        Belief {
            mean: prior.mean + mul(k, &(y - inn.predicted)),
            cov: symmetrize(&cov),
        }
    }

    /// Implicit update after a silent slot: `P = P⁻ − β K H P⁻`, mean unchanged.
    #[inline(always)]
    pub fn update_implicit(
        &self,
        prior: &Belief<N>,
        inn: &Innovation<N, M>,
        beta: f64,
    ) -> Belief<N> {
        let cov = prior.cov - mul(&inn.gain, &self.sensor.h_times(&prior.cov)) * beta;
        Belief {
            mean: prior.mean,
            cov: symmetrize(&cov),
        }
    }

    /// Update with a pseudo-measurement `y` whose noise covariance is
    /// `scale · R` (Joseph form): the send-on-delta family's silence, where
    /// `y` is the last delivered measurement (docs/MODEL.md §9). `scale = 1`
    /// is [`Self::update_explicit`]'s update.
    pub fn update_pseudo_measurement(
        &self,
        prior: &Belief<N>,
        inn: &Innovation<N, M>,
        y: &Vector<M>,
        scale: f64,
    ) -> Belief<N> {
        let (_, pht) = self.sensor.innovation_cov(&prior.cov);
        let r = self.sensor.r * scale;
        let z = inn.cov - self.sensor.r + r;
        // Z' ⪰ scale·R is SPD for scale > 0; no information if rounding
        // ever makes it singular.
        let Some(z_inv) = z.try_inverse() else {
            return *prior;
        };
        let k = mul(&pht, &z_inv);
        let ikh = Matrix::<N, N>::identity() - self.sensor.gain_times_h(&k);
        let cov = mul_transpose(&mul(&ikh, &prior.cov), &ikh) + mul_transpose(&mul(&k, &r), &k);
        Belief {
            mean: prior.mean + mul(&k, &(y - inn.predicted)),
            cov: symmetrize(&cov),
        }
    }

    /// Prediction only (no information at all, e.g. a dead sensor).
    #[inline(always)]
    pub fn predict(&self, post: &Belief<N>, u: &Vector<N>) -> Belief<N> {
        self.plant.predict(post, u)
    }

    /// Steady-state posterior covariance `P_KF` of the ordinary Kalman filter
    /// (δ = 0), by iterating the Riccati recursion to a fixed point.
    ///
    /// Rounding can leave the recursion cycling through a few covariances a
    /// few ulps apart, never meeting the stopping test; the answer is then
    /// the covariance after [`RICCATI_STEPS`] steps. Such a cycle is found
    /// (a state equal, bit for bit, to one of the last [`CYCLE_WINDOW`]) and
    /// the remaining steps are skipped to that same covariance: the bits of
    /// the plain iteration (`riccati_by_iteration`, kept in the tests), in
    /// microseconds instead of ~50 ms per sensor.
    pub fn steady_state_posterior(&self) -> Matrix<N, N> {
        let mut b = Belief {
            mean: Vector::<N>::zeros(),
            cov: self.plant.q,
        };
        let zero = Vector::<N>::zeros();
        // (step index k, b_k) of the last steps, once the changes are tiny.
        let mut recent: std::collections::VecDeque<(usize, Belief<N>)> =
            std::collections::VecDeque::with_capacity(CYCLE_WINDOW);
        for k in 0..RICCATI_STEPS {
            let prior = self.predict(&b, &zero);
            let inn = self.innovation(&prior);
            let next = self.update_implicit(&prior, &inn, 1.0);
            // Stop at the fixed point; the recursion contracts geometrically,
            // so a relative change of a few ulps is the floor rounding allows.
            let change = (next.cov - b.cov).amax();
            if change <= 4.0 * f64::EPSILON * next.cov.amax() {
                return next.cov;
            }
            if change <= CYCLE_WATCH * next.cov.amax() {
                if recent.len() == CYCLE_WINDOW {
                    recent.pop_front();
                }
                recent.push_back((k, b));
                // b_{k+1} = b_t: the steps repeat with period k + 1 − t (no
                // step of the cycle met the stopping test, or it would have
                // stopped), so b after RICCATI_STEPS steps is b_{t + (RICCATI_STEPS − t) mod p}.
                if let Some(&(t, _)) = recent.iter().find(|(_, old)| same_bits(old, &next)) {
                    let p = k + 1 - t;
                    let at = t + (RICCATI_STEPS - t) % p;
                    if let Some((_, end)) = recent.iter().find(|(i, _)| *i == at) {
                        return end.cov;
                    }
                }
            }
            b = next;
        }
        b.cov
    }
}

/// The steps of the Riccati recursion [`EtKalmanFilter::steady_state_posterior`]
/// stands for when it does not meet its stopping test.
pub const RICCATI_STEPS: usize = 1_000_000;
/// How many recent steps a rounding cycle is looked for in.
const CYCLE_WINDOW: usize = 64;
/// The relative change below which steps are remembered for the cycle search.
const CYCLE_WATCH: f64 = 1e-12;

/// Bit-for-bit equality (`==` would equate 0.0 and −0.0, whose steps may differ).
fn same_bits<const N: usize>(a: &Belief<N>, b: &Belief<N>) -> bool {
    let bits = |x: &f64, y: &f64| x.to_bits() == y.to_bits();
    a.mean.iter().zip(b.mean.iter()).all(|(x, y)| bits(x, y))
        && a.cov.iter().zip(b.cov.iter()).all(|(x, y)| bits(x, y))
}

#[cfg(test)]
mod tests;
