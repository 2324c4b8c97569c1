//! Adaptive splitting of regions (docs/MODEL.md §7.3, "Adaptive splitting";
//! issue 25 item 3): a region whose beliefs the aggregation test can tell
//! apart is cut in two at a threshold of one continuous **covariance
//! feature**, and each half becomes a state of its own.
//!
//! A split child is the parent region with one more entry appended,
//! `(SPLIT_MARK, side)`: side 0 for `feature < threshold`, 1 otherwise
//! (also for a NaN feature). A child can be split again, which appends
//! another entry. A belief is classified by its base region
//! ([`super::DecisionPointBins::classify`]) and then down the splits whose
//! parent is the region so far. Only covariance features are used (not the
//! estimate's mean): the coordinator classifies a belief from its covariance
//! alone, so a split must be decidable from it.
//!
//! Splits live beside the bins (`Mdp::splits`, `Strategy::splits`), not in
//! them, so files without splits keep their layout: an old strategy file has
//! none and classifies exactly as before.

use super::{DecisionPointBins, Discretization, Region};
use crate::linalg::deterministic_eigen;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// The bin pair that marks a split entry of a [`Region`] (no magnitude bin
/// reaches it: bin counts are `u16` and a split would need 65536 bins).
pub const SPLIT_MARK: u16 = u16::MAX;

/// One split of a region at a decision point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionSplit {
    pub decision_point: u32,
    /// The region cut (a base region, or a child of an earlier split).
    pub region: Region,
    /// Index into [`DecisionPointBins::covariance_features`].
    pub feature: u16,
    /// Side 0: `feature < threshold`; side 1: the rest.
    pub threshold: f64,
}

impl DecisionPointBins {
    /// The continuous coordinates of the descriptor, finer than the bins:
    /// log eigenvalues (descending) of the binned matrix (`C_h P C_hᵀ` with a
    /// workspace map, P otherwise; symmetrised), the angle of its leading axis
    /// from the nominal one, and with a workspace map the log of the rest
    /// `tr(Π P Π)`. The aggregation test splits on these (and on the mean's
    /// drift, which a split cannot use).
    pub fn covariance_features(&self, cov: &DMatrix<f64>) -> Vec<f64> {
        let m = match &self.workspace {
            Some(w) => w.marginal(cov),
            None => cov.clone(),
        };
        let (values, v) = deterministic_eigen(&((&m + m.transpose()) * 0.5));
        let mut f: Vec<f64> = values.iter().map(|x| x.max(1e-300).ln()).collect();
        let angle = self.nominal.first().map_or(0.0, |nom| {
            let c: f64 = v.column(0).iter().zip(nom).map(|(x, y)| x * y).sum();
            c.abs().min(1.0).acos()
        });
        f.push(angle);
        if let Some(w) = &self.workspace {
            f.push(w.rest(cov).max(1e-300).ln());
        }
        f
    }

    /// How many [`Self::covariance_features`] a belief has here.
    pub fn covariance_feature_count(&self) -> usize {
        let axes = match &self.workspace {
            Some(w) => w.c.len(),
            None => self.nominal.len(),
        };
        axes + 1 + usize::from(self.workspace.is_some())
    }
}

/// The side of a feature value: 0 below the threshold, 1 otherwise (NaN too).
pub fn split_side(value: f64, threshold: f64) -> u16 {
    if value < threshold { 0 } else { 1 }
}

/// `base` (the region of `cov` at decision point `dp` under `bins`) refined
/// by every split of `splits` whose parent it reaches.
pub fn refine_region(
    splits: &[RegionSplit],
    dp: usize,
    bins: &DecisionPointBins,
    cov: &DMatrix<f64>,
    base: Region,
) -> Region {
    let mut region = base;
    let mut features: Option<Vec<f64>> = None;
    // Each split appends one entry, so no chain is longer than the list.
    for _ in 0..splits.len() {
        let Some(s) = splits
            .iter()
            .find(|s| s.decision_point as usize == dp && s.region == region)
        else {
            break;
        };
        let f = features.get_or_insert_with(|| bins.covariance_features(cov));
        let value = f.get(usize::from(s.feature)).copied().unwrap_or(f64::NAN);
        region.0.push((SPLIT_MARK, split_side(value, s.threshold)));
    }
    region
}

impl Discretization {
    /// [`Discretization::classify`] refined by `splits`.
    pub fn classify_split(&self, dp: usize, cov: &DMatrix<f64>, splits: &[RegionSplit]) -> Region {
        let base = self.classify(dp, cov);
        match self.decision_points.get(dp) {
            Some(b) if !splits.is_empty() => refine_region(splits, dp, b, cov, base),
            _ => base,
        }
    }
}

