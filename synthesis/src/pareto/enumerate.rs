//! All vertices and facets of the Pareto front by supporting hyperplanes
//! (MODEL.md §5).
//!
//! Randomised strategies make the achievable set `A` convex; its lower
//! boundary is the front. Each round: take the convex hull of the points found
//! so far plus the recession cone (each point shifted far along every axis);
//! every lower facet (outward normal −λ with λ ≥ 0) not yet confirmed is probed
//! with one backward induction for `min λ·f`; a point below the facet's plane
//! is new, otherwise the facet is a facet of the front. Stops when every lower
//! facet is confirmed: then no weight vector can find a point outside the hull,
//! so the hull's lower part *is* the front.

use super::policy::{DeterministicPolicy, Objectives, backward_induction};
use crate::mdp::{CostModel, Mdp};
use chull::ConvexHullWrapper;
use std::collections::BTreeSet;

/// A point found by a weighted optimisation, with its policy.
#[derive(Debug, Clone)]
pub struct FoundPoint {
    pub objectives: Objectives,
    /// Minimisation vector (energy scaled).
    pub f: [f64; 3],
    pub policy: DeterministicPolicy,
    /// The weight vector that found it.
    pub lambda: [f64; 3],
}

/// A lower facet of the hull: three found points and the weight of its plane.
#[derive(Debug, Clone)]
pub struct LowerFacet {
    pub points: [usize; 3],
    /// λ ≥ 0, normalised to sum 1.
    pub lambda: [f64; 3],
}

/// Result of the enumeration.
#[derive(Debug, Clone)]
pub struct Enumeration {
    pub points: Vec<FoundPoint>,
    /// Indices of points that are vertices of the front.
    pub vertices: Vec<usize>,
    /// Bounded lower facets (all three corners are found points).
    pub facets: Vec<LowerFacet>,
    /// Weighted optimisations solved.
    pub optimisations: usize,
    pub rounds: usize,
}

/// Errors of the enumeration.
#[derive(Debug, thiserror::Error)]
pub enum EnumerationError {
    #[error("convex hull failed: {0}")]
    Hull(String),
}

/// Improvement (in scaled objective units) below which a facet counts as confirmed.
pub const TOLERANCE: f64 = 1e-9;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

struct Finder<'a> {
    mdp: &'a Mdp,
    scale: f64,
    cost: CostModel,
    points: Vec<FoundPoint>,
    optimisations: usize,
}

impl Finder<'_> {
    /// Optimise for λ; returns the index of the (possibly already known) point.
    fn probe(&mut self, lambda: [f64; 3]) -> usize {
        self.optimisations += 1;
        let (policy, objectives) = backward_induction(self.mdp, lambda, self.scale, self.cost);
        let f = objectives.minimisation(self.scale);
        if let Some(i) = self
            .points
            .iter()
            .position(|p| sub(p.f, f).iter().all(|d| d.abs() <= 1e-12))
        {
            return i;
        }
        self.points.push(FoundPoint {
            objectives,
            f,
            policy,
            lambda,
        });
        self.points.len() - 1
    }
}

/// Enumerate the front of `mdp` with energy divided by `scale` (e.g. the
/// full-KF energy) so the three objectives are of comparable size.
pub fn enumerate_front(mdp: &Mdp, scale: f64, cost: CostModel) -> Result<Enumeration, EnumerationError> {
    let mut finder = Finder {
        mdp,
        scale: if scale > 0.0 { scale } else { 1.0 },
        cost,
        points: Vec::new(),
        optimisations: 0,
    };
    // Single-objective optima (ties broken towards the others) and a balanced weight.
    for l in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]] {
        finder.probe(l);
    }
    let mut confirmed: BTreeSet<[usize; 3]> = BTreeSet::new();
    let mut rounds = 0;
    let facets = loop {
        rounds += 1;
        let facets = lower_facets(&finder.points)?;
        let mut new_points = false;
        for fct in &facets {
            if confirmed.contains(&fct.key) {
                continue;
            }
            let known = finder.points.len();
            let i = finder.probe(fct.lambda);
            let plane = dot(fct.lambda, finder.points[fct.anchor].f);
            let value = dot(fct.lambda, finder.points[i].f);
            if i >= known && value < plane - TOLERANCE {
                new_points = true;
            } else {
                if i >= known {
                    // On the plane within tolerance: not a new vertex.
                    finder.points.pop();
                }
                confirmed.insert(fct.key);
            }
        }
        if !new_points {
            break facets;
        }
    };
    let mut vertices: BTreeSet<usize> = BTreeSet::new();
    let mut bounded = Vec::new();
    for f in &facets {
        for &c in &f.corners {
            if let Some(i) = c {
                vertices.insert(i);
            }
        }
        if let [Some(a), Some(b), Some(c)] = f.corners {
            bounded.push(LowerFacet {
                points: [a, b, c],
                lambda: f.lambda,
            });
        }
    }
    // A single point (or a front that is one vertex) has no lower facet with it.
    if vertices.is_empty() && !finder.points.is_empty() {
        vertices.insert(0);
    }
    Ok(Enumeration {
        vertices: vertices.into_iter().collect(),
        facets: bounded,
        optimisations: finder.optimisations,
        rounds,
        points: finder.points,
    })
}

