//! Method 2 of docs/MODEL.md §4: the covariance region of a belief at a decision point.
//!
//! `P = Σ_j λ_j v_j v_jᵀ` (λ descending, deterministic basis). Per axis j:
//! * magnitude bin: uniform in log λ between `lambda_lo` and `lambda_hi`,
//!   values outside clamped into the end bins;
//! * angle bin of `θ_j = arccos |v_jᵀ v_nom,j| ∈ [0, π/2]`, skipped (bin 0) when
//!   λ_j is numerically repeated — the eigenvector is then arbitrary.
//!
//! The region is the tuple of (magnitude bin, angle bin) per axis. The same
//! classification runs offline (abstraction, validation) and at run time
//! (coordinator), so it lives here, in the shared vocabulary.
//!
//! **Workspace-marginal descriptor** (MODEL.md §7, beyond the paper): for an
//! agent with a workspace map C (d×n), the per-axis tuple over all n axes grows
//! as (bins)^n and spreads the samples thin. What decides collisions and
//! arrival is the workspace marginal `C P Cᵀ` (d×d); the rest of P matters only
//! through how it feeds the workspace later. With [`WorkspaceMarginal`] the
//! region is the per-axis tuple of `C P Cᵀ` (d axes, same magnitude/angle
//! rule) followed by one coarse log-magnitude bin of `tr(Π P Π)`, Π = I − C⁺C
//! the projector onto what C does not see (the velocity of a double integrator).
//! The synthesis passes `C F^h` as the map (the workspace marginal h silent
//! steps ahead, MODEL.md §7.3); classification needs only the stored map.

mod split;
pub use split::{RegionSplit, SPLIT_MARK, check_splits, refine_region, split_side};

use crate::linalg::deterministic_eigen;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;

/// Relative gap under which neighbouring eigenvalues count as repeated for the
/// angle bins (looser than the eigenbasis rule: rounding in the filter
/// recursion leaves ~1e-15 differences on an isotropic system).
pub const REPEATED_RTOL: f64 = 1e-9;

/// A covariance region: `(magnitude bin, angle bin)` per eigen-axis, λ descending.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Region(pub Vec<(u16, u16)>);

impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self.0.iter().map(|(m, a)| format!("{m}/{a}")).collect();
        write!(f, "[{}]", parts.join(" "))
    }
}

/// How many bins, chosen by the user.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BinCounts {
    /// Log-uniform magnitude bins per eigenvalue.
    pub magnitude: u16,
    /// Angle bins per eigenvector on [0, π/2].
    pub angle: u16,
}

impl Default for BinCounts {
    fn default() -> Self {
        Self {
            magnitude: 12,
            angle: 4,
        }
    }
}

/// The workspace-marginal descriptor of one decision point (see the module doc).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkspaceMarginal {
    /// The map, d rows of n: C, or `C F^h` with the lookahead of MODEL.md §7.3.
    pub c: Vec<Vec<f64>>,
    /// Π = I − C⁺C, n rows of n.
    pub rest_projector: Vec<Vec<f64>>,
    /// Log-uniform range and bin count of `tr(Π P Π)`.
    pub rest_lo: f64,
    pub rest_hi: f64,
    pub rest_bins: u16,
}

impl WorkspaceMarginal {
    /// The descriptor of workspace map `c` with `rest_bins` bins on `[rest_lo, rest_hi]`.
    pub fn new(c: &DMatrix<f64>, rest_lo: f64, rest_hi: f64, rest_bins: u16) -> Self {
        let n = c.ncols();
        let pinv = crate::scenario::pseudo_inverse(c);
        let proj = DMatrix::<f64>::identity(n, n) - pinv * c;
        Self {
            c: rows(c),
            rest_projector: rows(&proj),
            rest_lo,
            rest_hi,
            rest_bins,
        }
    }

    fn c_matrix(&self) -> DMatrix<f64> {
        from_rows(&self.c)
    }

