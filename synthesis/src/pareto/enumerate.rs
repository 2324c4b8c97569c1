//! All vertices and facets of the Pareto front by supporting hyperplanes
//! (docs/MODEL.md §5).
//!
//! Randomised strategies make the achievable set `A` convex; its lower
//! boundary is the front. Each round: take the convex hull of the points found
//! so far plus the recession cone (each point shifted far along every axis);
//! every lower facet (outward normal −λ with λ ≥ 0) not yet confirmed is probed
//! with one backward induction for `min λ·f`; a point below the facet's plane
//! is new, otherwise the facet is a facet of the front. Stops when every lower
//! facet is confirmed: then no weight vector can find a point outside the hull,
//! so the hull's lower part *is* the front.
//!
//! Certificate (docs/MODEL.md §5): every probe also returns the exact minimum
//! `v_λ` of `λ · f` over all strategies. When the loop stops, every facet of
//! the final hull `conv(P) + R³₊` (bounded, unbounded and the three axis
//! facets) has been probed, and `ε = max_facets (b_λ − v_λ)⁺` (`b_λ` the
//! facet's plane) bounds how far any achievable point lies beyond the hull:
//! `f + ε·(1, 1, 1)` is in the hull for every achievable `f`.
//!
//! Determinism: the hull is taken of the found points lifted by a tiny,
//! index-seeded amount (at most [`LIFT`]) so that no four are coplanar and the
//! hull is unique whatever order the hull library visits points in; facets are
//! probed in the order of their sorted corner indices, and each facet's weight
//! is computed from its corners in that order. The same MDP gives the same
//! front, bit for bit, whatever the thread count or the run.

use super::policy::{DeterministicPolicy, Objectives, backward_induction, weighted_optimum};
use crate::mdp::{CostModel, Mdp};
use chull::ConvexHullWrapper;
use std::collections::{BTreeMap, BTreeSet, HashMap};

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

/// A bounded lower facet of the hull: found points and the weight of its plane.
#[derive(Debug, Clone)]
pub struct LowerFacet {
    /// Its corners (three or more: coplanar triangles are merged).
    pub points: Vec<usize>,
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
    /// Certified additive gap in scaled units: every achievable `f` has a
    /// point of `conv(vertices) + R³₊` at most `epsilon` above it in every
    /// objective (docs/MODEL.md §5).
    pub epsilon: f64,
}

/// Errors of the enumeration.
#[derive(Debug, thiserror::Error)]
pub enum EnumerationError {
    #[error("convex hull failed: {0}")]
    Hull(String),
}

/// Improvement below which a facet counts as confirmed, in scaled objective
/// units (energy / full-KF energy, probabilities): the front is complete up to
/// this ε — no strategy is better than the computed front by more than 1e-6 in
/// any weighted objective, i.e. 1e-4 percentage points of probability. Far below
/// the Monte Carlo error of the abstraction, and it keeps winding-2d's front
/// (≈ 1800 vertices) under a second instead of ≈ 3300 vertices in 2.5 s at 1e-9.
/// The gap actually certified is computed after the loop (`Enumeration::epsilon`).
pub const TOLERANCE: f64 = 1e-6;

/// Largest lift of a point's hull coordinates (scaled units): far below
/// [`TOLERANCE`], far above the 2.2e-16 grid of the exact hull, so ties and
/// coplanar quadruples of found points are broken the same way in every run.
/// The lift only moves points up (away from the front), so the lifted hull
/// lies inside the true one and the certificate stays valid (docs/MODEL.md §5).
pub const LIFT: f64 = 1e-10;

/// Lift indices of the far copies of the explicit recession cone (apart
/// from every found point's).
const FAR_COPY_INDEX: usize = 1 << 40;

/// Largest |λ_k| a recession facet of the explicit cone gets from the lift of
/// its far copies (LIFT over `far` ≥ 8), with room to spare.
const FAR_TILT: f64 = 1e-9;

/// The lifted hull coordinates of found point `index`.
fn lifted(f: [f64; 3], index: usize) -> [f64; 3] {
    let mut out = f;
    for (k, x) in out.iter_mut().enumerate() {
        let h = etp_shared::rng::mix64((index as u64).wrapping_mul(3).wrapping_add(k as u64));
        *x += LIFT * etp_shared::rng::unit_f64(h);
    }
    out
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Points closer than 1e-12 in every objective are the same point.
fn quantise(f: [f64; 3]) -> [i64; 3] {
    f.map(|x| (x * 1e12).round() as i64)
}

struct Finder<'a> {
    mdp: &'a Mdp,
    scale: f64,
    cost: CostModel,
    points: Vec<FoundPoint>,
    /// Exact objective bits → point, to recognise a point found again.
    index: HashMap<[i64; 3], usize>,
    optimisations: usize,
    /// Exact `min λ · f` of every probed weight (by the bits of λ).
    bounds: BTreeMap<[u64; 3], f64>,
}

