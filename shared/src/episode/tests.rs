use super::*;
use crate::radio::EpisodeChannels;
use crate::rng::{stream_rng, streams};
use crate::scenario::Scenario;

fn winding() -> (Scenario, CompiledScenario<2>) {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let c = CompiledScenario::<2>::new(&s);
    (s, c)
}

fn constant(delta: f64) -> impl FnMut(usize, &Belief<2>, &mut crate::rng::SimRng) -> LegMode<2> {
    move |_, _, _| LegMode::EventTriggered(Threshold::new(delta))
}

#[test]
fn same_seed_same_episode() {
    let (_, c) = winding();
    let a = c.run_episode(
        constant(1.5),
        &mut stream_rng(7, streams::SIMULATE, 3),
        &mut EpisodeChannels::ideal(),
        &mut (),
    );
    let b = c.run_episode(
        constant(1.5),
        &mut stream_rng(7, streams::SIMULATE, 3),
        &mut EpisodeChannels::ideal(),
        &mut (),
    );
    assert_eq!(a, b);
    let other = c.run_episode(
        constant(1.5),
        &mut stream_rng(7, streams::SIMULATE, 4),
        &mut EpisodeChannels::ideal(),
        &mut (),
    );
    assert_ne!(a, other);
}

#[test]
fn full_kf_transmits_every_slot_and_counts_add_up() {
    let (_, c) = winding();
    struct Count {
        steps: u32,
        slots: u32,
        sent: u32,
        legs: u32,
    }
    impl EpisodeObserver<2> for Count {
        fn on_step(&mut self, e: &StepEvent<'_, 2>) {
            self.steps += 1;
            self.slots += u32::from(!e.collided);
            self.sent += u32::from(e.transmitted);
        }
        fn on_leg_end(&mut self, _: usize, _: usize, _: &LegResult) {
            self.legs += 1;
        }
    }
    for ep in 0..20 {
        let mut obs = Count {
            steps: 0,
            slots: 0,
            sent: 0,
            legs: 0,
        };
        let r = c.run_episode(
            constant(0.0),
            &mut stream_rng(1, streams::SIMULATE, ep),
            &mut EpisodeChannels::ideal(),
            &mut obs,
        );
        assert_eq!(r.transmissions, r.slots, "δ = 0 sends every measurement");
        assert_eq!(
            (obs.steps, obs.slots, obs.sent),
            (r.steps, r.slots, r.transmissions)
        );
        assert!(
            (r.energy - f64::from(r.transmissions)).abs() < 1e-12,
            "cost 1 per packet"
        );
        match r.outcome {
            Outcome::Collision => assert_eq!(r.steps, r.slots + 1),
            _ => {
                assert_eq!(r.steps, r.slots);
                assert_eq!(obs.legs as usize, c.legs.len());
            }
        }
    }
}

#[test]
fn a_leg_runs_at_least_one_step_and_stops_at_k_max() {
    let (_, mut c) = winding();
    c.k_max = 3;
    let mut rng = stream_rng(2, streams::SIMULATE, 0);
    let mut state = c.initial_state(&mut rng);
    let r = c.run_leg(
        0,
        &mut state,
        &LegMode::EventTriggered(Threshold::new(0.0)),
        &mut rng,
        &mut EpisodeChannels::ideal(),
        &mut (),
    );
    assert_eq!(r.end, LegEnd::Terminated);
    assert_eq!(r.steps, 3, "leg 0 of winding-2d is 2.5 long: k_max ends it");

    // Already at the waypoint: still one step (termination is checked after a step).
    let (_, c) = winding();
    let mut state = c.initial_state(&mut rng);
    state.belief.mean = c.legs[0].waypoint;
    state.x = c.legs[0].waypoint;
    let r = c.run_leg(
        0,
        &mut state,
        &LegMode::EventTriggered(Threshold::new(0.0)),
        &mut rng,
        &mut EpisodeChannels::ideal(),
        &mut (),
    );
    assert!(r.steps >= 1);
}

