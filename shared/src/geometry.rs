//! Closed axis-aligned boxes (obstacles and the target) and the workspace map
//! `q = C x` in which they live (MODEL.md §7).

use crate::dense::mul;
use crate::linalg::{Matrix, Vector, to_static_padded};
use nalgebra::DMatrix;
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

    /// Fixed-size copy for the hot loop. A box of dimension d < N is padded
    /// with `[0, 0]` on the axes past d, where [`WorkspaceMap::point`] is zero.
    pub fn to_static<const N: usize>(&self) -> StaticBox<N> {
        StaticBox {
            min: pad_point(&self.min),
            max: pad_point(&self.max),
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
    #[inline(always)]
    pub fn contains(&self, p: &Vector<N>) -> bool {
        (0..N).all(|i| self.min[i] <= p[i] && p[i] <= self.max[i])
    }
}

/// Index of the first box containing `p`, if any.
#[inline(always)]
pub fn first_containing<const N: usize>(boxes: &[StaticBox<N>], p: &Vector<N>) -> Option<usize> {
    boxes.iter().position(|b| b.contains(p))
}

/// A workspace point of dimension d ≤ N as an N-vector, zero past d.
pub fn pad_point<const N: usize>(v: &[f64]) -> Vector<N> {
    Vector::<N>::from_fn(|i, _| v.get(i).copied().unwrap_or(0.0))
}

/// The workspace map `q = C x` (MODEL.md §7) in fixed size: C is stored with
/// zero rows past d, so `q` is an N-vector whose entries past d are zero and
/// padded boxes and waypoints ([`pad_point`]) compare with it unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WorkspaceMap<const N: usize> {
    /// C = I (the paper's agents): `q = x` with no arithmetic at all.
    Identity,
    Linear(Matrix<N, N>),
}

impl<const N: usize> WorkspaceMap<N> {
    pub fn new(c: Option<&DMatrix<f64>>) -> Self {
        match c {
            None => Self::Identity,
            Some(c) => Self::Linear(to_static_padded(c)),
        }
    }

    /// `C x` (padded to N).
    #[inline(always)]
    pub fn point(&self, x: &Vector<N>) -> Vector<N> {
        match self {
            Self::Identity => *x,
            Self::Linear(c) => mul(c, x),
        }
    }
}