    /// `C P Cᵀ`.
    pub fn marginal(&self, cov: &DMatrix<f64>) -> DMatrix<f64> {
        let c = self.c_matrix();
        &c * cov * c.transpose()
    }

    /// `tr(Π P Π)`: the uncertainty C does not see.
    pub fn rest(&self, cov: &DMatrix<f64>) -> f64 {
        let p = from_rows(&self.rest_projector);
        (&p * cov * &p).trace()
    }

    /// Coarse log-uniform bin of [`Self::rest`], clamped.
    pub fn rest_bin(&self, cov: &DMatrix<f64>) -> u16 {
        log_bin(self.rest(cov), self.rest_lo, self.rest_hi, self.rest_bins)
    }
}

/// `C F^h`: the map whose marginal `C F^h P (C F^h)ᵀ` is the workspace
/// covariance of the estimation error after h silent steps (`e' = F e + w`
/// while nothing is received), less the process noise of those steps — the
/// same for every belief, so it cannot separate two (MODEL.md §7.3).
pub fn lookahead_map(c: &DMatrix<f64>, f: &DMatrix<f64>, h: u32) -> DMatrix<f64> {
    let mut m = c.clone();
    for _ in 0..h {
        m = &m * f;
    }
    m
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

fn from_rows(r: &[Vec<f64>]) -> DMatrix<f64> {
    let cols = r.first().map_or(0, Vec::len);
    DMatrix::from_fn(r.len(), cols, |i, j| r[i][j])
}

/// Bin of `v` among `bins` log-uniform bins on `[lo, hi]`, clamped.
fn log_bin(v: f64, lo: f64, hi: f64, bins: u16) -> u16 {
    let b = bins.max(1);
    if v.is_nan() || v <= 0.0 || lo <= 0.0 || hi <= lo {
        return 0;
    }
    let t = (v.ln() - lo.ln()) / (hi.ln() - lo.ln());
    let k = (t * f64::from(b)).floor();
    k.clamp(0.0, f64::from(b - 1)) as u16
}

/// The bins of one decision point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DecisionPointBins {
    pub lambda_lo: f64,
    pub lambda_hi: f64,
    pub counts: BinCounts,
    /// Nominal unit vector per axis (λ descending), from the samples seen here.
    pub nominal: Vec<Vec<f64>>,
    /// `Some`: regions describe `C P Cᵀ` plus a coarse bin of the rest, and
    /// `lambda_lo`, `lambda_hi`, `nominal` refer to `C P Cᵀ`; `None`: the
    /// paper's per-axis regions of P.
    #[serde(default)]
    pub workspace: Option<WorkspaceMarginal>,
}

