//! From run-time dimensions to compile-time ones.
//!
//! The maths is written for fixed sizes (`const N`, `const M`) so the hot loop
//! works on stack matrices. A scenario's `n` and each sensor's `m` are only known
//! at run time; these macros pick the instantiation once, outside the loop.

/// Run `$body` with `$N` bound to the compile-time constant equal to `$n` (1..=6).
///
/// ```
/// fn zeros<const N: usize>() -> usize { nalgebra::SVector::<f64, N>::zeros().len() }
/// let n = 3;
/// assert_eq!(etp_shared::with_dim!(n, N => zeros::<N>()), 3);
/// ```
///
/// Dimensions are validated at scenario load (1..=6); any other value panics
/// with a message, which would be a bug in validation.
#[macro_export]
macro_rules! with_dim {
    ($n:expr, $N:ident => $body:expr) => {
        match $n {
            1 => {
                const $N: usize = 1;
                $body
            }
            2 => {
                const $N: usize = 2;
                $body
            }
            3 => {
                const $N: usize = 3;
                $body
            }
            4 => {
                const $N: usize = 4;
                $body
            }
            5 => {
                const $N: usize = 5;
                $body
            }
            6 => {
                const $N: usize = 6;
                $body
            }
            other => panic!("dimension {other} outside 1..=6 (scenario validation bug)"),
        }
    };
}
