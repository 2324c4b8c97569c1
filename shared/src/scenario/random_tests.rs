//! The random scenario family: reproducible, valid, feasible.

use super::*;
use crate::episode::{CompiledScenario, LegMode, Outcome};
use crate::etkf::Threshold;
use crate::rng::stream_rng;
use crate::with_dim;

const KINDS: [AgentKind; 4] = [
    AgentKind::Single2,
    AgentKind::Single3,
    AgentKind::Double2,
    AgentKind::Double3,
];

/// Full-KF (δ = 0) episodes of a scenario: (targets, collisions).
fn full_kf(s: &Scenario, episodes: u64) -> (u64, u64) {
    let t = Threshold::new(0.0);
    with_dim!(s.dim, N => {
        let c = CompiledScenario::<N>::new(s);
        let mut hits = (0, 0);
        for e in 0..episodes {
            let mut rng = stream_rng(0, 1, e);
            let mut channels = c.channels(0, 1, e);
            let r = c.run_episode(
                |_, _, _| LegMode::<N>::EventTriggered(t),
                &mut rng,
                &mut channels,
                &mut (),
            );
            match r.outcome {
                Outcome::Target => hits.0 += 1,
                Outcome::Collision => hits.1 += 1,
                Outcome::Free => {}
            }
        }
        hits
    })
}

#[test]
fn the_same_seed_gives_the_same_text_and_seeds_differ() {
    for kind in KINDS {
        let (a, _) = random_scenario(kind, 7).expect("valid");
        let (b, _) = random_scenario(kind, 7).expect("valid");
        let (c, _) = random_scenario(kind, 8).expect("valid");
        assert_eq!(a, b);
        assert_ne!(a, c);
    }
}

/// 200 seeds per agent kind parse, validate without warnings (what `etp
/// check` runs: `Scenario::from_toml`), have 3–7 sensors with anisotropic R,
/// and keep the route clear of every obstacle.
#[test]
fn two_hundred_seeds_per_kind_are_valid() {
    for kind in KINDS {
        for seed in 0..200 {
            let (text, s) =
                random_scenario(kind, seed).unwrap_or_else(|e| panic!("{kind:?} seed {seed}: {e}"));
            assert!(
                s.warnings.is_empty(),
                "{kind:?} seed {seed}: {:?}",
                s.warnings
            );
            assert_eq!(s.dim, kind.dim());
            assert_eq!(s.workspace_dim(), kind.workspace_dim());
            assert!((3..=7).contains(&s.sensors.len()), "{text}");
            assert!((5..=8).contains(&s.num_legs()));
            assert!(!s.obstacles.is_empty());
            let mut route = vec![s.route_start.clone()];
            route.extend(s.legs.iter().map(|l| l.to.clone()));
            for o in &s.obstacles {
                for w in route.windows(2) {
                    let dist = segment_box_distance(
                        w[0].as_slice(),
                        w[1].as_slice(),
                        &o.bounds.min,
                        &o.bounds.max,
                    );
                    assert!(dist >= 0.29, "{kind:?} seed {seed}: {} at {dist}", o.name);
                }
            }
            assert!(!s.target.contains(s.route_start.as_slice()));
        }
    }
}

/// The double integrators are feasible, not degenerate: the full KF reaches
/// the target in 0.8–0.998 of 300 episodes on each of seeds 0..10 (measured
/// with `etp simulate --delta 0 --episodes 300`: n = 4 0.88–0.99, n = 6
/// 0.90–0.99; the bounds leave 3 binomial σ). The single integrators are
/// not asserted: at the built-ins' process noise their random gates and walls
/// are too tight (measured P_tar 0.18–0.61), see docs/MODEL.md.
#[test]
fn double_integrators_reach_the_target_under_the_full_kf() {
    for kind in [AgentKind::Double2, AgentKind::Double3] {
        for seed in 0..10 {
            let (_, s) = random_scenario(kind, seed).expect("valid");
            let (t, _) = full_kf(&s, 300);
            let p = t as f64 / 300.0;
            assert!(
                (0.8..=0.998).contains(&p),
                "{kind:?} seed {seed}: P_tar {p}"
            );
        }
    }
}
