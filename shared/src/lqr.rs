//! The discrete-time LQR gain of MODEL.md §7: `K = (Gᵀ S G + R_u)⁻¹ Gᵀ S F` with
//! S the stabilising solution of the discrete algebraic Riccati equation
//!
//! ```text
//! S = Fᵀ S F − Fᵀ S G (Gᵀ S G + R_u)⁻¹ Gᵀ S F + Q_x
//! ```
//!
//! solved by the structure-preserving doubling algorithm (Chu, Fan, Lin 2005):
//! it converges quadratically to the stabilising solution whenever one exists,
//! where plain value iteration crawls for slow modes such as a double
//! integrator's (closed-loop poles near 1). Pure dense maths on small matrices.

use nalgebra::DMatrix;

/// Why no LQR gain could be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LqrError {
    /// The doubling iteration diverged or did not settle: (F, G) is not
    /// stabilisable or (F, Q_x) has an unobservable unstable mode.
    #[error("the Riccati equation has no stabilising solution ({0})")]
    NoStabilisingSolution(String),
    /// A solution was found but the closed loop F − G K is not stable.
    #[error("the closed loop F − G K is not stable (spectral radius {0:.6} ≥ 1)")]
    Unstable(f64),
}

/// Relative change under which the doubling iteration has converged.
const CONVERGED_RTOL: f64 = 1e-13;
/// Doubling steps: step k covers 2^k Riccati iterations, 64 is beyond any use.
const MAX_DOUBLINGS: usize = 64;
/// Largest relative DARE residual accepted for the returned S.
const RESIDUAL_RTOL: f64 = 1e-8;

/// The relative residual of the DARE at `s` (max-norm of the difference of both
/// sides over the max-norm of S).
pub fn dare_residual(
    f: &DMatrix<f64>,
    g: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: &DMatrix<f64>,
) -> f64 {
    let gsf = g.transpose() * s * f;
    let inner = g.transpose() * s * g + r;
    let solved = inner
        .lu()
        .solve(&gsf)
        .unwrap_or_else(|| DMatrix::from_element(gsf.nrows(), gsf.ncols(), f64::NAN));
    let rhs = f.transpose() * s * f - gsf.transpose() * solved + q;
    (rhs - s).amax() / s.amax().max(f64::MIN_POSITIVE)
}

