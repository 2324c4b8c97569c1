//! The default waypoint controller of docs/MODEL.md §3: `u = sat(w − x̂, u_max)`.

use crate::etkf::Vector;

/// Drive the estimate toward the waypoint, saturated to Euclidean norm `u_max`.
#[inline]
pub fn waypoint_input<const N: usize>(
    mean: &Vector<N>,
    waypoint: &Vector<N>,
    u_max: f64,
) -> Vector<N> {
    let d = waypoint - mean;
    let norm = d.norm();
    if norm > u_max { d * (u_max / norm) } else { d }
}

/// Leg termination on the estimate: `‖x̂ − w‖₂ ≤ eps_x`.
#[inline]
pub fn reached<const N: usize>(mean: &Vector<N>, waypoint: &Vector<N>, eps_x: f64) -> bool {
    (mean - waypoint).norm_squared() <= eps_x * eps_x
}
