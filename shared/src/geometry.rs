//! Closed axis-aligned boxes: obstacles and the target.

use crate::etkf::Vector;
use serde::{Deserialize, Serialize};

/// A closed axis-aligned box `{p : min ≤ p ≤ max}` (any dimension).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Aabb {
    pub min: Vec<f64>,
    pub max: Vec<f64>,
}

impl Aabb {
    pub fn contains(&self, p: &[f64]) -> bool {
        p.iter()
            .zip(self.min.iter().zip(&self.max))
            .all(|(v, (lo, hi))| lo <= v && v <= hi)
    }

    /// Fixed-size copy for the hot loop.
    pub fn to_static<const N: usize>(&self) -> StaticBox<N> {
        StaticBox {
            min: Vector::<N>::from_fn(|i, _| self.min[i]),
            max: Vector::<N>::from_fn(|i, _| self.max[i]),
        }
    }
}

/// A closed box of fixed dimension.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticBox<const N: usize> {
    pub min: Vector<N>,
    pub max: Vector<N>,
}

impl<const N: usize> StaticBox<N> {
    #[inline]
    pub fn contains(&self, p: &Vector<N>) -> bool {
        (0..N).all(|i| self.min[i] <= p[i] && p[i] <= self.max[i])
    }
}

/// Index of the first box containing `p`, if any.
#[inline]
pub fn first_containing<const N: usize>(boxes: &[StaticBox<N>], p: &Vector<N>) -> Option<usize> {
    boxes.iter().position(|b| b.contains(p))
}
