//! The cross-fitted prediction of one strategy from R independent rebuilds
//! (`etp strategy --replicates R`): the held-out sample's own
//! error (the delta method of [`super::crossfit`]) leaves out the rest of a
//! rebuild's Monte Carlo — the pools the held-out segments start from are a
//! finite sample of the strategy's law, drawn by the main sample upstream
//! (docs/MODEL.md §7.3). Rebuilds with different seeds are independent draws
//! of *all* of it, so their spread measures it: the mean of R, with a
//! Student-t interval on R − 1 degrees of freedom, covers the whole.

use crate::pareto::policy::Objectives;
use statrs::distribution::{ContinuousCDF, StudentsT};

/// The combined prediction: the mean of the replicates and its 95 % half-width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Replicated {
    pub mean: Objectives,
    /// t(0.975; R − 1) · s / √R per objective (s the replicates' sample
    /// standard deviation).
    pub ci95: Objectives,
    pub replicates: usize,
}

/// The mean of `values` (at least two) and the 95 % Student-t half-width of
/// that mean; None with fewer than two.
pub fn replicated(values: &[Objectives]) -> Option<Replicated> {
    let r = values.len();
    if r < 2 {
        return None;
    }
    let n = r as f64;
    let t = StudentsT::new(0.0, 1.0, n - 1.0).ok()?.inverse_cdf(0.975);
    let field = |f: fn(&Objectives) -> f64| {
        let mean = values.iter().map(f).sum::<f64>() / n;
        let var = values.iter().map(|v| (f(v) - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, t * (var / n).sqrt())
    };
    let (e, p, q) = (
        field(|o| o.energy),
        field(|o| o.p_collision),
        field(|o| o.p_target),
    );
    Some(Replicated {
        mean: Objectives {
            energy: e.0,
            p_collision: p.0,
            p_target: q.0,
        },
        ci95: Objectives {
            energy: e.1,
            p_collision: p.1,
            p_target: q.1,
        },
        replicates: r,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use rand_distr::StandardNormal;

    fn o(p_target: f64) -> Objectives {
        Objectives {
            energy: 10.0 * p_target,
            p_collision: 1.0 - p_target,
            p_target,
        }
    }

    #[test]
    fn two_replicates_closed_form() {
        // R = 2: mean (a + b)/2, s = |a − b|/√2, half-width t(0.975; 1) · |a − b| / 2
        // with t(0.975; 1) = 12.7062.
        let r = replicated(&[o(0.90), o(0.92)]).expect("two");
        assert!((r.mean.p_target - 0.91).abs() < 1e-15);
        assert!((r.ci95.p_target - 12.7062 * 0.01).abs() < 1e-4, "{r:?}");
        assert!((r.ci95.energy - 12.7062 * 0.1).abs() < 1e-3);
        assert!(replicated(&[o(0.9)]).is_none());
    }

    #[test]
    fn the_interval_covers_the_true_mean_95_percent_of_the_time() {
        // 4000 experiments of R = 4 normal draws (σ = 0.01 around 0.9):
        // coverage of the Student-t interval within 93.5–96.5 % (the binomial
        // 99.9 % band around 95 % for 4000 trials is ±1.1 pt).
        let mut rng = etp_shared::rng::stream_rng(7, 0, 0);
        let mut inside = 0;
        for _ in 0..4000 {
            let v: Vec<Objectives> = (0..4)
                .map(|_| o(0.9 + 0.01 * rng.sample::<f64, _>(StandardNormal)))
                .collect();
            let r = replicated(&v).expect("four");
            inside += usize::from((r.mean.p_target - 0.9).abs() <= r.ci95.p_target);
        }
        assert!((3740..=3860).contains(&inside), "{inside} of 4000");
    }
}