impl Finder<'_> {
    /// Drop the last found point (it lay on a known facet).
    fn forget_last(&mut self) {
        if let Some(p) = self.points.pop() {
            self.index.remove(&quantise(p.f));
        }
    }

    /// Optimise for λ; returns the index of the (possibly already known) point.
    fn probe(&mut self, lambda: [f64; 3]) -> usize {
        self.optimisations += 1;
        let opt = weighted_optimum(self.mdp, lambda, self.scale, self.cost);
        self.bounds.insert(lambda.map(f64::to_bits), opt.bound);
        let (policy, objectives) = (opt.policy, opt.objectives);
        let f = objectives.minimisation(self.scale);
        let key = quantise(f);
        if let Some(&i) = self.index.get(&key) {
            return i;
        }
        self.index.insert(key, self.points.len());
        self.points.push(FoundPoint {
            objectives,
            f,
            policy,
            lambda,
        });
        self.points.len() - 1
    }

    /// The exact `min λ · f` (probing λ if it was not probed yet; such
    /// certificate-only probes are not counted in `optimisations`, whose count
    /// would otherwise depend on how the hull library triangulated coplanar
    /// recession-cone faces).
    fn bound(&mut self, lambda: [f64; 3]) -> f64 {
        let key = lambda.map(f64::to_bits);
        if let Some(&b) = self.bounds.get(&key) {
            return b;
        }
        let b = weighted_optimum(self.mdp, lambda, self.scale, self.cost).bound;
        self.bounds.insert(key, b);
        b
    }
}

/// Enumerate the front of `mdp` with energy divided by `scale` (e.g. the
/// full-KF energy) so the three objectives are of comparable size.
pub fn enumerate_front(
    mdp: &Mdp,
    scale: f64,
    cost: CostModel,
) -> Result<Enumeration, EnumerationError> {
    enumerate_front_to(mdp, scale, cost, TOLERANCE)
}

/// [`enumerate_front`] with another stopping tolerance (the certified gap is
/// computed whatever it is).
pub fn enumerate_front_to(
    mdp: &Mdp,
    scale: f64,
    cost: CostModel,
    tolerance: f64,
) -> Result<Enumeration, EnumerationError> {
    let mut finder = Finder {
        mdp,
        scale: if scale > 0.0 { scale } else { 1.0 },
        cost,
        points: Vec::new(),
        index: HashMap::new(),
        optimisations: 0,
        bounds: BTreeMap::new(),
    };
    // Single-objective optima (ties broken towards the others) and a balanced weight.
    for l in [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ] {
        finder.probe(l);
    }
    // Recession-cone copies sit further out than any achievable point: beyond
    // the largest energy any policy can spend (probabilities are in [0, 1]).
    let (_, most) = backward_induction(mdp, [-1.0, 0.0, 0.0], finder.scale, cost);
    let far = 4.0 * (most.energy / finder.scale + 2.0);
    let mut hull = RecessionHull::new(far);
    let mut confirmed: BTreeSet<Vec<usize>> = BTreeSet::new();
    let mut rounds = 0;
    // Points that may be corners of the hull: a point inside `conv(P) + R³₊`
    // stays inside as P grows, so only the last hull's corners and the new
    // points enter the next hull.
    let mut alive: Vec<usize> = (0..finder.points.len()).collect();
    let facets = loop {
        rounds += 1;
        let facets = hull.lower_facets(&finder.points, &alive)?;
        // The certificate needs every facet of the hull: none is a failure.
        if facets.is_empty() {
            return Err(EnumerationError::Hull("the hull has no lower facet".into()));
        }
        let before = finder.points.len();
        let mut new_points = false;
        for fct in &facets {
            if confirmed.contains(&fct.key) {
                continue;
            }
            let known = finder.points.len();
            let i = finder.probe(fct.lambda);
            let plane = dot(fct.lambda, finder.points[fct.anchor].f);
            let value = dot(fct.lambda, finder.points[i].f);
            if i >= known && value < plane - tolerance {
                new_points = true;
            } else {
                if i >= known {
                    // On the plane within tolerance: not a new vertex.
                    finder.forget_last();
                }
                confirmed.insert(fct.key.clone());
            }
        }
        if !new_points {
            break facets;
        }
        let corners: BTreeSet<usize> = facets
            .iter()
            .flat_map(|f| f.corners.iter().flatten().copied())
            .chain(before..finder.points.len())
            .collect();
        alive = corners.into_iter().collect();
    };
    let mut vertices: BTreeSet<usize> = BTreeSet::new();
    let mut bounded = Vec::new();
    for f in &facets {
        for &c in &f.corners {
            if let Some(i) = c {
                vertices.insert(i);
            }
        }
        let points: Vec<usize> = f.corners.iter().flatten().copied().collect();
        if points.len() == f.corners.len() {
            bounded.push(LowerFacet {
                points,
                lambda: f.lambda,
            });
        }
    }
    // A single point (or a front that is one vertex) has no lower facet with it.
    if vertices.is_empty() && !finder.points.is_empty() {
        vertices.insert(0);
    }
    let epsilon = certify(&mut finder, &facets);
    Ok(Enumeration {
        vertices: vertices.into_iter().collect(),
        facets: bounded,
        optimisations: finder.optimisations,
        rounds,
        points: finder.points,
        epsilon,
    })
}

