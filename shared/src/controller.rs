//! The waypoint controller: docs/MODEL.md §3's default `u = sat(w − x̂, u_max)` and
//! its general form of §7, `u = sat(K (C⁺w − x̂), u_max)`.

use crate::dense::mul;
use crate::etkf::{Matrix, Vector};
use crate::linalg::to_static_padded;
use crate::scenario::Scenario;

/// Drive the estimate toward the waypoint, saturated to Euclidean norm `u_max`.
#[inline(always)]
pub fn waypoint_input<const N: usize>(
    mean: &Vector<N>,
    waypoint: &Vector<N>,
    u_max: f64,
) -> Vector<N> {
    saturate(waypoint - mean, u_max)
}

/// Scale `d` to Euclidean norm `u_max` if it is longer.
#[inline(always)]
fn saturate<const N: usize>(d: Vector<N>, u_max: f64) -> Vector<N> {
    let norm = d.norm();
    if norm > u_max { d * (u_max / norm) } else { d }
}

/// Leg termination on the estimate: `‖x̂ − w‖₂ ≤ eps_x` (pass `C x̂` for §7).
#[inline(always)]
pub fn reached<const N: usize>(mean: &Vector<N>, waypoint: &Vector<N>, eps_x: f64) -> bool {
    (mean - waypoint).norm_squared() <= eps_x * eps_x
}

/// `u = sat(K (r − x̂), u_max)` with the reference `r = C⁺ w` (MODEL.md §7).
///
/// The input lives in R^p, p ≤ n; it is carried in an N-vector whose entries
/// past p are zero (K is stored with zero rows past p, G with zero columns), so
/// the fixed-size plant works unchanged. Without a gain (K = I, p = n) this is
/// [`waypoint_input`] exactly, so the paper's scenarios run bit for bit as before.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackController<const N: usize> {
    /// K padded to N×N; `None` = I.
    pub gain: Option<Matrix<N, N>>,
    pub u_max: f64,
}

impl<const N: usize> FeedbackController<N> {
    pub fn new(scenario: &Scenario) -> Self {
        Self {
            gain: scenario.gain.as_ref().map(to_static_padded::<N, N>),
            u_max: scenario.controller.u_max,
        }
    }

    /// The input for estimate `mean` and reference `reference` (= C⁺ w).
    #[inline(always)]
    pub fn input(&self, reference: &Vector<N>, mean: &Vector<N>) -> Vector<N> {
        match &self.gain {
            None => waypoint_input(mean, reference, self.u_max),
            Some(k) => saturate(mul(k, &(reference - mean)), self.u_max),
        }
    }
}
