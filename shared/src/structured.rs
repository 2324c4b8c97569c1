//! A sensor matrix that only selects state entries (a position-only sensor's
//! `H = [I 0]`, or `H = I`): its products become gathers and scatters, without
//! changing a single bit of their results.
//!
//! **Bit-for-bit:** nalgebra's fixed-size product accumulates every entry
//! `Σ_k a_ik b_kj` in ascending `k`; with a selection exactly one term is
//! non-zero and the others are exact zeros (`0 · b = ±0`, `s + ±0 = s`), so
//! the gather is the dense result — except that an all-zero sum may come out
//! `+0` where the dense one was `−0`, which no comparison, probability or
//! decision can see. The unit tests hold the results equal on random inputs;
//! the golden numbers of the built-in scenarios stay put.
//!
//! (A zero-skipping `F P Fᵀ` for a double integrator's sparse F was tried and
//! removed: scalar loops over the non-zeros were no faster than nalgebra's
//! vectorised dense product.)

use crate::linalg::{Matrix, Vector};

/// An M×N matrix whose every row is a distinct unit coordinate vector `e_cᵀ`:
/// `H x` picks entries of x (a position-only sensor, or `H = I`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Selection<const M: usize> {
    /// Row r of H is `e_{columns[r]}ᵀ`.
    pub columns: [usize; M],
}

impl<const M: usize> Selection<M> {
    /// `Some` iff `h` is a selection (entries exactly 0 or 1, one 1 per row,
    /// no column selected twice).
    pub fn of<const N: usize>(h: &Matrix<M, N>) -> Option<Self> {
        let mut columns = [0usize; M];
        for (r, c) in columns.iter_mut().enumerate() {
            let mut found = None;
            for j in 0..N {
                let v = h[(r, j)];
                if v == 1.0 && found.is_none() {
                    found = Some(j);
                } else if v != 0.0 {
                    return None;
                }
            }
            *c = found?;
        }
        for a in 0..M {
            for b in a + 1..M {
                if columns[a] == columns[b] {
                    return None;
                }
            }
        }
        Some(Self { columns })
    }

    /// `H x`.
    #[inline(always)]
    pub fn pick<const N: usize>(&self, x: &Vector<N>) -> Vector<M> {
        Vector::<M>::from_fn(|r, _| x[self.columns[r]])
    }

    /// `H P` (M×N): the selected rows of P.
    #[inline(always)]
    pub fn rows<const N: usize>(&self, p: &Matrix<N, N>) -> Matrix<M, N> {
        Matrix::<M, N>::from_fn(|r, j| p[(self.columns[r], j)])
    }

    /// `P Hᵀ` (N×M): the selected columns of P.
    #[inline(always)]
    pub fn columns_of<const N: usize>(&self, p: &Matrix<N, N>) -> Matrix<N, M> {
        Matrix::<N, M>::from_fn(|i, c| p[(i, self.columns[c])])
    }

    /// `H A` for an N×M matrix A (M×M): the selected rows.
    #[inline(always)]
    pub fn rows_of_tall<const N: usize>(&self, a: &Matrix<N, M>) -> Matrix<M, M> {
        Matrix::<M, M>::from_fn(|r, c| a[(self.columns[r], c)])
    }

    /// `K H` (N×N) for an N×M gain K: K's columns scattered to the selected columns.
    #[inline(always)]
    pub fn scatter<const N: usize>(&self, k: &Matrix<N, M>) -> Matrix<N, N> {
        let mut out = Matrix::<N, N>::zeros();
        for (c, &j) in self.columns.iter().enumerate() {
            out.set_column(j, &k.column(c));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;
    use rand::{RngExt, SeedableRng};

    fn same_bits<const R: usize, const C: usize>(a: &Matrix<R, C>, b: &Matrix<R, C>) -> bool {
        // ±0 may differ (module doc); everything else must be the same bits.
        a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (*x == 0.0 && *y == 0.0))
    }

    fn random<const R: usize, const C: usize>(rng: &mut SimRng) -> Matrix<R, C> {
        Matrix::<R, C>::from_fn(|_, _| {
            rng.random_range(-3.0..3.0) * 10f64.powi(rng.random_range(-6..3))
        })
    }

    #[test]
    fn selection_products_are_the_dense_products_bit_for_bit() {
        let mut rng = SimRng::seed_from_u64(8);
        let mut h = Matrix::<3, 6>::zeros();
        h[(0, 0)] = 1.0;
        h[(1, 1)] = 1.0;
        h[(2, 2)] = 1.0;
        let sel = Selection::of(&h).expect("a selection");
        for _ in 0..2000 {
            let p = random::<6, 6>(&mut rng);
            let x = random::<6, 1>(&mut rng);
            let k = random::<6, 3>(&mut rng);
            assert!(same_bits(&sel.pick(&x), &(h * x)));
            assert!(same_bits(&sel.rows(&p), &(h * p)));
            assert!(same_bits(&sel.columns_of(&p), &(p * h.transpose())));
            assert!(same_bits(&sel.rows_of_tall(&k), &(h * k)));
            assert!(same_bits(&sel.scatter(&k), &(k * h)));
        }
    }

    #[test]
    fn only_true_selections_are_recognised() {
        let h = Matrix::<2, 4>::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        assert_eq!(Selection::of(&h), Some(Selection { columns: [0, 1] }));
        let twice = Matrix::<2, 4>::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0);
        assert_eq!(Selection::of(&twice), None);
        let scaled = Matrix::<2, 4>::new(2.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        assert_eq!(Selection::of(&scaled), None);
        let mixed = Matrix::<2, 4>::new(1.0, 0.5, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        assert_eq!(Selection::of(&mixed), None);
        assert_eq!(
            Selection::of(&Matrix::<2, 2>::identity()),
            Some(Selection { columns: [0, 1] })
        );
    }
}
