//! Tests of the layered build: carried true states and the on-policy reach.

use super::*;

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
        lo: 0,
        hi: 64,
        holdout: false,
    };
    let run = |x: Option<Vector<2>>| {
        let p = Particle {
            belief: cs.initial,
            x,
        };
        run_task(&cs, 0, false, &[p], None, &mode, 11, task)
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