/// The certified gap of the final hull: the largest amount by which the exact
/// optimum of a facet's weight lies below the facet's plane, over every facet
/// of `conv(P̃) + R³₊` (P̃ the lifted points): its bounded and unbounded lower
/// facets and the three axis facets `f_k ≥ min_P̃ f_k`. Planes are taken at
/// the highest of their corners (a conservative choice under rounding).
fn certify(finder: &mut Finder<'_>, facets: &[HullFacet]) -> f64 {
    let lifted_points: Vec<[f64; 3]> = finder
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| lifted(p.f, i))
        .collect();
    let mut gap = 0.0_f64;
    for f in facets {
        let plane = f
            .corners
            .iter()
            .flatten()
            .map(|&i| dot(f.lambda, lifted_points[i]))
            .fold(f64::NEG_INFINITY, f64::max);
        if plane.is_finite() {
            gap = gap.max(plane - finder.bound(f.lambda));
        }
    }
    for k in 0..3 {
        let mut axis = [0.0; 3];
        axis[k] = 1.0;
        let lowest = lifted_points
            .iter()
            .map(|p| p[k])
            .fold(f64::INFINITY, f64::min);
        if lowest.is_finite() {
            gap = gap.max(lowest - finder.bound(axis));
        }
    }
    gap
}

struct HullFacet {
    /// Found-point index per corner, `None` for a recession-cone (far) point.
    corners: Vec<Option<usize>>,
    /// Sorted hull-coordinate indices (stable across rounds).
    key: Vec<usize>,
    lambda: [f64; 3],
    /// A corner that is a found point (the plane passes through it).
    anchor: usize,
}

/// The lower facets of `conv(P) + R³₊` for the found points P.
///
/// Exact and cheap: its bounded facets are the facets of `conv(P)` with outward
/// normal `−λ`, `λ ≥ 0`; its unbounded facets (one λ_k = 0) are the lower edges
/// of the 2-D hulls of P projected along each axis k. When P is too small or
/// flat for those hulls, the recession cone is made explicit instead: every
/// point enters with three copies shifted far along the axes.
struct RecessionHull {
    far: f64,
}

/// Hull of `coords` (2-D or 3-D): vertex coordinates and the facets as index
/// lists into them. Exact (big-integer) arithmetic: the float quickhull of
/// `chull` gives up with round-off errors on these nearly coplanar fronts.
fn hull(coords: &[Vec<f64>]) -> Result<(Vec<Vec<f64>>, Vec<usize>), EnumerationError> {
    Ok(ConvexHullWrapper::try_new(coords, None)
        .map_err(|e| EnumerationError::Hull(format!("{e:?}")))?
        .vertices_indices())
}

/// Map hull vertices back to input indices (exact bits, else nearest).
fn map_back(coords: &[Vec<f64>], hv: &[Vec<f64>]) -> Vec<usize> {
    let exact: HashMap<Vec<u64>, usize> = coords
        .iter()
        .enumerate()
        .map(|(i, c)| (c.iter().map(|x| x.to_bits()).collect(), i))
        .collect();
    hv.iter()
        .map(|v| {
            let key: Vec<u64> = v.iter().map(|x| x.to_bits()).collect();
            exact
                .get(&key)
                .copied()
                .unwrap_or_else(|| nearest(coords, v))
        })
        .collect()
}

fn centroid(coords: &[Vec<f64>]) -> Vec<f64> {
    let d = coords.first().map_or(0, Vec::len);
    let mut c = vec![0.0; d];
    for p in coords {
        for k in 0..d {
            c[k] += p[k] / coords.len() as f64;
        }
    }
    c
}

