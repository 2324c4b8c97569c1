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
            let r = c.run_episode(|_, _, _| LegMode::<N>::EventTriggered(t), &mut rng, &mut ());
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
            let (text, s) = random_scenario(kind, seed)
                .unwrap_or_else(|e| panic!("{kind:?} seed {seed}: {e}"));
            assert!(s.warnings.is_empty(), "{kind:?} seed {seed}: {:?}", s.warnings);
            assert_eq!(s.dim, kind.dim());
            assert_eq!(s.workspace_dim(), kind.workspace_dim());
            assert!((3..=7).contains(&s.sensors.len()), "{text}");
            assert!((5..=8).contains(&s.num_legs()));
            assert!(!s.obstacles.is_empty());
            let mut route = vec![s.route_start.clone()];
            route.extend(s.legs.iter().map(|l| l.to.clone()));
            for o in &s.obstacles {
                for w in route.windows(2) {
                    let dist =
                        segment_box_distance(w[0].as_slice(), w[1].as_slice(), &o.bounds.min, &o.bounds.max);
                    assert!(dist >= 0.29, "{kind:?} seed {seed}: {} at {dist}", o.name);
                }
            }
            assert!(!s.target.contains(s.route_start.as_slice()));
        }
    }
}

#[test]
#[ignore = "exploration"]
fn explore_feasibility() {
    for kind in KINDS {
        let mut line = format!("{kind:?}:");
        for seed in 0..30 {
            let (_, s) = random_scenario(kind, seed).expect("valid");
            let (t, c) = full_kf(&s, 400);
            line += &format!(" {:.2}/{:.2}", t as f64 / 400.0, c as f64 / 400.0);
        }
        println!("{line}");
    }
}