/// Stabilising solution S of the DARE for (F, G, Q_x, R_u).
pub fn solve_dare(
    f: &DMatrix<f64>,
    g: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>, LqrError> {
    let n = f.nrows();
    let r_inv = r
        .clone()
        .try_inverse()
        .ok_or_else(|| LqrError::NoStabilisingSolution("input weight is singular".into()))?;
    let mut a = f.clone();
    let mut gm = g * r_inv * g.transpose();
    let mut h = q.clone();
    let eye = DMatrix::<f64>::identity(n, n);
    for _ in 0..MAX_DOUBLINGS {
        let w = (&eye + &gm * &h).lu();
        let (Some(w_a), Some(w_g)) = (w.solve(&a), w.solve(&gm)) else {
            return Err(LqrError::NoStabilisingSolution(
                "singular step in the doubling iteration".into(),
            ));
        };
        let a_next = &a * &w_a;
        let g_next = &gm + &a * w_g * a.transpose();
        let h_next = &h + a.transpose() * &h * &w_a;
        if !h_next.iter().all(|v| v.is_finite()) {
            return Err(LqrError::NoStabilisingSolution(
                "the doubling iteration diverged".into(),
            ));
        }
        let change = (&h_next - &h).amax();
        a = a_next;
        gm = g_next;
        h = h_next;
        if change <= CONVERGED_RTOL * h.amax().max(f64::MIN_POSITIVE) {
            let s = (&h + h.transpose()) * 0.5;
            let residual = dare_residual(f, g, q, r, &s);
            if residual.is_nan() || residual > RESIDUAL_RTOL {
                return Err(LqrError::NoStabilisingSolution(format!(
                    "relative residual {residual:e}"
                )));
            }
            return Ok(s);
        }
    }
    Err(LqrError::NoStabilisingSolution(
        "the doubling iteration did not converge".into(),
    ))
}

/// The LQR gain `K = (Gᵀ S G + R_u)⁻¹ Gᵀ S F` (p×n), checked to stabilise F − G K.
pub fn lqr_gain(
    f: &DMatrix<f64>,
    g: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>, LqrError> {
    let s = solve_dare(f, g, q, r)?;
    let k = (g.transpose() * &s * g + r)
        .lu()
        .solve(&(g.transpose() * &s * f))
        .ok_or_else(|| LqrError::NoStabilisingSolution("GᵀSG + R_u is singular".into()))?;
    let rho = spectral_radius(&(f - g * &k));
    if rho.is_nan() || rho >= 1.0 {
        return Err(LqrError::Unstable(rho));
    }
    Ok(k)
}

/// Largest eigenvalue modulus of a square matrix.
pub fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    m.clone()
        .complex_eigenvalues()
        .iter()
        .map(|c| c.norm())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn double_integrator(tau: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let f = DMatrix::from_row_slice(2, 2, &[1.0, tau, 0.0, 1.0]);
        let g = DMatrix::from_row_slice(2, 1, &[0.5 * tau * tau, tau]);
        (f, g)
    }

    #[test]
    fn scalar_dare_has_its_closed_form() {
        // n = p = 1, F = a, G = 1: S² − (a² q... ) closed form of
        // S = a² S − a² S² / (S + r) + q  ⇔  S² + (r − a² r − q) S − q r = 0.
        let (a, q, r) = (1.2_f64, 0.5_f64, 2.0_f64);
        let b = r - a * a * r - q;
        let s_exact = (-b + (b * b + 4.0 * q * r).sqrt()) / 2.0;
        let m = |v: f64| DMatrix::from_element(1, 1, v);
        let s = solve_dare(&m(a), &m(1.0), &m(q), &m(r)).expect("solvable");
        assert!((s[(0, 0)] - s_exact).abs() <= 1e-12 * s_exact);
        let k = lqr_gain(&m(a), &m(1.0), &m(q), &m(r)).expect("stabilising");
        assert!((k[(0, 0)] - a * s_exact / (s_exact + r)).abs() <= 1e-12);
    }

    #[test]
    fn double_integrator_gain_solves_the_dare_and_stabilises() {
        let (f, g) = double_integrator(0.1);
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![1.0, 0.0]));
        let r = DMatrix::from_element(1, 1, 0.01);
        let s = solve_dare(&f, &g, &q, &r).expect("solvable");
        assert!(dare_residual(&f, &g, &q, &r, &s) < 1e-10);
        // S is symmetric positive definite (the position weight reaches both states).
        assert!(s.clone().symmetric_eigenvalues().min() > 0.0);
        let k = lqr_gain(&f, &g, &q, &r).expect("stabilising");
        let rho = spectral_radius(&(&f - &g * &k));
        assert!(rho < 1.0, "closed loop radius {rho}");
        // Optimality: the gain is the minimiser of the one-step Bellman form, so
        // perturbing K raises the cost-to-go of a test state.
        let cost = |k: &DMatrix<f64>| {
            // Closed-loop Lyapunov sum Σ xᵀ(Q + KᵀRK)x from x0 = (1, 0), 4000 steps.
            let acl = &f - &g * k;
            let w = &q + k.transpose() * &r * k;
            let mut x = nalgebra::DVector::from_vec(vec![1.0, 0.0]);
            let mut c = 0.0;
            for _ in 0..4000 {
                c += x.dot(&(&w * &x));
                x = &acl * x;
            }
            c
        };
        let best = cost(&k);
        assert!(
            (best - s[(0, 0)]).abs() <= 1e-6 * best,
            "{best} vs S00 {}",
            s[(0, 0)]
        );
        for dk in [-0.05, 0.05] {
            let mut k2 = k.clone();
            k2[(0, 0)] *= 1.0 + dk;
            assert!(cost(&k2) > best);
        }
    }

    #[test]
    fn an_uncontrollable_unstable_mode_is_refused() {
        // The second state doubles every step and the input cannot reach it.
        let f = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 2.0]);
        let g = DMatrix::from_row_slice(2, 1, &[1.0, 0.0]);
        let q = DMatrix::identity(2, 2);
        let r = DMatrix::identity(1, 1);
        assert!(matches!(
            lqr_gain(&f, &g, &q, &r),
            Err(LqrError::NoStabilisingSolution(_))
        ));
    }
}