impl RecessionHull {
    fn new(far: f64) -> Self {
        Self { far }
    }

    /// The lower facets of the hull of the points `alive` (global indices).
    fn lower_facets(
        &mut self,
        points: &[FoundPoint],
        alive: &[usize],
    ) -> Result<Vec<HullFacet>, EnumerationError> {
        let lifted_points: Vec<[f64; 3]> = alive.iter().map(|&i| lifted(points[i].f, i)).collect();
        let mut facets = match self.split(&lifted_points) {
            Ok(f) => f,
            Err(_) => self.explicit_cone(&lifted_points)?,
        };
        // Local (position in `alive`) to global indices; pseudo-indices of the
        // recession directions (≥ alive.len()) stay.
        let global = |i: usize| alive.get(i).copied().unwrap_or(i);
        for f in &mut facets {
            f.corners = f.corners.iter().map(|c| c.map(global)).collect();
            f.key = f.key.iter().map(|&k| global(k)).collect();
            f.key.sort_unstable();
            f.anchor = global(f.anchor);
        }
        // Canonical order (the hull library's facet order is not).
        let bits = |l: [f64; 3]| l.map(f64::to_bits);
        facets.sort_by(|a, b| a.key.cmp(&b.key).then(bits(a.lambda).cmp(&bits(b.lambda))));
        facets.dedup_by(|a, b| a.key == b.key && a.lambda == b.lambda);
        Ok(facets)
    }

    /// 3-D hull of P plus the three projected 2-D hulls.
    fn split(&self, points: &[[f64; 3]]) -> Result<Vec<HullFacet>, EnumerationError> {
        let coords: Vec<Vec<f64>> = points.iter().map(|p| p.to_vec()).collect();
        if coords.len() < 4 {
            return Err(EnumerationError::Hull("too few points".into()));
        }
        let (hv, idx) = hull(&coords)?;
        let map = map_back(&coords, &hv);
        let c = centroid(&coords);
        let mut out = Vec::new();
        for tri in idx.chunks_exact(3) {
            let mut ids = [map[tri[0]], map[tri[1]], map[tri[2]]];
            ids.sort_unstable();
            let Some(lambda) =
                lower_weight([points[ids[0]], points[ids[1]], points[ids[2]]], &c, 1e-12)
            else {
                continue;
            };
            let key = ids.to_vec();
            out.push(facet(key.iter().map(|&i| Some(i)).collect(), key, lambda));
        }
        if out.is_empty() {
            return Err(EnumerationError::Hull("no lower facet".into()));
        }
        for k in 0..3 {
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            let proj: Vec<Vec<f64>> = points.iter().map(|p| vec![p[a], p[b]]).collect();
            let (hv, idx) = hull(&proj)?;
            let map = map_back(&proj, &hv);
            let c = centroid(&proj);
            for edge in idx.chunks_exact(2) {
                let (i, j) = (
                    map[edge[0]].min(map[edge[1]]),
                    map[edge[0]].max(map[edge[1]]),
                );
                let (p, q) = (&proj[i], &proj[j]);
                let mut n = [q[1] - p[1], p[0] - q[0]];
                let len = (n[0] * n[0] + n[1] * n[1]).sqrt();
                if len == 0.0 {
                    continue;
                }
                if n[0] * (c[0] - p[0]) + n[1] * (c[1] - p[1]) > 0.0 {
                    n = [-n[0], -n[1]];
                }
                let (la, lb) = (-n[0] / len, -n[1] / len);
                if la < -1e-12 || lb < -1e-12 {
                    continue;
                }
                let mut lambda = [0.0; 3];
                lambda[a] = la;
                lambda[b] = lb;
                // Keys of unbounded facets: the axis (as a pseudo-index beyond
                // every point) and the two points.
                let mut key = vec![i, j];
                key.push(usize::MAX - k);
                out.push(facet(vec![Some(i), Some(j), None], key, lambda));
            }
        }
        Ok(out)
    }