/// Why a list of splits does not fit its bins.
pub fn check_splits(splits: &[RegionSplit], d: &Discretization) -> Result<(), String> {
    for (i, s) in splits.iter().enumerate() {
        let Some(b) = d.decision_points.get(s.decision_point as usize) else {
            return Err(format!(
                "splits[{i}].decision_point {} beyond the discretization's {} decision points",
                s.decision_point,
                d.decision_points.len()
            ));
        };
        if usize::from(s.feature) >= b.covariance_feature_count() {
            return Err(format!(
                "splits[{i}].feature {} but decision point {} has {} covariance features",
                s.feature,
                s.decision_point,
                b.covariance_feature_count()
            ));
        }
        if !s.threshold.is_finite() {
            return Err(format!("splits[{i}].threshold must be finite"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::BinCounts;

    /// Per-axis bins of 2×2 covariances, axes x then y.
    fn bins() -> DecisionPointBins {
        DecisionPointBins {
            lambda_lo: 1e-4,
            lambda_hi: 1e-1,
            counts: BinCounts {
                magnitude: 1,
                angle: 1,
            },
            nominal: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
            workspace: None,
        }
    }

    fn diag(a: f64, b: f64) -> DMatrix<f64> {
        DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![a, b]))
    }

    #[test]
    fn features_are_log_eigenvalues_and_the_leading_angle() {
        let b = bins();
        let f = b.covariance_features(&diag(4e-3, 1e-3));
        assert_eq!(f.len(), b.covariance_feature_count());
        assert!((f[0] - 4e-3_f64.ln()).abs() < 1e-12 && (f[1] - 1e-3_f64.ln()).abs() < 1e-12);
        assert!(f[2].abs() < 1e-12, "aligned with the nominal axis");
    }

    #[test]
    fn a_split_refines_its_region_only_and_nests() {
        // Both covariances lie in the one base region (a single magnitude
        // bin); the split on log λ1 at ln 5e-3 separates them.
        let d = Discretization {
            decision_points: vec![bins(), bins()],
        };
        let (small, large) = (diag(2e-3, 1e-3), diag(2e-2, 1e-3));
        let base = d.classify(1, &small);
        assert_eq!(base, d.classify(1, &large));
        let split = RegionSplit {
            decision_point: 1,
            region: base.clone(),
            feature: 0,
            threshold: 5e-3_f64.ln(),
        };
        let splits = vec![split.clone()];
        let mut lo = base.clone();
        lo.0.push((SPLIT_MARK, 0));
        let mut hi = base.clone();
        hi.0.push((SPLIT_MARK, 1));
        assert_eq!(d.classify_split(1, &small, &splits), lo);
        assert_eq!(d.classify_split(1, &large, &splits), hi);
        // Another decision point, or no splits: the base region.
        assert_eq!(d.classify_split(0, &small, &splits), base);
        assert_eq!(d.classify_split(1, &small, &[]), base);
        // The upper child split again on λ2.
        let nested = RegionSplit {
            decision_point: 1,
            region: hi.clone(),
            feature: 1,
            threshold: 5e-4_f64.ln(),
        };
        let splits = vec![split, nested];
        let mut hi_hi = hi.clone();
        hi_hi.0.push((SPLIT_MARK, 1));
        assert_eq!(d.classify_split(1, &large, &splits), hi_hi);
        assert_eq!(d.classify_split(1, &small, &splits), lo);
        assert!(check_splits(&splits, &d).is_ok());
        let mut bad = splits.clone();
        bad[0].feature = 3;
        assert!(
            check_splits(&bad, &d)
                .expect_err("refused")
                .contains("feature")
        );
        bad[0].feature = 0;
        bad[0].decision_point = 2;
        assert!(
            check_splits(&bad, &d)
                .expect_err("refused")
                .contains("decision_point")
        );
    }

    #[test]
    fn nan_goes_to_the_upper_side() {
        assert_eq!(split_side(f64::NAN, 0.0), 1);
        assert_eq!(split_side(-1.0, 0.0), 0);
        assert_eq!(split_side(0.0, 0.0), 1);
    }

    /// A strategy with a split region: the child states' ω are found by
    /// classifying a belief, before and after the sealed JSON round trip; a
    /// strategy without splits writes no `splits` key (its file is as before).
    #[test]
    fn a_split_region_round_trips_through_the_strategy_file() {
        use crate::strategy::{OmegaChoice, Strategy, StrategyState};
        let s = crate::scenario::Scenario::builtin("winding-2d").expect("built-in");
        let p = crate::strategy::Prediction {
            p_target: 0.9,
            p_collision: 0.1,
            p_free: 0.0,
            energy_mean: 1.0,
        };
        let mut st = Strategy::constant(&s, 0, Some(p));
        let d = Discretization {
            decision_points: vec![bins(); s.num_legs()],
        };
        let plain = {
            let mut t = st.clone();
            t.policy.discretization = Some(d.clone());
            t.to_json()
        };
        assert!(!plain.contains("\"splits\""), "no key without splits");
        let (small, large) = (diag(2e-3, 1e-3), diag(2e-2, 1e-3));
        let base = d.classify(2, &small);
        st.policy.discretization = Some(d);
        st.policy.splits = vec![RegionSplit {
            decision_point: 2,
            region: base.clone(),
            feature: 0,
            threshold: 5e-3_f64.ln(),
        }];
        st.policy.states.retain(|x| x.decision_point != 2);
        for (side, omega) in [
            (0, vec![0.0, 1.0, 0.0, 0.0, 0.0]),
            (1, vec![0.0, 0.0, 0.0, 1.0, 0.0]),
        ] {
            let mut r = base.clone();
            r.0.push((SPLIT_MARK, side));
            let mut omega = omega;
            omega.resize(s.deltas.len(), 0.0);
            st.policy.states.push(StrategyState {
                decision_point: 2,
                region: r,
                omega,
            });
        }
        let back = Strategy::from_sealed_json(&st.to_json()).expect("loads");
        assert_eq!(back, st);
        for t in [&st, &back] {
            assert_eq!(t.policy.draw(2, &small, 0.5), 1);
            assert_eq!(t.policy.draw(2, &large, 0.5), 3);
            assert!(matches!(t.policy.omega(2, &small), OmegaChoice::Exact(_)));
        }
        // A split naming a feature the bins do not have is refused.
        let mut bad = st.clone();
        bad.policy.splits[0].feature = 9;
        let e = Strategy::from_json(&bad.to_json()).expect_err("bad feature");
        assert!(e.to_string().contains("splits[0].feature"), "{e}");
    }
}