impl DecisionPointBins {
    /// Bins with nominal axes taken from the mean of the covariances seen at
    /// this decision point (its eigenvectors, deterministic basis).
    pub fn from_samples<'a>(
        lambda_lo: f64,
        lambda_hi: f64,
        counts: BinCounts,
        covs: impl IntoIterator<Item = &'a DMatrix<f64>>,
    ) -> Self {
        let mut mean: Option<DMatrix<f64>> = None;
        let mut n = 0.0;
        for c in covs {
            n += 1.0;
            mean = Some(match mean {
                None => c.clone(),
                Some(m) => m + c,
            });
        }
        let nominal = match mean {
            Some(m) => {
                let (_, v) = deterministic_eigen(&(m / n));
                (0..v.ncols())
                    .map(|j| v.column(j).iter().copied().collect())
                    .collect()
            }
            None => Vec::new(),
        };
        Self {
            lambda_lo,
            lambda_hi,
            counts,
            nominal,
            workspace: None,
        }
    }

    /// Magnitude bin of an eigenvalue (log-uniform, clamped).
    pub fn magnitude_bin(&self, lambda: f64) -> u16 {
        log_bin(
            lambda,
            self.lambda_lo,
            self.lambda_hi,
            self.counts.magnitude,
        )
    }

    /// Angle bin of `θ = arccos |v·v_nom|` on [0, π/2].
    pub fn angle_bin(&self, axis: usize, v: &[f64]) -> u16 {
        let a = self.counts.angle.max(1);
        let Some(nom) = self.nominal.get(axis) else {
            return 0;
        };
        let c = v
            .iter()
            .zip(nom)
            .map(|(x, y)| x * y)
            .sum::<f64>()
            .abs()
            .min(1.0);
        let k = (c.acos() / FRAC_PI_2 * f64::from(a)).floor();
        k.clamp(0.0, f64::from(a - 1)) as u16
    }

    /// The region of a covariance at this decision point.
    pub fn classify(&self, cov: &DMatrix<f64>) -> Region {
        match &self.workspace {
            None => self.classify_axes(cov),
            Some(w) => {
                let mut r = self.classify_axes(&w.marginal(cov));
                r.0.push((w.rest_bin(cov), 0));
                r
            }
        }
    }

    /// The per-axis (magnitude, angle) tuple of a symmetric matrix.
    fn classify_axes(&self, cov: &DMatrix<f64>) -> Region {
        let (values, v) = deterministic_eigen(cov);
        let n = values.len();
        let scale = values
            .iter()
            .fold(0.0_f64, |m, x| m.max(x.abs()))
            .max(f64::MIN_POSITIVE);
        let repeated = |j: usize| {
            (j > 0 && (values[j - 1] - values[j]).abs() <= REPEATED_RTOL * scale)
                || (j + 1 < n && (values[j] - values[j + 1]).abs() <= REPEATED_RTOL * scale)
        };
        Region(
            (0..n)
                .map(|j| {
                    let m = self.magnitude_bin(values[j]);
                    let a = if repeated(j) {
                        0
                    } else {
                        let col: Vec<f64> = v.column(j).iter().copied().collect();
                        self.angle_bin(j, &col)
                    };
                    (m, a)
                })
                .collect(),
        )
    }
}

/// The bins of every decision point of a scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Discretization {
    pub decision_points: Vec<DecisionPointBins>,
}