    /// Small or flat P: hull of P and its far-shifted copies.
    fn explicit_cone(&self, points: &[[f64; 3]]) -> Result<Vec<HullFacet>, EnumerationError> {
        let mut coords: Vec<Vec<f64>> = Vec::with_capacity(4 * points.len());
        let mut owner: Vec<Option<usize>> = Vec::with_capacity(4 * points.len());
        for (i, p) in points.iter().enumerate() {
            coords.push(p.to_vec());
            owner.push(Some(i));
            for k in 0..3 {
                let mut q = *p;
                q[k] += self.far;
                // Lifted too: unlifted, the copies of two points along one
                // axis are coplanar with them, and the hull library (which
                // iterates randomly seeded hash sets) splits that
                // parallelogram either way — a different λ in the last bits
                // from run to run. Lifted, the hull is unique.
                let q = lifted(q, FAR_COPY_INDEX + 3 * i + k);
                coords.push(q.to_vec());
                owner.push(None);
            }
        }
        let (hv, idx) = hull(&coords)?;
        let map = map_back(&coords, &hv);
        let c = centroid(&coords);
        let at = |i: usize| [coords[i][0], coords[i][1], coords[i][2]];
        let mut out = Vec::new();
        for tri in idx.chunks_exact(3) {
            let mut ids = [map[tri[0]], map[tri[1]], map[tri[2]]];
            ids.sort_unstable();
            // The lifted far copies tilt a recession facet by ~LIFT/far:
            // its zero weight may come out as -1e-11.
            let Some(lambda) = lower_weight([at(ids[0]), at(ids[1]), at(ids[2])], &c, FAR_TILT)
            else {
                continue;
            };
            let corners: Vec<Option<usize>> = ids.iter().map(|&i| owner[i]).collect();
            // Keys in point indices (far copies as axis pseudo-indices), so
            // they stay comparable with the split method's keys.
            let mut key: Vec<usize> = ids
                .iter()
                .map(|&i| owner[i].unwrap_or_else(|| usize::MAX - (i % 4).saturating_sub(1)))
                .collect();
            key.sort_unstable();
            key.dedup();
            out.push(facet(corners, key, lambda));
        }
        Ok(out)
    }
}

/// The weight λ ≥ 0 of a hull triangle if it is a lower facet: its outward
/// normal (away from the interior point `inside`) is `−λ`. `None` for upper or
/// degenerate triangles.
fn lower_weight([a, b, d]: [[f64; 3]; 3], inside: &[f64], slack: f64) -> Option<[f64; 3]> {
    let mut normal = cross(sub(b, a), sub(d, a));
    let len = dot(normal, normal).sqrt();
    if len == 0.0 {
        return None;
    }
    if dot(normal, sub([inside[0], inside[1], inside[2]], a)) > 0.0 {
        normal = normal.map(|x| -x);
    }
    let lambda = normal.map(|x| -x / len);
    lambda.iter().all(|&l| l >= -slack).then_some(lambda)
}

fn facet(corners: Vec<Option<usize>>, key: Vec<usize>, lambda: [f64; 3]) -> HullFacet {
    let anchor = corners.iter().flatten().next().copied().unwrap_or(0);
    let total: f64 = lambda
        .iter()
        .map(|l| l.max(0.0))
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    HullFacet {
        corners,
        key,
        lambda: lambda.map(|l| l.max(0.0) / total),
        anchor,
    }
}

/// Index of the coordinate nearest to `v` (for the big-integer hull, whose
/// round trip may change the last bits).
fn nearest(coords: &[Vec<f64>], v: &[f64]) -> usize {
    let mut best = (f64::INFINITY, 0);
    for (i, c) in coords.iter().enumerate() {
        let d: f64 = c.iter().zip(v).map(|(a, b)| (a - b).powi(2)).sum();
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A front with one flat objective (no collision at all, as the Method 1
    /// baseline often is): the 3-D split fails and the explicit recession cone
    /// is used, whose far copies form coplanar quadruples.
    fn flat_front() -> Vec<[f64; 3]> {
        (0..12)
            .map(|i| {
                let t = f64::from(i) / 11.0;
                lifted([0.2 + 3.0 * t * t, 1.0 - t, 0.0], i as usize)
            })
            .collect()
    }

    fn signature(facets: &[HullFacet]) -> Vec<(Vec<usize>, [u64; 3])> {
        let mut v: Vec<_> = facets
            .iter()
            .map(|f| (f.key.clone(), f.lambda.map(f64::to_bits)))
            .collect();
        v.sort();
        v
    }

    /// The hull library iterates hash sets with a fresh random state per
    /// instance, so each call below triangulates in its own order: the facets
    /// must not depend on it (front.json was not reproducible).
    #[test]
    fn the_explicit_cone_is_the_same_whatever_the_hull_library_order() {
        let points = flat_front();
        let hull = RecessionHull::new(4.0 * (3.2 + 2.0));
        let first = signature(&hull.explicit_cone(&points).expect("hull"));
        assert!(first.len() >= 3, "{first:?}");
        for _ in 0..40 {
            assert_eq!(
                signature(&hull.explicit_cone(&points).expect("hull")),
                first
            );
        }
    }
}
