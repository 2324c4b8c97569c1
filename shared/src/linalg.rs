//! Small dense linear algebra the model needs beyond nalgebra: a *deterministic*
//! symmetric eigenbasis (the ∞-norm trigger depends on the basis, docs/MODEL.md §2),
//! conversions between dynamic and fixed-size matrices, and the Riccati steady state.

use nalgebra::{DMatrix, SMatrix, SVector};

/// Column vector of dimension N.
pub type Vector<const N: usize> = SVector<f64, N>;
/// R×C matrix.
pub type Matrix<const R: usize, const C: usize> = SMatrix<f64, R, C>;

/// Relative tolerance under which two eigenvalues count as repeated.
pub const REPEATED_EIGENVALUE_RTOL: f64 = 1e-9;

/// Eigen-decomposition `A = V diag(λ) Vᵀ` of a symmetric matrix with a basis fixed
/// by rule, not by the solver: eigenvalues sorted descending; for a repeated
/// eigenvalue the coordinate axes projected into its eigenspace and
/// orthonormalised in coordinate order (so `V = I` for a multiple of I); every
/// column's sign chosen so that its largest-magnitude entry is positive.
pub fn deterministic_eigen(a: &DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let n = a.nrows();
    let sym = (a + a.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let values: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let scale = values
        .iter()
        .fold(0.0_f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let mut v = DMatrix::<f64>::zeros(n, n);
    let mut start = 0;
    while start < n {
        let mut end = start + 1;
        while end < n && (values[end - 1] - values[end]).abs() <= REPEATED_EIGENVALUE_RTOL * scale {
            end += 1;
        }
        if end - start == 1 {
            v.set_column(start, &eig.eigenvectors.column(order[start]));
        } else {
            // Projector onto the repeated eigenspace.
            let mut u = DMatrix::<f64>::zeros(n, end - start);
            for (c, k) in (start..end).enumerate() {
                u.set_column(c, &eig.eigenvectors.column(order[k]));
            }
            let proj = &u * u.transpose();
            let mut filled = 0;
            for axis in 0..n {
                if filled == end - start {
                    break;
                }
                let mut w = proj.column(axis).clone_owned();
                for c in 0..filled {
                    let prev = v.column(start + c).clone_owned();
                    w -= &prev * prev.dot(&w);
                }
                let norm = w.norm();
                if norm > 1e-6 {
                    v.set_column(start + filled, &(w / norm));
                    filled += 1;
                }
            }
        }
        start = end;
    }
    for c in 0..n {
        let col = v.column(c);
        let imax = col.iamax();
        if col[imax] < 0.0 {
            v.column_mut(c).neg_mut();
        }
    }
    (values, v)
}

/// [`deterministic_eigen`] for a fixed-size matrix, without heap allocation
/// (the whitening of every non-diagonal innovation covariance calls it, once
/// per step). Same rule: λ descending, coordinate axes projected into a
/// repeated eigenspace and orthonormalised in coordinate order, each column's
/// largest-magnitude entry positive.
pub fn deterministic_eigen_static<const M: usize>(
    a: &SMatrix<f64, M, M>,
) -> (SVector<f64, M>, SMatrix<f64, M, M>) {
    let (eigenvalues, eigenvectors) = jacobi_eigen(&((a + a.transpose()) * 0.5));
    let mut order = [0usize; M];
    for (i, o) in order.iter_mut().enumerate() {
        *o = i;
    }
    order.sort_by(|&i, &j| eigenvalues[j].total_cmp(&eigenvalues[i]));
    let values = SVector::<f64, M>::from_fn(|i, _| eigenvalues[order[i]]);
    let scale = values.amax().max(f64::MIN_POSITIVE);
    let mut v = SMatrix::<f64, M, M>::zeros();
    let mut start = 0;
    while start < M {
        let mut end = start + 1;
        while end < M && (values[end - 1] - values[end]).abs() <= REPEATED_EIGENVALUE_RTOL * scale {
            end += 1;
        }
        if end - start == 1 {
            v.set_column(start, &eigenvectors.column(order[start]));
        } else {
            // Projector onto the repeated eigenspace.
            let mut proj = SMatrix::<f64, M, M>::zeros();
            for &k in &order[start..end] {
                let c = eigenvectors.column(k);
                proj += c * c.transpose();
            }
            let mut filled = 0;
            for axis in 0..M {
                if filled == end - start {
                    break;
                }
                let mut w = proj.column(axis).clone_owned();
                for c in 0..filled {
                    let prev = v.column(start + c).clone_owned();
                    w -= prev * prev.dot(&w);
                }
                let norm = w.norm();
                if norm > 1e-6 {
                    v.set_column(start + filled, &(w / norm));
                    filled += 1;
                }
            }
        }
        start = end;
    }
    for c in 0..M {
        let imax = v.column(c).iamax();
        if v[(imax, c)] < 0.0 {
            v.column_mut(c).neg_mut();
        }
    }
    (values, v)
}

/// Eigenvalues and eigenvectors (columns) of a symmetric matrix by cyclic
/// Jacobi rotations: allocation-free for any fixed size (nalgebra's symmetric
/// eigensolver needs type-level dimensions a `const M` cannot give), accurate to
/// rounding, a handful of sweeps for M ≤ 6 (one rotation for M = 2).
pub fn jacobi_eigen<const M: usize>(
    sym: &SMatrix<f64, M, M>,
) -> (SVector<f64, M>, SMatrix<f64, M, M>) {
    let mut a = *sym;
    let mut v = SMatrix::<f64, M, M>::identity();
    let total = a.norm_squared();
    for _ in 0..64 {
        let mut off = 0.0;
        for p in 0..M {
            for q in p + 1..M {
                off += a[(p, q)] * a[(p, q)];
            }
        }
        if off <= 1e-32 * total || off == 0.0 {
            break;
        }
        for p in 0..M {
            for q in p + 1..M {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                // a ← Jᵀ a J with J the rotation in the (p, q) plane.
                for k in 0..M {
                    let (akp, akq) = (a[(k, p)], a[(k, q)]);
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..M {
                    let (apk, aqk) = (a[(p, k)], a[(q, k)]);
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
                a[(p, q)] = 0.0;
                a[(q, p)] = 0.0;
                for k in 0..M {
                    let (vkp, vkq) = (v[(k, p)], v[(k, q)]);
                    v[(k, p)] = c * vkp - s * vkq;
                    v[(k, q)] = s * vkp + c * vkq;
                }
            }
        }
    }
    (a.diagonal(), v)
}

/// Dynamic → fixed-size copy (dimensions are validated at scenario load).
pub fn to_static<const R: usize, const C: usize>(m: &DMatrix<f64>) -> SMatrix<f64, R, C> {
    debug_assert_eq!((m.nrows(), m.ncols()), (R, C));
    SMatrix::<f64, R, C>::from_fn(|i, j| m[(i, j)])
}

/// Dynamic → fixed-size copy of a matrix that may be smaller (n×p inputs,
/// d×n workspace maps): entries outside it are zero.
pub fn to_static_padded<const R: usize, const C: usize>(m: &DMatrix<f64>) -> SMatrix<f64, R, C> {
    SMatrix::<f64, R, C>::from_fn(|i, j| {
        if i < m.nrows() && j < m.ncols() {
            m[(i, j)]
        } else {
            0.0
        }
    })
}

/// Dynamic vector → fixed-size vector.
pub fn to_static_vec<const N: usize>(v: &nalgebra::DVector<f64>) -> SVector<f64, N> {
    debug_assert_eq!(v.len(), N);
    SVector::<f64, N>::from_fn(|i, _| v[i])
}

/// Fixed-size → dynamic copy.
pub fn to_dynamic<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_fn(R, C, |i, j| m[(i, j)])
}

/// Lower Cholesky factor of an SPD matrix (validated at load; falls back to the
/// symmetric square root's diagonal if rounding ever breaks definiteness).
pub fn cholesky_lower<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    match nalgebra::Cholesky::new(*m) {
        Some(c) => c.l(),
        None => SMatrix::<f64, N, N>::from_diagonal(&m.diagonal().map(|d| d.max(0.0).sqrt())),
    }
}

/// Symmetrise in place: `(A + Aᵀ)/2`.
#[inline(always)]
pub fn symmetrize<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (m + m.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multiple_of_identity_gets_the_coordinate_axes() {
        let (vals, v) = deterministic_eigen(&DMatrix::identity(3, 3).scale(0.5));
        assert_eq!(vals, vec![0.5, 0.5, 0.5]);
        assert_eq!(v, DMatrix::identity(3, 3));
    }

    #[test]
    fn distinct_eigenvalues_sorted_descending_with_fixed_sign() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 3.0]);
        let (vals, v) = deterministic_eigen(&a);
        assert_eq!(vals, vec![3.0, 1.0]);
        assert_eq!(v, DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 1.0, 0.0]));
        let b = DMatrix::from_row_slice(3, 3, &[2.0, -0.4, 0.1, -0.4, 1.0, 0.2, 0.1, 0.2, 0.5]);
        let (vals, v) = deterministic_eigen(&b);
        let recon =
            &v * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vals.clone())) * v.transpose();
        assert!((recon - &b).amax() < 1e-12);
        for c in 0..3 {
            let col = v.column(c);
            assert!(col[col.iamax()] > 0.0);
        }
    }

    #[test]
    fn static_and_dynamic_bases_agree() {
        let b = DMatrix::from_row_slice(3, 3, &[2.0, -0.4, 0.1, -0.4, 1.0, 0.2, 0.1, 0.2, 0.5]);
        let (vals, v) = deterministic_eigen(&b);
        let (svals, sv) = deterministic_eigen_static(&to_static::<3, 3>(&b));
        for i in 0..3 {
            assert!((vals[i] - svals[i]).abs() < 1e-14);
            for j in 0..3 {
                assert!((v[(i, j)] - sv[(i, j)]).abs() < 1e-12);
            }
        }
        let block = SMatrix::<f64, 3, 3>::from_diagonal(&SVector::<f64, 3>::new(2.0, 1.0, 1.0));
        assert_eq!(
            deterministic_eigen_static(&block).1,
            SMatrix::<f64, 3, 3>::identity()
        );
    }

    #[test]
    fn repeated_block_is_orthonormalised_in_coordinate_order() {
        // diag(2, 1, 1) rotated in the (y, z) plane stays diag: block spans y, z.
        let a = DMatrix::from_row_slice(3, 3, &[2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let (vals, v) = deterministic_eigen(&a);
        assert_eq!(vals, vec![2.0, 1.0, 1.0]);
        assert_eq!(v, DMatrix::identity(3, 3));
    }
}