struct HullFacet {
    /// Found-point index per corner, `None` for a recession-cone (far) point.
    corners: [Option<usize>; 3],
    key: [usize; 3],
    lambda: [f64; 3],
    /// A corner that is a found point (the plane passes through it).
    anchor: usize,
}

/// Lower facets of hull(points + recession cone).
fn lower_facets(points: &[FoundPoint]) -> Result<Vec<HullFacet>, EnumerationError> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p.f[k]);
            hi[k] = hi[k].max(p.f[k]);
        }
    }
    let far = 4.0 * (0..3).map(|k| hi[k] - lo[k]).fold(1.0, f64::max);
    // Coordinates: real points first, then 3 shifted copies of each.
    let n = points.len();
    let mut coords: Vec<[f64; 3]> = points.iter().map(|p| p.f).collect();
    for p in points {
        for k in 0..3 {
            let mut q = p.f;
            q[k] += far;
            coords.push(q);
        }
    }
    let input: Vec<Vec<f64>> = coords.iter().map(|c| c.to_vec()).collect();
    let hull = ConvexHullWrapper::try_new(&input, None).map_err(|e| EnumerationError::Hull(format!("{e:?}")))?;
    let (hv, idx) = hull.vertices_indices();
    // Map the hull's (renumbered) vertices back to our coordinates.
    let map: Vec<usize> = hv
        .iter()
        .map(|v| {
            let mut best = (f64::INFINITY, 0);
            for (i, c) in coords.iter().enumerate() {
                let d = (c[0] - v[0]).powi(2) + (c[1] - v[1]).powi(2) + (c[2] - v[2]).powi(2);
                if d < best.0 {
                    best = (d, i);
                }
            }
            best.1
        })
        .collect();
    let centroid = {
        let mut c = [0.0; 3];
        for q in &coords {
            for k in 0..3 {
                c[k] += q[k] / coords.len() as f64;
            }
        }
        c
    };
    let mut out = Vec::new();
    for tri in idx.chunks_exact(3) {
        let ids = [map[tri[0]], map[tri[1]], map[tri[2]]];
        let (a, b, c) = (coords[ids[0]], coords[ids[1]], coords[ids[2]]);
        let mut normal = cross(sub(b, a), sub(c, a));
        let len = dot(normal, normal).sqrt();
        if len == 0.0 {
            continue;
        }
        // Orient outward (away from the interior centroid).
        if dot(normal, sub(centroid, a)) > 0.0 {
            normal = [-normal[0], -normal[1], -normal[2]];
        }
        // Lower facet: outward normal has no positive component.
        let lambda = [-normal[0] / len, -normal[1] / len, -normal[2] / len];
        if lambda.iter().any(|&l| l < -1e-12) {
            continue;
        }
        let corners = ids.map(|i| (i < n).then_some(i));
        let Some(anchor) = corners.iter().flatten().next().copied() else {
            continue;
        };
        let sum: f64 = lambda.iter().map(|l| l.max(0.0)).sum();
        let lambda = lambda.map(|l| l.max(0.0) / sum);
        let mut key = ids;
        key.sort_unstable();
        out.push(HullFacet {
            corners,
            key,
            lambda,
            anchor,
        });
    }
    Ok(out)
}