#[test]
fn an_obstacle_on_the_line_is_hit() {
    let text = crate::scenario::builtin_text("winding-2d").expect("built-in");
    // A wall across leg 0 (x from 0.5 to 3.0 at y = 1).
    let text = text.replace(
        "[[obstacle]]\nname = \"g1+\"",
        "[[obstacle]]\nname = \"wall\"\nmin = [2.0, -5.0]\nmax = [2.2, 5.0]\n\n[[obstacle]]\nname = \"g1+\"",
    );
    let s = Scenario::from_toml(&text).expect("valid");
    let c = CompiledScenario::<2>::new(&s);
    let r = c.run_episode(
        constant(0.0),
        &mut stream_rng(3, streams::SIMULATE, 0),
        &mut EpisodeChannels::ideal(),
        &mut (),
    );
    assert_eq!(r.outcome, Outcome::Collision);
    assert_eq!(r.steps, r.slots + 1);
}

#[test]
fn kf_convergence_spends_slots_at_delta_zero_near_the_waypoint() {
    let (_, c) = winding();
    let p_kf = c.filters[0].steady_state_posterior();
    let mode = LegMode::KfConvergence {
        threshold: Threshold::new(2.2365),
        eps_kf: 0.2,
        eps_p: 1e-6,
        p_kf,
    };
    let mut rng = stream_rng(4, streams::SIMULATE, 0);
    let mut state = c.initial_state(&mut rng);
    let r = c.run_leg(
        0,
        &mut state,
        &mode,
        &mut rng,
        &mut EpisodeChannels::ideal(),
        &mut (),
    );
    assert_eq!(r.end, LegEnd::Terminated);
    assert!(r.kf_slots > 0 && r.steps < c.k_max);
    assert!((state.belief.cov - p_kf).amax() <= 1e-6);
    assert!((state.belief.mean - c.legs[0].waypoint).norm() <= c.eps_x);
}

/// The Riccati recursion as it was first written: up to `RICCATI_STEPS`
/// steps, no cycle search. `steady_state_posterior` must give its bits.
fn riccati_by_iteration<const N: usize, const M: usize>(
    f: &crate::etkf::EtKalmanFilter<N, M>,
) -> Matrix<N, N> {
    let mut b = Belief {
        mean: Vector::<N>::zeros(),
        cov: f.plant.q,
    };
    let zero = Vector::<N>::zeros();
    for _ in 0..crate::etkf::RICCATI_STEPS {
        let prior = f.predict(&b, &zero);
        let inn = f.innovation(&prior);
        let next = f.update_implicit(&prior, &inn, 1.0);
        let change = (next.cov - b.cov).amax();
        b = next;
        if change <= 4.0 * f64::EPSILON * b.cov.amax() {
            break;
        }
    }
    b.cov
}

fn steady_states_agree<const N: usize>(s: &Scenario) -> usize {
    let c = CompiledScenario::<N>::new(s);
    for (i, f) in c.filters.iter().enumerate() {
        let (fast, slow) =
            on_filter!(f, f => (f.steady_state_posterior(), riccati_by_iteration(f)));
        let bits = |m: &Matrix<N, N>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&fast), bits(&slow), "{} sensor {i}", s.name);
    }
    c.filters.len()
}

#[test]
fn steady_state_skips_a_rounding_cycle_to_the_same_bits() {
    // winding-2d's sensors cycle through a few covariances ulps apart and
    // never meet the stopping test (the plain loop runs all 10⁶ steps);
    // inertia-2d's converge. Both, every built-in and random agents.
    let mut scenarios: Vec<Scenario> = crate::scenario::BUILTIN_NAMES
        .iter()
        .map(|n| Scenario::builtin(n).expect("built-in"))
        .collect();
    for (k, kind) in [
        crate::scenario::random::AgentKind::Single2,
        crate::scenario::random::AgentKind::Single3,
        crate::scenario::random::AgentKind::Double2,
        crate::scenario::random::AgentKind::Double3,
    ]
    .into_iter()
    .enumerate()
    {
        for seed in 0..2 {
            let (_, s) = crate::scenario::random::random_scenario(kind, 40 + 2 * k as u64 + seed)
                .expect("a random scenario");
            scenarios.push(s);
        }
    }
    let mut filters = 0;
    for s in &scenarios {
        filters += crate::with_dim!(s.dim, N => steady_states_agree::<N>(s));
    }
    assert!(filters >= 20, "{filters} filters compared");
}
