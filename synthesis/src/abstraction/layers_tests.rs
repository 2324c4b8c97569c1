//! Tests of the layered build: carried true states and the on-policy reach.

use super::*;
use crate::abstraction::segments::{Task, run_task};
use etp_shared::etkf::Vector;

#[test]
fn a_carried_true_state_is_where_the_segment_starts() {
    // A carried state (on-policy pools): the segment starts from it,
    // not from a draw of N(x̂, P). Carried into the middle of the largest
    // obstacle, every segment collides; drawn around the initial belief
    // (clear of the obstacles), few do.
    let s = etp_shared::scenario::Scenario::builtin("winding-2d").expect("built-in");
    let cs = CompiledScenario::<2>::new(&s);
    let volume = |o: &&etp_shared::scenario::Obstacle| {
        (o.bounds.max[0] - o.bounds.min[0]) * (o.bounds.max[1] - o.bounds.min[1])
    };
    let big = s
        .obstacles
        .iter()
        .max_by(|a, b| volume(a).total_cmp(&volume(b)))
        .expect("winding-2d has obstacles");
    let centre = Vector::<2>::new(
        0.5 * (big.bounds.min[0] + big.bounds.max[0]),
        0.5 * (big.bounds.min[1] + big.bounds.max[1]),
    );
    assert!(cs.collision(&centre).is_some());
    let mode = LegMode::EventTriggered(Threshold::new(s.deltas[0]));
    let task = Task {
        state: 0,
        action: 0,
        choice: 0,
        lo: 0,
        hi: 64,
        holdout: false,
    };
    let run = |x: Option<Vector<2>>| {
        let p = Particle {
            belief: cs.initial,
            x,
        };
        run_task(&cs, 0, false, &[p], None, &mode, 11, 0, task)
    };
    assert_eq!(run(Some(centre)).collisions, 64);
    let drawn = run(None);
    assert!(drawn.collisions < 8, "{}", drawn.collisions);
    // Arrivals record the true state they arrived with: clear of every
    // obstacle (a segment that entered one ended there).
    assert!(!drawn.arrivals.is_empty());
    assert!(drawn.arrivals.iter().all(|a| cs.collision(&a.x).is_none()));
}

#[test]
fn reach_flows_through_the_policys_mass() {
    use crate::mdp::tests::toy;
    let mdp = toy();
    // The root (one state, two actions): ω = (0.25, 0.75), reach 1.
    let w = vec![0.25, 0.75];
    let reach = next_reach(&mdp.states[..1], &w, 1, 2);
    // Action 0 goes to state 1 w.p. 0.9, action 1 to state 2 w.p. 0.7.
    assert!((reach[0] - 0.25 * 0.9).abs() < 1e-15);
    assert!((reach[1] - 0.75 * 0.7).abs() < 1e-15);
}

#[test]
fn policy_only_offers_the_actions_the_policy_takes() {
    let omegas = vec![vec![0.0, 1.0, 0.0], vec![0.5, 0.0, 0.5], vec![0.0; 3]];
    // Every action without a policy, or with one but not `policy_only`.
    assert_eq!(offered_choices(2, 3, None, true).len(), 6);
    assert_eq!(offered_choices(3, 3, Some(&omegas), false).len(), 9);
    // Its own: ω > 0; a state where ω takes none (not a distribution)
    // keeps every action rather than none.
    assert_eq!(
        offered_choices(3, 3, Some(&omegas), true),
        vec![(0, 1), (1, 0), (1, 2), (2, 0), (2, 1), (2, 2)]
    );
}

#[test]
fn on_policy_states_are_keyed_by_region_default_ones_by_index() {
    let r = |v: &[(u16, u16)]| Region(v.to_vec());
    let (a, b) = (r(&[(1, 2), (3, 4)]), r(&[(1, 2), (4, 3)]));
    assert_eq!(state_key(7, &a, false), 7);
    // The same region keys alike wherever it stands in the layer...
    assert_eq!(state_key(0, &a, true), state_key(5, &a, true));
    // ...and different regions differently (coordinates are not summed).
    assert_ne!(state_key(0, &a, true), state_key(0, &b, true));
    assert_ne!(state_key(0, &a, true), state_key(0, &r(&[(1, 2)]), true));
}
