//! Fixed-size dense products, unrolled, with nalgebra's rounding.
//!
//! nalgebra's `Mul` of two static matrices goes through its generic `gemm`
//! (column by column, a `gemv` of axpys), which the compiler keeps out of line
//! with loops over the dimensions: a third of an n = 6 episode step was spent
//! there. The functions here compute the same thing with every bound a
//! constant, so the loops unroll and vectorise.
//!
//! **Bit-for-bit:** nalgebra forms entry (i, j) as `a_i0 b_0j` and then
//! `a_ik b_kj + acc` for k = 1, 2, … in ascending order, a multiply and an add
//! each rounded (no fused multiply-add); so do these. The unit tests hold the
//! results equal to nalgebra's on random inputs, and the golden numbers and
//! `simulate` outputs of the built-in scenarios do not move.

use crate::linalg::Matrix;

/// `A B` (R×K times K×C), exactly as nalgebra's product rounds it.
#[inline(always)]
pub fn mul<const R: usize, const K: usize, const C: usize>(
    a: &Matrix<R, K>,
    b: &Matrix<K, C>,
) -> Matrix<R, C> {
    let b = &b.data.0;
    accumulate(a, |k, j| b[j][k])
}

/// `A Bᵀ` (R×K times (C×K)ᵀ), exactly as nalgebra's `a * b.transpose()`
/// rounds it (a transpose is exact, so the sums are those of [`mul`]).
#[inline(always)]
pub fn mul_transpose<const R: usize, const K: usize, const C: usize>(
    a: &Matrix<R, K>,
    b: &Matrix<C, K>,
) -> Matrix<R, C> {
    let b = &b.data.0;
    accumulate(a, |k, j| b[k][j])
}

/// `Σ_k a_ik b(k, j)` for every (i, j), in nalgebra's order: `a_i0 b(0, j)`,
/// then `a_ik b(k, j) + acc` for k = 1, 2, ….
#[inline(always)]
fn accumulate<const R: usize, const K: usize, const C: usize>(
    a: &Matrix<R, K>,
    b: impl Fn(usize, usize) -> f64,
) -> Matrix<R, C> {
    let a = &a.data.0;
    let mut out = [[0.0f64; R]; C];
    if let Some(a0) = a.first() {
        for (j, col) in out.iter_mut().enumerate() {
            let b0 = b(0, j);
            for (c, &x) in col.iter_mut().zip(a0) {
                *c = x * b0;
            }
            for (k, ak) in a.iter().enumerate().skip(1) {
                let bk = b(k, j);
                for (c, &x) in col.iter_mut().zip(ak) {
                    *c += x * bk;
                }
            }
        }
    }
    Matrix::<R, C>::from_data(nalgebra::ArrayStorage(out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;
    use rand::{RngExt, SeedableRng};

    fn random<const R: usize, const C: usize>(rng: &mut SimRng) -> Matrix<R, C> {
        Matrix::<R, C>::from_fn(|_, _| {
            // Mixed magnitudes and exact zeros, so rounding and ±0 are exercised.
            if rng.random_range(0..8) == 0 {
                0.0
            } else {
                rng.random_range(-3.0..3.0) * 10f64.powi(rng.random_range(-8..4))
            }
        })
    }

    fn same_bits<const R: usize, const C: usize>(a: &Matrix<R, C>, b: &Matrix<R, C>) -> bool {
        a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (*x == 0.0 && *y == 0.0))
    }

    fn check<const R: usize, const K: usize, const C: usize>(rng: &mut SimRng) {
        for _ in 0..500 {
            let a = random::<R, K>(rng);
            let b = random::<K, C>(rng);
            let bt = random::<C, K>(rng);
            assert!(same_bits(&mul(&a, &b), &(a * b)), "{R}x{K} * {K}x{C}");
            assert!(
                same_bits(&mul_transpose(&a, &bt), &(a * bt.transpose())),
                "{R}x{K} * ({C}x{K})ᵀ"
            );
        }
    }

    #[test]
    fn products_are_nalgebras_bit_for_bit() {
        let mut rng = SimRng::seed_from_u64(11);
        check::<1, 1, 1>(&mut rng);
        check::<2, 2, 2>(&mut rng);
        check::<3, 3, 3>(&mut rng);
        check::<4, 4, 4>(&mut rng);
        check::<6, 6, 6>(&mut rng);
        check::<6, 3, 6>(&mut rng);
        check::<6, 3, 3>(&mut rng);
        check::<4, 2, 4>(&mut rng);
        check::<5, 6, 1>(&mut rng);
        check::<3, 6, 6>(&mut rng);
    }
}