impl Discretization {
    /// Region of covariance `cov` at decision point `dp`.
    /// A decision point without bins (never in a consistent file) has the
    /// empty region.
    pub fn classify(&self, dp: usize, cov: &DMatrix<f64>) -> Region {
        self.decision_points
            .get(dp)
            .map_or_else(|| Region(Vec::new()), |b| b.classify(cov))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bins() -> DecisionPointBins {
        let covs = [DMatrix::from_row_slice(2, 2, &[4.0, 0.0, 0.0, 1.0])];
        DecisionPointBins::from_samples(
            1e-4,
            1e-2,
            BinCounts {
                magnitude: 4,
                angle: 3,
            },
            covs.iter(),
        )
    }

    #[test]
    fn magnitudes_are_log_uniform_and_clamped() {
        let b = bins();
        assert_eq!(b.magnitude_bin(1e-6), 0);
        assert_eq!(b.magnitude_bin(1e-4), 0);
        assert_eq!(b.magnitude_bin(3.2e-4), 1); // log10 = -3.49 → t = 0.25..
        assert_eq!(b.magnitude_bin(1.1e-3), 2);
        assert_eq!(b.magnitude_bin(9.9e-3), 3);
        assert_eq!(b.magnitude_bin(1.0), 3);
    }

    #[test]
    fn isotropic_covariance_has_magnitudes_only() {
        let b = bins();
        let r = b.classify(&DMatrix::identity(2, 2).scale(1.1e-3));
        assert_eq!(r, Region(vec![(2, 0), (2, 0)]));
    }

    #[test]
    fn rotated_covariance_changes_the_angle_bin() {
        let b = bins();
        assert_eq!(b.nominal[0], vec![1.0, 0.0]);
        let aligned = DMatrix::from_row_slice(2, 2, &[4e-3, 0.0, 0.0, 1e-3]);
        assert_eq!(b.classify(&aligned).0[0].1, 0);
        // Rotate by 60°: θ = π/3 → bin 2 of 3.
        let (c, s) = (60f64.to_radians().cos(), 60f64.to_radians().sin());
        let rot = DMatrix::from_row_slice(2, 2, &[c, -s, s, c]);
        let rotated = &rot * aligned * rot.transpose();
        assert_eq!(b.classify(&rotated).0[0].1, 2);
    }

    #[test]
    fn workspace_marginal_sees_the_position_block_and_bins_the_rest() {
        // Double integrator, C = [I 0]: Π projects onto the velocities.
        let c = DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        let w = WorkspaceMarginal::new(&c, 1e-4, 1e-1, 3);
        let p = DMatrix::from_row_slice(
            4,
            4,
            &[
                4e-3, 1e-3, 2e-3, 0.0, 1e-3, 2e-3, 0.0, 1e-3, 2e-3, 0.0, 2.5e-3, 0.0, 0.0, 1e-3,
                0.0, 2.5e-3,
            ],
        );
        let m = w.marginal(&p);
        assert_eq!(m, p.view((0, 0), (2, 2)).clone_owned());
        assert!(
            (w.rest(&p) - 5e-3).abs() < 1e-15,
            "tr of the velocity block"
        );
        // log-uniform thirds of [1e-4, 1e-1]: 5e-3 lies in the middle one.
        assert_eq!(w.rest_bin(&p), 1);
        let mut b = bins();
        b.workspace = Some(w);
        let r = b.classify(&p);
        assert_eq!(r.0.len(), 3, "d = 2 axes of C P Cᵀ plus the rest bin");
        assert_eq!(r.0[2], (1, 0));
        assert_eq!(r.0[..2], b.classify_axes(&m).0[..]);
    }

    #[test]
    fn the_lookahead_separates_beliefs_that_differ_only_in_velocity() {
        // Double integrator, τ = 0.1: two beliefs with the same position
        // covariance, one with 16× the velocity variance. Now (h = 0) they
        // share a region; after h = 5 silent steps their position errors
        // differ (Σ_pp + h²τ² Σ_vv: 1e-3 + 0.25·1e-3 vs 1e-3 + 0.25·1.6e-2),
        // and so do their regions.
        let tau = 0.1;
        let f = DMatrix::from_row_slice(
            4,
            4,
            &[
                1.0, 0.0, tau, 0.0, 0.0, 1.0, 0.0, tau, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
            ],
        );
        let c = DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        let diag =
            |v: f64| DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![1e-3, 1e-3, v, v]));
        let (slow, fast) = (diag(1e-3), diag(1.6e-2));
        assert_eq!(lookahead_map(&c, &f, 0), c);
        let c5 = lookahead_map(&c, &f, 5);
        assert_eq!(
            c5.row(0).iter().copied().collect::<Vec<_>>(),
            vec![1.0, 0.0, 0.5, 0.0]
        );
        let classify = |map: &DMatrix<f64>, p: &DMatrix<f64>| {
            let mut b = DecisionPointBins {
                lambda_lo: 1e-4,
                lambda_hi: 1e-1,
                counts: BinCounts::default(),
                nominal: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
                workspace: None,
            };
            b.workspace = Some(WorkspaceMarginal::new(map, 1e-4, 1.0, 1));
            b.classify(p)
        };
        assert_eq!(classify(&c, &slow), classify(&c, &fast));
        assert_ne!(classify(&c5, &slow), classify(&c5, &fast));
        let m = WorkspaceMarginal::new(&c5, 1e-4, 1.0, 1).marginal(&fast);
        assert!((m[(0, 0)] - (1e-3 + 0.25 * 1.6e-2)).abs() < 1e-15);
    }
}
